"""The separation guard of a live flight: measured states, their age and each vehicle's limits into the guard.

This is a thin adapter of :class:`uav_swarm.world.guard.FleetGuard` (the guard and its proof). Several
times a second (``[guard] rate_hz``, at least 5) it takes each vehicle's measured position and velocity
(its GLOBAL_POSITION_INT in the flight's East-North frame) with the time it was received (its age is
judged from that; the time it was true is taken as ``position_age_s`` earlier, the soonest it may have
been), and decides each steered vehicle's next point; a vehicle not steered (climbing, landing, flying
home in RTL) is a disc the others keep away from, with the column over its home where it lands. A
vehicle steered before that goes unheard, loses its fix or is being taken back keeps its disc (and its
home column: its failsafe may take it home) until it is measured again; only one known to be on the
ground leaves the guard. Each vehicle is planned with the smaller of ``[guard] accel_m_s2`` /
``jerk_m_s3`` and what it reports (:func:`bridge.flight.limits.read_horizontal_limits`, read before
arming); the guard's limits are its own, apart from the env's ``[uav]`` kinematics.

A hold needs no command: a vehicle whose next point is refused keeps flying to the point it has, inside
its certified disc. The points are sent by the caller (one command, one copy, answered within
``command_delay_s``), who reports each acknowledgement or its absence.

Examples:
    >>> import numpy as np
    >>> guard = FlightGuard(GuardConfig(), min_separation_m=5.0, n_vehicles=2)
    >>> rows = [(0, (0.0, 0.0), (0.0, 0.0), 0.0, (40.0, 0.0), True),
    ...         (1, (40.0, 0.0), (0.0, 0.0), 0.0, (0.0, 0.0), True)]  # a head-on swap
    >>> [d.state for d in guard.decide(rows, now_s=0.1)]  # first, the points where they hover
    ['on', 'on']
    >>> later = [(i, p, v, 1.1, goal, steer) for i, p, v, _, goal, steer in rows]  # received at 1.1 s
    >>> [d.state for d in guard.decide(later, now_s=1.2)]  # no answer within command_delay_s: may go on
    ['free', 'free']
    >>> bool(guard.gap_m(0, 1) >= 5.0)  # the certified discs keep the minimum
    True
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bridge.flight.limits import HorizontalLimits
from typed_config import Config, param
from uav_swarm.world.guard import Bounds, Decision, FleetGuard
from uav_swarm.world.separation import required_distances_m

__all__ = ["GuardConfig", "GuardDecision", "FlightGuard", "Measured"]

GuardDecision = Decision
"""What one vehicle is told (:class:`uav_swarm.world.guard.Decision`)."""

Measured = tuple[int, tuple[float, float], tuple[float, float], float, "tuple[float, float] | None", bool]
"""``(vehicle, (x, y), (vx, vy), received_s, goal or None, steerable)`` of one vehicle with a position."""


@dataclass(frozen=True)
class GuardConfig(Config):
    """The separation guard's bounds and settings (``[guard]``), its own, apart from ``[uav]``."""

    rate_hz: float = param(10.0, ge=5.0, le=50.0, doc="guard decisions per second (measured positions)")
    margin_m: float = param(1.0, ge=0.0, le=50.0, doc="metres added to uav.min_separation_m")
    accel_m_s2: float = param(2.5, gt=0.0, le=20.0,
                              doc="horizontal acceleration and braking the guard plans with at most, m/s^2 "
                                  "(each vehicle: the smaller of this and its own WPNAV_ACCEL / MPC_ACC_HOR)")
    jerk_m_s3: float = param(0.0, ge=0.0, le=1000.0,
                             doc="jerk the guard plans with at most, m/s^3 (0: none; each vehicle: the "
                                 "smaller of this and its own PSC_JERK_XY / MPC_JERK_AUTO)")
    stated_limits: bool = param(False, doc="fly a vehicle whose limits cannot be read with accel_m_s2 and "
                                           "jerk_m_s3 (else it is refused before arming)")
    command_delay_s: float = param(1.0, gt=0.0, le=10.0,
                                   doc="a command takes effect and its acknowledgement is back within this, "
                                       "seconds (one copy; none back: reported, the point kept as possible)")
    position_age_s: float = param(1.0, gt=0.0, le=10.0,
                                  doc="a measured position is at most this old (the vehicle's lag and the "
                                      "link); older: reported, the vehicle held, seconds")
    position_error_m: float = param(0.5, ge=0.0, le=50.0, doc="largest error of a measured position, metres")
    velocity_error_m_s: float = param(0.5, ge=0.0, le=20.0,
                                      doc="largest error of a measured velocity, m/s")
    tracking_error_m: float = param(0.5, ge=0.0, le=50.0,
                                    doc="largest distance between a vehicle and its autopilot's set point "
                                        "(wind, gusts), metres")
    sidestep_after_s: float = param(2.0, ge=0.0, le=60.0,
                                    doc="a vehicle held this long may step round what blocks it, seconds")
    max_step_m: float = param(16.0, ge=1.0, le=64.0,
                              doc="the farthest ahead a vehicle is committed at a time, metres (shorter: "
                                  "smaller certified discs, slower vehicles)")
    return_timeout_s: float = param(120.0, ge=0.0, le=3600.0,
                                    doc="at the end (RTL), vehicles fly home through the guard at most this "
                                        "long; then every one still away is sent RTL at once, seconds")


