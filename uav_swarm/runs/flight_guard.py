"""The separation guard of a live flight: every target passes through it, on the vehicles' measured positions.

Several times a second (``[guard] rate_hz``, at least 5) the guard takes each vehicle's measured
position and velocity (its GLOBAL_POSITION_INT in the flight's East-North frame) and predicts, over
``horizon_s``, where each vehicle goes:

- **on its route**: it keeps its measured velocity for ``latency_s`` (the age of the measurement and
  the command's round trip), then flies the route's points in turn to ``uav.max_speed_m_s``, speeding
  up at ``uav.max_accel_m_s2`` or faster (an autopilot's own acceleration is not known): at each
  instant it is somewhere on the stretch of the route between the two;
- **held**: sent back to where it is now, it keeps its velocity for ``latency_s``, slows at
  ``uav.max_accel_m_s2`` to a stop (``v^2 / 2a`` further, the continuous form of
  :func:`uav_swarm.world.step_guard.stopping_distance_m`) and comes back: it stays between the two.

Vehicles are decided one after the other (the ones the bridge cannot steer first: climbing, or in
a mission of their own; then by UAV id). A vehicle gets its route only when its predicted track
keeps ``min_separation_m + margin_m`` (horizontal distance, whatever the altitudes) in every step of
``step_s`` (between the two stretches of the step, :func:`uav_swarm.world.step_guard.path_distances_m`)
from the tracks of the vehicles decided before it *and* from the held tracks of those not decided
yet; otherwise it is **held**: sent back to the point where it was when held (``MAV_CMD_DO_REPOSITION``
to its measured position, kept while it is held: a position hold inside the fence), until its route
is clear again. A hold is always possible:
every route chosen before was checked against this vehicle's held track. A vehicle whose way
is blocked by one parked on it (still, and not on its goal) goes round it, by a point
``1.5 (min_separation_m + margin_m)`` beside it. Two vehicles that must swap places hold each other;
one held and standing still for ``sidestep_after_s`` then steps aside, across its way, by the same
distance (when that is clear), and the other passes.

Each hold is an event (which vehicle, for which other) and is counted; the guard's state per
vehicle is ``"free"``, ``"held"`` or ``"aside"``.

Examples:
    >>> import numpy as np
    >>> from uav_swarm.world.uav import UAVConfig
    >>> guard = FlightGuard(GuardConfig(), UAVConfig(min_separation_m=5.0, max_speed_m_s=10.0))
    >>> p, v = np.array([[0.0, 0.0], [40.0, 0.0]]), np.zeros((2, 2))  # a head-on swap
    >>> decisions = guard.decide(p, v, [(40.0, 0.0), (0.0, 0.0)], [True, True], now_s=0.0)
    >>> [d.state for d in decisions]
    ['held', 'held']
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from typed_config import Config, param
from uav_swarm.world.step_guard import path_distances_m
from uav_swarm.world.uav import UAVConfig

__all__ = ["GuardConfig", "GuardDecision", "FlightGuard", "route_track_m", "braking_track_m", "route_band_m",
           "braking_band_m"]

_ARRIVED_M = 1.0  # a step-aside point this close is reached


@dataclass(frozen=True)
class GuardConfig(Config):
    """How the flight's separation guard predicts and decides (``[guard]``)."""

    rate_hz: float = param(10.0, ge=5.0, le=50.0, doc="guard decisions per second (measured positions)")
    latency_s: float = param(0.5, ge=0.0, le=5.0,
                             doc="seconds a vehicle keeps its velocity before a command acts (measurement "
                                 "age and command round trip)")
    margin_m: float = param(1.0, ge=0.0, le=50.0,
                            doc="metres added to uav.min_separation_m for position error")
    horizon_s: float = param(30.0, ge=1.0, le=300.0, doc="seconds of each predicted track")
    step_s: float = param(0.25, gt=0.0, le=1.0,
                          doc="time step of the predicted tracks, seconds (each whole step is checked)")
    sidestep_after_s: float = param(3.0, ge=0.0, le=60.0,
                                    doc="a vehicle held and still this long steps aside, seconds")
    return_timeout_s: float = param(120.0, ge=0.0, le=3600.0,
                                    doc="at the end (RTL), vehicles fly home through the guard at most this "
                                        "long; then every one still away is sent RTL at once, seconds")


