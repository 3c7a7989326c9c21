"""A guard trial's settings: the fleet, the autopilots, the link, the bounds the guard is told, the events.

:class:`Trial` is one simulated flight's settings and :class:`TrialResult` what the judge saw
(:mod:`uav_swarm.runs.flight.guard_trial`); :func:`bounds_of` the bounds the guard is told,
:func:`copter_of` one simulated autopilot.

Examples:
    >>> bounds_of(Trial(latency_s=0.4)).command_delay_s  # the latency and two integration steps
    0.5
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from bridge.simulated.dynamics import AutopilotLimits, PointMassCopter, Realism
from bridge.simulated.jerk_limited import (
    ARDUCOPTER_JERK,
    PX4_JERK,
    ArduCopterLikeCopter,
    JerkLimits,
    PX4LikeCopter,
)
from uav_swarm.world.guard import Bounds

__all__ = ["ALT_M", "AUTOPILOTS", "DT_S", "EVENTS", "GUARD_EVERY", "JOIN_AHEAD_M", "Trial", "TrialResult",
           "Window", "bounds_of", "copter_of", "realism_of"]

DT_S = 0.05
"""The judge's step (20 Hz) and the integration step, seconds."""
GUARD_EVERY = 2
"""A guard decision every this many steps (10 Hz)."""
ALT_M = 10.0
"""The altitude every trial flies at, metres."""
AUTOPILOTS = ("pointmass", "arducopter", "px4")
"""The simulated autopilots a trial may fly."""
EVENTS = ("silent", "no-fix", "join-in-flight", "stale-first-rows", "reversal")
"""The events a random trial may add (:mod:`uav_swarm.runs.flight.guard_trial`)."""
JOIN_AHEAD_M = 50.0
"""How far ahead of a vehicle joined in flight the named join case puts the hovering one, metres."""
_DEFAULT_JERK = {"pointmass": math.inf, "arducopter": ARDUCOPTER_JERK.jerk_m_s3, "px4": PX4_JERK.jerk_m_s3}

Window = tuple[int, float, float]


@dataclass(frozen=True)
class Trial:
    """One simulated flight: the fleet, the autopilots, the link, the guard's stated bounds, its events.

    ``stated_accel_m_s2`` is what the guard is told (0: the autopilots' own ``accel_m_s2``); a larger
    value than the real one puts the flight outside the bounds. ``jerk_m_s3`` is the autopilots' jerk
    limit (0: the autopilot's default; the point mass has none). ``script`` replaces random goals by
    ``(time_s, vehicle, (x, y))`` goals; ``starts_m`` replaces random starts.

    Events (module docstring): ``silent`` and ``no_fix`` are ``(vehicle, from_s, to_s)``; ``joins`` are
    ``(vehicle, join_s, (x, y))``, the point it flies to from the start, outside the guard, until it
    joins; ``stale_first_s`` are ``(vehicle, seconds)``; ``reversals`` are ``(vehicle, speed_m_s, metres)``:
    when its true speed first reaches ``speed_m_s``, its goal becomes the point that far behind it.
    """

    n_uavs: int = 4
    area_m: tuple[float, float] = (60.0, 60.0)
    min_separation_m: float = 5.0
    speed_m_s: float = 10.0
    accel_m_s2: float = 2.5
    stated_accel_m_s2: float = 0.0
    autopilot: str = "pointmass"
    jerk_m_s3: float = 0.0
    latency_s: float = 0.4
    loss: float = 0.0
    age_s: float = 0.2
    rate_hz: float = 10.0
    noise_m: float = 0.0
    wind_m_s: float = 0.0
    gust_m_s: float = 0.0
    goal_every_s: tuple[float, float] = (1.0, 10.0)
    duration_s: float = 60.0
    seed: int = 0
    reach_m: float = 1.0
    within_factor: float = 1.5
    script: tuple[tuple[float, int, tuple[float, float]], ...] = ()
    starts_m: tuple[tuple[float, float], ...] = ()
    silent: tuple[Window, ...] = ()
    no_fix: tuple[Window, ...] = ()
    joins: tuple[tuple[int, float, tuple[float, float]], ...] = ()
    stale_first_s: tuple[tuple[int, float], ...] = ()
    reversals: tuple[tuple[int, float, float], ...] = ()

    def __post_init__(self) -> None:
        if self.autopilot not in AUTOPILOTS:
            raise ValueError(f"autopilot must be one of {', '.join(AUTOPILOTS)}, got {self.autopilot!r}")

    @property
    def jerk(self) -> float:
        """The autopilots' jerk limit, m/s^3 (``inf``: none)."""
        return self.jerk_m_s3 or _DEFAULT_JERK[self.autopilot]