class FlightGuard:
    """The guard of one flight's vehicles, by their row in the flight (module docstring).

    Args:
        config: The guard's settings.
        min_separation_m: The minimum distance between two vehicles (``[uav] min_separation_m``).
        n_vehicles: Rows of the flight.
        altitudes_m: (n,) cruise altitudes (layers), or None for one altitude.
        area_m: (width, height) of the area a step round another vehicle stays in (None: anywhere).
    """

    def __init__(self, config: GuardConfig, min_separation_m: float, n_vehicles: int,
                 altitudes_m: np.ndarray | None = None, area_m: tuple[float, float] | None = None) -> None:
        self.config = config
        self.need_m = min_separation_m + config.margin_m
        required = required_distances_m(min_separation_m, altitudes_m, n_vehicles)
        required = np.where(required > 0, required + config.margin_m, 0.0)
        self.fleet = FleetGuard(required, detour_after_s=config.sidestep_after_s, detour_m=self.need_m,
                                area_m=area_m, max_step_m=config.max_step_m)
        self.homes_m: dict[int, tuple[float, float]] = {}
        """Each vehicle's home (East, North) by row, where its RTL or failsafe lands it."""
        self._bounds = [self._stated() for _ in range(n_vehicles)]
        self.limits: dict[int, HorizontalLimits] = {}
        self.states: dict[int, str] = {}
        """Each vehicle's guard state after the last :meth:`decide` (by row)."""

    def _stated(self, reported: HorizontalLimits | None = None) -> Bounds:
        cfg = self.config
        accel = cfg.accel_m_s2 if reported is None else min(cfg.accel_m_s2, reported.accel_m_s2)
        jerk = cfg.jerk_m_s3 or math.inf
        if reported is not None:
            jerk = min(jerk, reported.jerk_m_s3)
        return Bounds(accel_m_s2=accel, jerk_m_s3=jerk, position_error_m=cfg.position_error_m,
                      velocity_error_m_s=cfg.velocity_error_m_s, tracking_error_m=cfg.tracking_error_m,
                      command_delay_s=cfg.command_delay_s, position_age_s=cfg.position_age_s,
                      per_axis=reported is not None and reported.per_axis)

    def set_limits(self, row: int, reported: HorizontalLimits | None) -> Bounds:
        """Plan vehicle ``row`` with the smaller of the stated limits and what it reports; its bounds."""
        if reported is not None:
            self.limits[row] = reported
        self._bounds[row] = self._stated(reported)
        return self._bounds[row]

    def forget(self, row: int) -> None:
        """Drop a vehicle known to be on the ground (disarmed): it joins again when it flies again."""
        self.fleet.leave(row)
        self.states.pop(row, None)

    def gap_m(self, a: int, b: int) -> float:
        """The distance between the certified discs of two vehicles, metres."""
        apart = float(np.hypot(*(self.fleet.centre_m(a) - self.fleet.centre_m(b))))
        return apart - self.fleet.radius_m(a) - self.fleet.radius_m(b)

    def decide(self, measured: Sequence[Measured], now_s: float, busy: Sequence[int] = (),
               returning: Sequence[int] = ()) -> list[Decision]:
        """One decision per row of ``measured``; a row steered before and absent now keeps its disc.

        Args:
            measured: Each flying vehicle's measurement, goal and whether the guard steers it.
            now_s: The guard's clock (the stamps' clock), seconds.
            busy: Rows whose previous command is still being sent (they are sent nothing new).
            returning: Rows flying home under their autopilot (RTL): a disc on their position and the
                column over their home (the others not steered are climbing: a disc on their position,
                or, taken back in flight, the disc they had).
        """
        fleet, k = self.fleet, len(self._bounds)
        goals = np.full((k, 2), np.nan)
        steered = set()
        lag_s = self.config.position_age_s  # it was true at most this long before it was received
        for row, (x, y), (vx, vy), received_s, goal, steerable in measured:
            stamp_s = received_s - lag_s
            position, velocity = np.array([x, y]), np.array([vx, vy])
            home = self.homes_m.get(row)
            home_m = None if home is None else np.array(home)
            if not steerable and row not in returning and fleet.joined(row):
                fleet.silent(row, home_m)  # taken back in flight: still flying to a point it was sent
                continue
            if not steerable:
                bounds = self._bounds[row]
                reach = float(bounds.radius_m(np.zeros(2), velocity))
                fleet.obstacle(row, position, reach, home_m if row in returning else None)
                continue
            if not fleet.joined(row):  # after its take-off it may still fly to where it took off
                fleet.join(row, position, self._bounds[row], now_s=stamp_s,
                           earlier_m=() if home_m is None else (home_m,))
            fleet.measure(row, position, velocity, stamp_s, now_s, received_s)
            steered.add(row)
            if goal is not None:
                goals[row] = goal
        listed = {m[0] for m in measured}
        for row in range(k):
            if row not in listed:  # unheard, without a fix, or lost: its disc (or obstacle) stays
                home = self.homes_m.get(row)
                fleet.silent(row, None if home is None else np.array(home))
        for row in busy:
            goals[row] = np.nan
        decisions = fleet.decide(goals, now_s)
        out = [decisions[row] for row, *_ in measured]
        self.states = {row: d.state for (row, *_), d in zip(measured, out, strict=True)}
        return out

    def acknowledged(self, row: int, seq: int, now_s: float) -> None:
        """The vehicle acknowledged point ``seq`` (at ``now_s``)."""
        self.fleet.acknowledged(row, seq, now_s)

    def unacknowledged(self, row: int, seq: int, now_s: float) -> None:
        """Point ``seq`` got no acknowledgement within ``command_delay_s``."""
        self.fleet.unacknowledged(row, seq, now_s)