@dataclass(frozen=True)
class GuardDecision:
    """What one vehicle is told now.

    Attributes:
        state: ``"free"`` (its route), ``"held"`` (stop where it can) or ``"aside"`` (stepping aside).
        point_m: The (x, y) it is sent to now (None: no command, e.g. no target yet).
        blocker: Index of the vehicle its route would have come too close to (-1: none).
    """

    state: str
    point_m: tuple[float, float] | None
    blocker: int = -1


def _times(config: GuardConfig) -> np.ndarray:
    return np.arange(0.0, config.horizon_s + 1e-9, config.step_s)


def braking_track_m(p: np.ndarray, v: np.ndarray, times_s: np.ndarray, latency_s: float,
                    accel_m_s2: float) -> np.ndarray:
    """(T, 2) where a vehicle at ``p`` moving at ``v`` is at ``times_s`` if it brakes after ``latency_s``."""
    speed = float(np.hypot(*v))
    if speed < 1e-9:
        return np.repeat(p[None, :], times_s.size, axis=0)
    unit = v / speed
    t = np.maximum(times_s - latency_s, 0.0)
    braked = np.minimum(t, speed / accel_m_s2)
    along = np.minimum(times_s, latency_s) * speed + speed * braked - 0.5 * accel_m_s2 * braked**2
    return p[None, :] + along[:, None] * unit[None, :]


def route_track_m(p: np.ndarray, v: np.ndarray, route_m: Sequence[tuple[float, float]], times_s: np.ndarray,
                  latency_s: float, speed_m_s: float, accel_m_s2: float) -> np.ndarray:
    """(T, 2) where a vehicle flying ``route_m`` after ``latency_s`` at its velocity is at ``times_s``.

    It speeds up at ``accel_m_s2`` (``math.inf``: at once) from its speed along the route.
    """
    start = p + v * latency_s
    points = np.vstack([start[None, :], np.asarray(route_m, dtype=np.float64).reshape(-1, 2)])
    legs = np.diff(points, axis=0)
    lengths = np.hypot(legs[:, 0], legs[:, 1])
    cumulative = np.concatenate([[0.0], np.cumsum(lengths)])
    first = legs[0] / lengths[0] if lengths[0] > 1e-9 else np.zeros(2)
    u0 = min(max(float(v @ first), 0.0), speed_m_s)
    t = np.maximum(times_s - latency_s, 0.0)
    ramp = max(speed_m_s - u0, 0.0) / accel_m_s2  # seconds until full speed
    ramped = np.minimum(t, ramp)
    speeding = 0.5 * accel_m_s2 * ramped**2 if math.isfinite(accel_m_s2) else np.zeros_like(t)
    distance = u0 * ramped + speeding + speed_m_s * np.maximum(t - ramp, 0.0)
    distance = np.minimum(distance, cumulative[-1])
    leg = np.clip(np.searchsorted(cumulative, distance, side="right") - 1, 0, max(len(lengths) - 1, 0))
    with np.errstate(invalid="ignore", divide="ignore"):
        fraction = np.where(lengths[leg] > 1e-9, (distance - cumulative[leg]) / lengths[leg], 0.0)
    moving = points[leg] + fraction[:, None] * legs[leg]
    before = times_s < latency_s
    drift = p[None, :] + times_s[:, None] * v[None, :]
    return np.where(before[:, None], drift, moving)


def route_band_m(p: np.ndarray, v: np.ndarray, route_m: Sequence[tuple[float, float]], times_s: np.ndarray,
                 latency_s: float, speed_m_s: float, accel_m_s2: float) -> np.ndarray:
    """(T, 2, 2): where on its route a vehicle is from ``times_s[k]`` to ``times_s[k + 1]``.

    From where one speeding up at ``accel_m_s2`` to ``speed_m_s`` is at the first to where one at full
    speed at once is at the second (its measured speed when faster: an autopilot may fly faster than
    asked): an autopilot's own acceleration lies between, and so does every instant of the step.
    """
    slow = route_track_m(p, v, route_m, times_s, latency_s, speed_m_s, accel_m_s2)
    fast = route_track_m(p, v, route_m, times_s, latency_s, max(speed_m_s, float(np.hypot(*v))), math.inf)
    return np.stack([slow, np.concatenate([fast[1:], fast[-1:]])], axis=1)


