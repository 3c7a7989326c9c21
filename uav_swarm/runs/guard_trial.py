"""The separation guard flown against simulated autopilots in simulated time, judged on true positions.

:func:`fly_trial` flies one :class:`Trial`: K :class:`bridge.simulated.dynamics.PointMassCopter`
vehicles (their autopilots' own speed and acceleration, command latency and loss, late and noisy
positions, wind), started at rest and apart, each given a new goal every 1-10 s (goals kept apart
from the others' goals); a :class:`uav_swarm.world.guard.FleetGuard` decides 10 times a second on the
vehicles' *reports* and its points reach them ``command_latency_s`` later (an acknowledgement comes
back with the command's effect; a lost one is never acknowledged). The judge is independent: the
**true** positions every 0.05 s, their pair distances by ``scipy.spatial.distance.pdist``.

Liveness is the share of goals reached (within ``reach_m`` of the vehicle's true position while it
was its goal) among the goals an unguarded vehicle could reach in the time they were held (the
latency, then accelerating and braking at the autopilot's limit, twice over, plus 2 s): a guard
that holds everyone fails it.

Examples:
    >>> result = fly_trial(Trial(n_uavs=2, area_m=(60.0, 60.0), seed=0, duration_s=20.0))
    >>> result.closest_m >= 5.0, result.breaches
    (True, 0)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial.distance import pdist

from bridge.simulated.dynamics import AutopilotLimits, PointMassCopter, Realism
from uav_swarm.world.guard import Bounds, FleetGuard
from uav_swarm.world.separation import draw_apart_m, max_spread_m

__all__ = ["NAMED_TRIALS", "Trial", "TrialResult", "WORST_BOUNDS", "fly_trial", "random_trial"]

_DT_S = 0.05  # the judge's step (20 Hz) and the integration step
_GUARD_EVERY = 2  # a guard decision every 2 steps (10 Hz)
_ALT_M = 10.0


@dataclass(frozen=True)
class Trial:
    """One simulated flight: the fleet, the autopilots, the link, the guard's stated bounds.

    ``stated_accel_m_s2`` is what the guard is told (0: the autopilots' own ``accel_m_s2``); a larger
    value than the real one puts the flight outside the bounds. ``script`` replaces random goals by
    ``(time_s, vehicle, (x, y))`` goals; ``starts_m`` replaces random starts.
    """

    n_uavs: int = 4
    area_m: tuple[float, float] = (60.0, 60.0)
    min_separation_m: float = 5.0
    speed_m_s: float = 10.0
    accel_m_s2: float = 2.5
    stated_accel_m_s2: float = 0.0
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
    script: tuple[tuple[float, int, tuple[float, float]], ...] = ()
    starts_m: tuple[tuple[float, float], ...] = ()


@dataclass
class TrialResult:
    """What the judge saw."""

    closest_m: float
    area_m: tuple[float, float]
    goals: int
    reached: int
    breaches: int
    holds: int
    events: dict[str, int] = field(default_factory=dict)

    @property
    def liveness(self) -> float:
        """Share of the goals that could be reached that were (1 with none)."""
        return self.reached / self.goals if self.goals else 1.0


def _bounds(trial: Trial) -> Bounds:
    realism = _realism(trial)
    noise = 6.0 * trial.noise_m * math.sqrt(2.0)  # 6 sigma on each axis: a bound in practice
    tracking = realism.tracking_error_bound_m
    return Bounds(accel_m_s2=trial.stated_accel_m_s2 or trial.accel_m_s2, position_error_m=noise,
                  velocity_error_m_s=2.0 * tracking / realism.wind_response_s if tracking else 0.0,
                  tracking_error_m=tracking, command_delay_s=trial.latency_s + 2 * _DT_S,
                  position_age_s=trial.age_s + 1.0 / trial.rate_hz + 2 * _DT_S)


def _realism(trial: Trial) -> Realism:
    return Realism(command_latency_s=trial.latency_s, command_loss=trial.loss, position_age_s=trial.age_s,
                   position_rate_hz=trial.rate_hz, position_noise_m=trial.noise_m, wind_m_s=trial.wind_m_s,
                   gust_m_s=trial.gust_m_s)


def _travel_s(distance_m: float, trial: Trial) -> float:
    """Seconds an unguarded vehicle needs from rest to rest over ``distance_m``."""
    v, a = trial.speed_m_s, trial.accel_m_s2
    if distance_m <= v * v / a:
        return 2.0 * math.sqrt(distance_m / a)
    return distance_m / v + v / a


def _draw_goal(rng: np.random.Generator, trial: Trial, others: np.ndarray) -> np.ndarray | None:
    area = np.asarray(trial.area_m)
    for _ in range(50):
        goal = rng.uniform(0.0, area)
        if others.size == 0 or np.hypot(*(others - goal).T).min() >= trial.min_separation_m + 2.0:
            return goal
    return None


def _starts(rng: np.random.Generator, trial: Trial, gap_m: float) -> tuple[np.ndarray, float]:
    """Random starts ``gap_m`` apart, and the scale of the area they needed (1: the trial's own area).

    Where random draws do not fit them, the area grows by 5 % at a time (the scale says how much).
    """
    k, scale = trial.n_uavs, 1.0
    while True:
        try:
            area = np.asarray(trial.area_m) * scale
            return draw_apart_m(rng, k, area, np.full((k, k), gap_m), max_tries=2000), scale
        except ValueError:
            scale *= 1.05


def fly_trial(trial: Trial) -> TrialResult:
    """Fly one trial (module docstring)."""
    rng = np.random.default_rng(trial.seed)
    k, bounds = trial.n_uavs, _bounds(trial)
    need = trial.min_separation_m
    if trial.starts_m:
        starts = np.asarray(trial.starts_m, dtype=np.float64)
    else:
        gap_m = need + 2.0 * bounds.position_error_m + 4.0 * bounds.tracking_error_m + 1.0
        starts, scale = _starts(rng, trial, gap_m)
        trial = replace(trial, area_m=(trial.area_m[0] * scale, trial.area_m[1] * scale))
    limits = AutopilotLimits(trial.speed_m_s, trial.accel_m_s2, climb_m_s=3.0, descent_m_s=1.5)
    copters = [PointMassCopter(np.array([*starts[i], _ALT_M]), limits, _realism(trial), rng.spawn(1)[0])
               for i in range(k)]
    guard = FleetGuard(np.full((k, k), need))
    for i in range(k):
        guard.join(i, starts[i], bounds, now_s=0.0)
    goals = starts.copy()
    goal_since = np.zeros(k)
    goal_reached = np.ones(k, bool)
    next_goal_s = rng.uniform(*trial.goal_every_s, size=k) if not trial.script else np.full(k, np.inf)
    script = sorted(trial.script)
    acks: list[tuple[float, int, int, bool]] = []  # (due_s, vehicle, seq, acknowledged)
    counted, reachable, reached, holds = 0, 0, 0, 0
    closest = math.inf
    states = ["idle"] * k
    steps = int(round(trial.duration_s / _DT_S))

    def close_goal(i: int, now_s: float) -> None:
        nonlocal reachable, reached
        start_gap = float(np.hypot(*(goals[i] - goal_start[i])))
        needed = 2.0 * (trial.latency_s + _travel_s(start_gap, trial)) + 2.0
        if now_s - goal_since[i] >= needed:
            reachable += 1
            reached += int(goal_reached[i])

    goal_start = starts.copy()
    for step in range(steps + 1):
        now_s = step * _DT_S
        while script and script[0][0] <= now_s + 1e-9:
            _, i, scripted = script.pop(0)
            if counted:
                close_goal(i, now_s)
            goals[i], goal_since[i], goal_start[i] = scripted, now_s, copters[i].position_m[:2]
            goal_reached[i] = False
            counted += 1
        for due_uav in np.flatnonzero(next_goal_s <= now_s + 1e-9):
            i = int(due_uav)
            drawn = _draw_goal(rng, trial, np.delete(goals, i, axis=0))
            if drawn is not None:
                close_goal(i, now_s)
                goals[i], goal_since[i], goal_start[i] = drawn, now_s, copters[i].position_m[:2]
                goal_reached[i] = False
                counted += 1
            next_goal_s[i] = now_s + rng.uniform(*trial.goal_every_s)
        for due in [a for a in acks if a[0] <= now_s + 1e-9]:
            acks.remove(due)
            (guard.acknowledged if due[3] else guard.unacknowledged)(due[1], due[2], due[0])
        if step % _GUARD_EVERY == 0:
            for i, copter in enumerate(copters):
                report = copter.report()
                guard.measure(i, report.position_m[:2], report.velocity_m_s[:2], report.stamp_s, now_s)
            for i, decision in enumerate(guard.decide(goals, now_s)):
                holds += int(decision.state == "held" and states[i] != "held")
                states[i] = decision.state
                if decision.point_m is not None:
                    arrived = copters[i].send(now_s, np.array([*decision.point_m, _ALT_M]))
                    due_s = now_s + (trial.latency_s + _DT_S if arrived else bounds.command_delay_s)
                    acks.append((due_s, i, decision.seq, arrived))
        truth = np.array([c.position_m[:2] for c in copters])
        closest = min(closest, float(pdist(truth).min()))
        goal_reached |= np.hypot(*(truth - goals).T) <= trial.reach_m
        if step < steps:
            for copter in copters:
                copter.advance(_DT_S)
    for i in range(k):  # the goals held at the end
        close_goal(i, trial.duration_s)
    kinds: dict[str, int] = {}
    for _, _, kind in guard.events:
        kinds[kind] = kinds.get(kind, 0) + 1
    return TrialResult(closest, trial.area_m, reachable, reached, kinds.get("outside_bounds", 0), holds,
                       kinds)


_TURN = Trial(n_uavs=2, speed_m_s=12.0, accel_m_s2=2.5, latency_s=0.4, age_s=0.2, duration_s=60.0,
              area_m=(200.0, 200.0), starts_m=((0.0, 100.0), (70.0, 112.0)),
              script=((0.0, 0, (190.0, 100.0)), (6.0, 0, (20.0, 170.0))))
_CROSS = Trial(n_uavs=2, speed_m_s=15.0, accel_m_s2=2.5, latency_s=0.4, age_s=0.2, duration_s=60.0,
               area_m=(200.0, 200.0), starts_m=((0.0, 100.0), (100.0, 0.0)),
               script=((0.0, 0, (200.0, 100.0)), (0.0, 1, (100.0, 200.0))))
_OVERSHOOT = Trial(n_uavs=3, speed_m_s=15.0, accel_m_s2=2.5, latency_s=0.4, age_s=0.2, duration_s=60.0,
                   area_m=(200.0, 200.0), starts_m=((0.0, 100.0), (100.0, 100.0), (100.0, 50.0)),
                   script=((0.0, 0, (93.0, 100.0)), (3.0, 2, (100.0, 160.0)), (5.0, 0, (180.0, 100.0))))
NAMED_TRIALS: dict[str, Trial] = {
    "turn-at-12-m-s-beside-a-hover": _TURN,
    "crossing-at-15-m-s": _CROSS,
    "held-with-overshoot": _OVERSHOOT,
}
"""Scripted flights (goals by time) that brought the earlier guard under the minimum."""
WORST_BOUNDS: dict[str, dict[str, float]] = {
    "braking-2.5": {"accel_m_s2": 2.5},
    "braking-2": {"accel_m_s2": 2.0},
    "positions-1-s-old": {"age_s": 1.0},
    "round-trip-1.5-s": {"latency_s": 1.5},
    "all-at-once": {"accel_m_s2": 2.0, "age_s": 1.0, "latency_s": 1.5, "loss": 0.2, "rate_hz": 5.0},
}
"""The named worst cases: a turn at 12 m/s beside a hovering vehicle, a crossing at 15 m/s, a vehicle
held on its way with overshoot; each flown with the worst bounds of :data:`WORST_BOUNDS`."""


def random_trial(rng: np.random.Generator, seed: int, duration_s: float = 60.0) -> Trial:
    """A trial drawn within the guard's tested bounds.

    2-10 vehicles, 5-20 m/s, braking 2-5 m/s^2, command latency up to 1.5 s (5 % of commands lost),
    positions up to 1 s old, square areas from the tightest the fleet check accepts for 6 m between
    starts (the minimum and a metre) up to 200 m.
    """
    n = int(rng.integers(2, 11))
    tightest = 6.0 / max_spread_m(n, 1.0, 1.0)  # the fleet check's limit for 6 m between starts
    side = float(np.exp(rng.uniform(np.log(tightest), np.log(200.0))))
    return Trial(n_uavs=n, area_m=(side, side), speed_m_s=float(rng.uniform(5.0, 20.0)),
                 accel_m_s2=float(rng.uniform(2.0, 5.0)), latency_s=float(rng.uniform(0.0, 1.5)),
                 loss=float(rng.choice([0.0, 0.05])), age_s=float(rng.uniform(0.0, 1.0)),
                 rate_hz=float(rng.choice([5.0, 10.0])), noise_m=float(rng.choice([0.0, 0.2])),
                 duration_s=duration_s, seed=seed)