@dataclass
class TrialResult:
    """What the judge saw.

    Attributes:
        closest_m: The closest pair of vehicles under the guard (once seen the minimum apart), true positions.
        area_m: The area flown (grown where the starts did not fit).
        goals: Separable goals (module docstring).
        reached: Of those, the goals reached.
        breaches: ``outside_bounds`` events the guard reported.
        holds: Decisions that turned a vehicle to ``"held"``.
        pairs_under: Pairs of vehicles that came closer than the minimum.
        outside: Vehicles the judge found outside the set the guard certified for them.
        outside_steps: Judge steps (0.05 s) a vehicle was found outside it, summed over the vehicles.
        outside_m: The furthest a vehicle was found outside it, metres.
        events: Every kind of event the guard reported, with its count.
        timely: Of the separable goals, those reached within ``within_factor`` times the time the same
            vehicle, unguarded, needed (:mod:`uav_swarm.runs.flight.guard_trial`).
    """

    closest_m: float
    area_m: tuple[float, float]
    goals: int
    reached: int
    breaches: int
    holds: int
    pairs_under: int = 0
    outside: int = 0
    outside_steps: int = 0
    outside_m: float = 0.0
    events: dict[str, int] = field(default_factory=dict)
    timely: int = 0

    @property
    def liveness(self) -> float:
        """Share of the separable goals that were reached (1 with none)."""
        return self.reached / self.goals if self.goals else 1.0

    @property
    def timely_share(self) -> float:
        """Share of the separable goals reached in time (``within_factor``; 1 with none)."""
        return self.timely / self.goals if self.goals else 1.0


def bounds_of(trial: Trial) -> Bounds:
    """The bounds the guard is told for every vehicle of ``trial``."""
    realism = realism_of(trial)
    noise = 6.0 * trial.noise_m * math.sqrt(2.0)  # 6 sigma on each axis: a bound in practice
    tracking = realism.tracking_error_bound_m
    return Bounds(accel_m_s2=trial.stated_accel_m_s2 or trial.accel_m_s2, jerk_m_s3=trial.jerk,
                  position_error_m=noise,
                  velocity_error_m_s=2.0 * tracking / realism.wind_response_s if tracking else 0.0,
                  tracking_error_m=tracking, command_delay_s=trial.latency_s + 2 * DT_S,
                  position_age_s=trial.age_s + 1.0 / trial.rate_hz + 2 * DT_S,
                  per_axis=trial.autopilot == "px4")


def realism_of(trial: Trial) -> Realism:
    """The link, positions and wind of ``trial``'s simulated autopilots."""
    return Realism(command_latency_s=trial.latency_s, command_loss=trial.loss, position_age_s=trial.age_s,
                   position_rate_hz=trial.rate_hz, position_noise_m=trial.noise_m, wind_m_s=trial.wind_m_s,
                   gust_m_s=trial.gust_m_s)


def copter_of(trial: Trial, start_m: np.ndarray, rng: np.random.Generator) -> PointMassCopter:
    """One of ``trial``'s simulated autopilots, at rest at ``start_m``."""
    limits = AutopilotLimits(trial.speed_m_s, trial.accel_m_s2, climb_m_s=3.0, descent_m_s=1.5)
    position = np.array([*start_m, ALT_M])
    if trial.autopilot == "pointmass":
        return PointMassCopter(position, limits, realism_of(trial), rng)
    jerk = JerkLimits(jerk_m_s3=trial.jerk, vertical_jerk_m_s3=trial.jerk)
    kind = ArduCopterLikeCopter if trial.autopilot == "arducopter" else PX4LikeCopter
    return kind(position, limits, realism_of(trial), rng, jerk)