def braking_band_m(p: np.ndarray, v: np.ndarray, times_s: np.ndarray, latency_s: float,
                   accel_m_s2: float) -> np.ndarray:
    """(T, 2, 2): where a held vehicle is from ``times_s[k]`` to ``times_s[k + 1]``.

    Sent back to where it is now (``p``), it is between ``p`` and where one slowing at ``accel_m_s2``
    after ``latency_s`` stops (its overshoot, and the way back).
    """
    late = braking_track_m(p, v, times_s, latency_s, accel_m_s2)
    early = np.repeat(p[None, :], times_s.size, axis=0)
    return np.stack([early, np.concatenate([late[1:], late[-1:]])], axis=1)


def _gaps(band: np.ndarray, others: np.ndarray, enough_m: np.ndarray | float) -> np.ndarray:
    """(M,) least distance over time between ``band`` (T, 2, 2) and each of ``others`` (M, T, 2, 2).

    At each time both vehicles lie somewhere on their stretch: the distance is the segments'
    (:func:`uav_swarm.world.step_guard.path_distances_m`). Pairs that keep ``enough_m`` by a bound from
    the stretches' midpoints and half lengths get that bound (at least ``enough_m``) instead.
    """
    if others.shape[0] == 0:
        return np.zeros(0)
    mid, half = band.mean(axis=1), 0.5 * np.linalg.norm(band[:, 1] - band[:, 0], axis=-1)  # (T, 2), (T,)
    other_mid = others.mean(axis=2)  # (M, T, 2)
    other_half = 0.5 * np.linalg.norm(others[:, :, 1] - others[:, :, 0], axis=-1)  # (M, T)
    bound = (np.linalg.norm(other_mid - mid[None], axis=-1) - half[None] - other_half).min(axis=1)
    gaps = bound.copy()
    close = np.flatnonzero(bound < np.broadcast_to(enough_m, bound.shape))
    if close.size:
        exact = path_distances_m(band[:, None], np.swapaxes(others[close], 0, 1))  # (T, 1, C)
        gaps[close] = exact[:, 0, :].min(axis=0)
    return gaps


class FlightGuard:
    """Decides, on measured positions, which vehicles fly their routes and which hold (module docstring).

    Args:
        config: The guard's settings.
        uav: ``min_separation_m``, ``max_speed_m_s`` and ``max_accel_m_s2`` (the deceleration limit).
        area_m: (width, height) of the area a step aside must stay in (None: anywhere).
    """

    def __init__(self, config: GuardConfig, uav: UAVConfig,
                 area_m: tuple[float, float] | None = None) -> None:
        self.config = config
        self.uav = uav
        self.area_m = area_m
        self.need_m = uav.min_separation_m + config.margin_m
        self._times = _times(config)
        self._held_since: dict[int, float] = {}
        self._aside: dict[int, tuple[tuple[float, float], bool]] = {}  # a way point, then the goal?
        self._hold_at: dict[int, tuple[float, float]] = {}
        self.states: dict[int, str] = {}
        """Each vehicle's guard state after the last :meth:`decide` (by index)."""

    def forget(self, index: int) -> None:
        """Drop what the guard remembers of a vehicle (it left the flight, or got a new target)."""
        self._held_since.pop(index, None)
        self._aside.pop(index, None)
        self._hold_at.pop(index, None)
        self.states.pop(index, None)

    def decide(self, positions_m: np.ndarray, velocities_m_s: np.ndarray,
               goals_m: Sequence[tuple[float, float] | None], steerable: Sequence[bool],
               now_s: float) -> list[GuardDecision]:
        """One decision per vehicle (module docstring).

        Args:
            positions_m: (K, 2) measured horizontal positions (East, North), metres.
            velocities_m_s: (K, 2) measured horizontal velocities, m/s.
            goals_m: Each vehicle's target (None: no target, it stays where it is).
            steerable: False for a vehicle the guard cannot command (climbing, flying its own mission):
                it is decided first, braking.
            now_s: A monotonic clock, seconds (for how long a vehicle has been held).
        """
        p = np.asarray(positions_m, dtype=np.float64).reshape(-1, 2)
        v = np.asarray(velocities_m_s, dtype=np.float64).reshape(-1, 2)
        k = p.shape[0]
        cfg, uav, times = self.config, self.uav, self._times
        brakes = np.stack([braking_band_m(p[i], v[i], times, cfg.latency_s, uav.max_accel_m_s2)
                           for i in range(k)]) if k else np.zeros((0, times.size, 2, 2))
        # A pair already closer than the minimum may only keep or widen its gap.
        threshold = np.full((k, k), self.need_m)
        for i in range(k):
            gaps = _gaps(brakes[i], brakes, self.need_m)
            threshold[i] = np.minimum(threshold[i], gaps - 1e-6)
        decided = brakes.copy()
        order = sorted(range(k), key=lambda i: (bool(steerable[i]), i))
        decisions: list[GuardDecision | None] = [None] * k
        for i in order:
            goal = goals_m[i]
            if not steerable[i] or goal is None:
                self.forget(i)
                decisions[i] = GuardDecision("free", None)
                continue
            decisions[i], decided[i] = self._choose(i, p, v, goal, decided, threshold[i], now_s)
        self.states = {i: d.state for i, d in enumerate(decisions) if d is not None}
        return [d if d is not None else GuardDecision("free", None) for d in decisions]

    def _choose(self, i: int, p: np.ndarray, v: np.ndarray, goal: tuple[float, float], decided: np.ndarray,
                threshold: np.ndarray, now_s: float) -> tuple[GuardDecision, np.ndarray]:
        cfg, uav, times = self.config, self.uav, self._times
        others = np.arange(decided.shape[0]) != i

        def clear(track: np.ndarray) -> tuple[bool, int]:
            gaps = _gaps(track, decided[others], threshold[others])
            short = gaps < threshold[others]
            if not short.any():
                return True, -1
            return False, int(np.flatnonzero(others)[int(np.argmax(short))])

        via = self._aside.get(i)
        if via is not None and math.dist(via[0], p[i]) <= _ARRIVED_M:
            del self._aside[i]  # reached: from here on to its goal
            via = None
        route = [goal] if via is None else [via[0], goal] if via[1] else [via[0]]
        track = route_band_m(p[i], v[i], route, times, cfg.latency_s, uav.max_speed_m_s, uav.max_accel_m_s2)
        ok, blocker = clear(track)
        if ok:
            self._held_since.pop(i, None)
            self._hold_at.pop(i, None)
            return GuardDecision("free" if via is None else "aside", route[0]), track
        if via is not None:
            self._aside.pop(i, None)  # its way round is no longer clear: it holds, then starts again
        since = self._held_since.setdefault(i, now_s)
        still = float(np.hypot(*v[i])) < 0.5
        parked = float(np.hypot(*v[blocker])) < 0.5 and math.dist(p[blocker], goal) >= self.need_m
        ways = [(point, True) for point in self._around(p[i], goal, p[blocker])] if parked else []
        if still and now_s - since >= cfg.sidestep_after_s:
            ways += [(point, False) for point in self._sidesteps(p[i], goal)]
        for point, then_goal in ways:  # round a parked vehicle, or (held long) aside
            way = [point, goal] if then_goal else [point]
            step = route_band_m(p[i], v[i], way, times, cfg.latency_s, uav.max_speed_m_s, uav.max_accel_m_s2)
            if clear(step)[0]:
                self._aside[i] = (point, then_goal)
                self._held_since.pop(i, None)
                self._hold_at.pop(i, None)
                return GuardDecision("aside", point, blocker), step
        here = self._hold_at.setdefault(i, (float(p[i, 0]), float(p[i, 1])))  # kept while it is held
        return GuardDecision("held", here, blocker), decided[i]

    def _around(self, p: np.ndarray, goal: tuple[float, float],
                other: np.ndarray) -> list[tuple[float, float]]:
        """Points beside a vehicle parked on the way, on either side of the way, the shorter way first."""
        way = np.asarray(goal, dtype=np.float64) - p
        length = float(np.hypot(*way))
        if length < 1e-9:
            return []
        across = np.array([-way[1], way[0]]) / length
        points = [other + side * 1.5 * self.need_m * across for side in (1.0, -1.0)]
        points.sort(key=lambda q: float(np.hypot(*(q - p)) + np.hypot(*(np.asarray(goal) - q))))
        return self._inside(points)

    def _sidesteps(self, p: np.ndarray, goal: tuple[float, float]) -> list[tuple[float, float]]:
        """Points across its way, on either side, to step aside to."""
        way = np.asarray(goal, dtype=np.float64) - p
        length = float(np.hypot(*way))
        if length < 1e-9:
            return []
        across = np.array([-way[1], way[0]]) / length
        return self._inside([p + side * 1.5 * self.need_m * across for side in (1.0, -1.0)])

    def _inside(self, points: list[np.ndarray]) -> list[tuple[float, float]]:
        """The points inside the area (all of them without one)."""
        if self.area_m is not None:
            w, h = self.area_m
            points = [q for q in points if 0.0 <= q[0] <= w and 0.0 <= q[1] <= h]
        return [(float(q[0]), float(q[1])) for q in points]
