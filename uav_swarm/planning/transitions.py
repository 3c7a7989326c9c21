"""Transitions between two plans: every UAV flies to its new target and no two come closer than the minimum.

A replan gives each UAV a new target; this module decides *when* each one leaves, so that the flights
between the two plans keep ``[uav] min_separation_m`` (3-D with altitude layers, ``[uav] layer_step_m``):

1. **Assignment without crossings.** The planners assign targets by the least sum of *squared* travel
   (distance in :func:`uav_swarm.planning.assignment.assign_targets`, time to reach in planning in
   motion): a convex cost, so two assigned straight paths do not cross where an exchange of their targets
   would shorten the sum (the CAPT argument of Turpin et al.). :func:`squared_assignment` is that step.
2. **Prediction.** Each UAV flies a straight line to its target with the speed profile of the waypoint
   controller of :mod:`uav_swarm.world.uav`: from its current speed along the line, accelerating at
   ``max_accel_m_s2`` up to ``max_speed_m_s``, braking to a stop on the target (closed form, all UAVs
   and instants at once). A UAV's speed across its line (it was flying elsewhere) adds its stopping
   distance ``v^2 / 2a`` to the distance its pairs need.
3. **Closest approach.** Every pair's least distance over the predicted flights, sampled every
   ``sample_s`` and exact between samples for the linear motion in between
   (:mod:`uav_swarm.planning.trajectory`).
4. **Resolution.** UAVs in no conflict leave at once. A UAV in conflict *holds*: it brakes to a stop
   on its current heading (the hold point) and waits there until its departure, the first of 0 and
   the brake time plus a wait (steps of ``delay_step_s`` for 3 s, then growing by 40 %, at most until
   all have arrived) that keeps the minimum (plus ``margin_m``) to every UAV already
   scheduled, over the whole flight and at the targets. A UAV that no delay clears (another UAV sits on
   its path, or their paths overlap head-on) *detours*: its hold point moves beside the first UAV on its
   path (1.25 or 2 times the distance needed, either side, inside the area), it flies there and on after
   the same choice of waits. A UAV still in conflict is scheduled first in a second pass. Pairs that
   neither pass clears are reported in :attr:`Transition.unresolved`; the step guard of
   :func:`uav_swarm.world.step_guard.guard_commands` is the last safety net for them.

The caller flies :meth:`Transition.targets_at` (the hold point until a UAV's departure, then its target).

Examples:
    >>> from uav_swarm.world.uav import UAVConfig
    >>> starts = np.array([[20.0, 50.0], [50.0, 20.0]])  # two flights that cross at (50, 50)
    >>> targets = np.array([[80.0, 50.0], [50.0, 80.0]])
    >>> plan = plan_transition(starts, np.zeros((2, 2)), targets, UAVConfig(min_separation_m=5.0))
    >>> plan.delays_s.tolist(), bool(plan.closest_m >= 5.0), plan.unresolved.shape
    ([0.0, 1.0], True, (0, 2))
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import linear_sum_assignment

from uav_swarm.planning.trajectory import Legs, arrival_s, first_clear, pair_closest_m, tracks_m
from uav_swarm.world.separation import pair_distances_m, required_distances_m
from uav_swarm.world.step_guard import path_distances_m
from uav_swarm.world.uav import UAVConfig

__all__ = ["Transition", "plan_transition", "predict_positions_m", "squared_assignment"]


@dataclass(frozen=True)
class Transition:
    """When each UAV leaves for its new target.

    Attributes:
        targets_m: ``(K, 2)`` the new targets.
        hold_m: ``(K, 2)`` where each UAV flies first and waits until it leaves: its braking point (its
            position at rest), or a detour beside a UAV on its path.
        delays_s: ``(K,)`` seconds from the replan until the UAV leaves its hold point (0: at once).
        closest_m: The predicted closest approach of any pair over the transition (3-D with layers).
        unresolved: ``(M, 2)`` pairs ``i < j`` still predicted closer than their minimum.
    """

    targets_m: np.ndarray
    hold_m: np.ndarray
    delays_s: np.ndarray
    closest_m: float
    unresolved: np.ndarray

    @property
    def held(self) -> np.ndarray:
        """``(K,)`` True for a UAV that waits before it leaves."""
        return self.delays_s > 0

    def targets_at(self, elapsed_s: float) -> np.ndarray:
        """``(K, 2)`` what each UAV flies to ``elapsed_s`` after the replan: hold point, then target."""
        return np.where((elapsed_s < self.delays_s)[:, None], self.hold_m, self.targets_m)


def squared_assignment(starts_m: np.ndarray, goals_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(rows, cols)``: start ``rows[i]`` flies to goal ``cols[i]``, the least sum of squared distances.

    Examples:
        >>> starts = np.array([[0.0, 0.0], [10.0, 0.0]])
        >>> squared_assignment(starts, np.array([[12.0, 0.0], [2.0, 0.0]]))[1].tolist()
        [1, 0]
    """
    diff = np.asarray(starts_m, np.float64)[:, None, :] - np.asarray(goals_m, np.float64)[None, :, :]
    return linear_sum_assignment(np.einsum("ijc,ijc->ij", diff, diff))


def predict_positions_m(positions_m: np.ndarray, velocities_m_s: np.ndarray, targets_m: np.ndarray,
                        t_s: np.ndarray, config: UAVConfig, delays_s: np.ndarray | None = None) -> np.ndarray:
    """``(K, T, 2)`` where each UAV is predicted at times ``t_s`` (T,) in the transition (module docstring).

    Args:
        positions_m: ``(K, 2)`` positions now.
        velocities_m_s: ``(K, 2)`` velocities now.
        targets_m: ``(K, 2)`` the new targets.
        t_s: ``(T,)`` seconds from now.
        config: Speed and acceleration limits.
        delays_s: ``(K,)`` departure of each UAV from its hold point (default: every UAV leaves at once).
    """
    fleet = _fleet(np.asarray(positions_m, np.float64).reshape(-1, 2),
                   np.asarray(velocities_m_s, np.float64).reshape(-1, 2),
                   np.asarray(targets_m, np.float64).reshape(-1, 2), config)
    k = len(fleet.start)
    delays = np.zeros(k) if delays_s is None else np.asarray(delays_s, np.float64)
    return tracks_m(_chosen(fleet, delays, np.arange(k)), np.asarray(t_s, np.float64), config)


@dataclass(frozen=True)
class _Fleet:
    """The quantities of one transition: both ways a UAV may fly (at once, or by its hold point)."""

    start: np.ndarray
    turn: np.ndarray  # the hold point (its braking point, or a detour's)
    end: np.ndarray
    velocity: np.ndarray
    speed0: np.ndarray  # speed along the leg to the hold point
    speed0_direct: np.ndarray  # speed along the line to the target when leaving at once
    lateral_m: np.ndarray  # stopping distance of the speed across that line
    brake_s: np.ndarray  # time to stop on the hold point
    direct_s: np.ndarray  # flight time straight to the target, leaving at once
    after_s: np.ndarray  # flight time from the hold point to the target, from rest


def _fleet(p: np.ndarray, v: np.ndarray, targets: np.ndarray, config: UAVConfig) -> _Fleet:
    speed = np.hypot(v[:, 0], v[:, 1])
    a = config.max_accel_m_s2
    with np.errstate(divide="ignore", invalid="ignore"):
        heading = np.where(speed[:, None] > 1e-9, v / speed[:, None], 0.0)
        offset = targets - p
        length = np.hypot(offset[:, 0], offset[:, 1])
        unit = np.where(length[:, None] > 1e-9, offset / length[:, None], 0.0)
    speed = np.minimum(speed, config.max_speed_m_s)
    along = np.maximum(np.einsum("kc,kc->k", v, unit), 0.0)
    across = np.abs(v[:, 0] * unit[:, 1] - v[:, 1] * unit[:, 0])
    turn = p + heading * (speed * speed / (2.0 * a))[:, None]
    return _Fleet(p, turn, targets, v, speed, np.minimum(along, config.max_speed_m_s),
                  np.minimum(across, config.max_speed_m_s) ** 2 / (2.0 * a), speed / a,
                  arrival_s(np.hypot(*(targets - p).T), np.minimum(along, config.max_speed_m_s), config),
                  arrival_s(np.hypot(*(targets - turn).T), 0.0, config))


def plan_transition(positions_m: np.ndarray, velocities_m_s: np.ndarray, targets_m: np.ndarray,
                    config: UAVConfig, altitudes_m: np.ndarray | None = None, *, margin_m: float = 1.0,
                    sample_s: float = 0.2, delay_step_s: float = 0.5, area_m: np.ndarray | None = None
                    ) -> Transition:
    """Departure times that keep every pair apart between the current state and the new targets.

    Args:
        positions_m: ``(K, 2)`` UAV positions now.
        velocities_m_s: ``(K, 2)`` UAV velocities now.
        targets_m: ``(K, 2)`` the new plan's targets (assigned already).
        config: Speed and acceleration limits and ``min_separation_m`` (0: every UAV leaves at once).
        altitudes_m: ``(K,)`` the UAVs' altitudes (layers), or None for one altitude.
        margin_m: Kept beyond the minimum in the prediction (the controller does not fly the model exactly).
        sample_s: Sampling period of the predicted flights (exact between samples for linear motion).
        delay_step_s: Granularity of the departure delays.
        area_m: ``(2,)`` the area's upper corner: detours stay inside it (None: no border).

    Returns:
        The :class:`Transition` (module docstring).
    """
    p = np.asarray(positions_m, np.float64).reshape(-1, 2)
    v = np.asarray(velocities_m_s, np.float64).reshape(-1, 2)
    targets = np.asarray(targets_m, np.float64).reshape(-1, 2)
    k = len(p)
    fleet = _fleet(p, v, targets, config)
    delays = np.zeros(k)
    if k < 2 or config.min_separation_m <= 0:
        return Transition(targets.copy(), fleet.turn, delays, np.inf, np.zeros((0, 2), np.int64))
    need = required_distances_m(config.min_separation_m, altitudes_m, k)
    need = np.where(need > 0, need + margin_m + fleet.lateral_m[:, None] + fleet.lateral_m[None, :], 0.0)
    # a pair that starts (or is planned) closer than that may only keep its gap: no schedule widens it
    need = np.minimum(need, np.minimum(pair_distances_m(p), pair_distances_m(targets)) - 1e-6)
    np.fill_diagonal(need, 0.0)
    gaps = _gaps(fleet, delays, need, config, sample_s)
    conflicted = np.flatnonzero((gaps < need).any(axis=1))
    if len(conflicted):
        delays, fleet = _resolve(fleet, conflicted, need, config, sample_s, delay_step_s, area_m)
        gaps = _gaps(fleet, delays, need, config, sample_s)
    unresolved = np.argwhere(np.triu(gaps < need, 1)).astype(np.int64)
    if altitudes_m is not None:
        dz = np.asarray(altitudes_m, np.float64)
        gaps = np.sqrt(gaps**2 + (dz[:, None] - dz[None, :]) ** 2)
    return Transition(targets.copy(), fleet.turn, delays, float(gaps.min()), unresolved)


def _grid(horizon_s: float, sample_s: float) -> np.ndarray:
    """Sample times ``0 ... horizon_s`` (the last sample at or after the horizon)."""
    return np.arange(0.0, horizon_s + 1.5 * sample_s, sample_s)


def _finish_s(fleet: _Fleet, delays: np.ndarray, ids: np.ndarray, config: UAVConfig) -> np.ndarray:
    """When UAVs ``ids`` are predicted on their targets with these delays."""
    return np.where(delays[ids] > 0, delays[ids] + fleet.after_s[ids], fleet.direct_s[ids])


def _paths(fleet: _Fleet, delays: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """``(N, 3, 2)`` the polyline each UAV of ``ids`` flies: start, hold point (or start), target."""
    held = (delays[ids] > 0)[:, None]
    return np.stack([fleet.start[ids], np.where(held, fleet.turn[ids], fleet.start[ids]), fleet.end[ids]], 1)


def _gaps(fleet: _Fleet, delays: np.ndarray, need: np.ndarray, config: UAVConfig, sample_s: float
          ) -> np.ndarray:
    """``(K, K)`` predicted closest approach of the pairs, at least (horizontal; ``inf`` on the diagonal).

    Each path lies in a disc around the middle of its start and target; pairs whose discs stay ``need``
    apart get the gap of their discs (a lower bound, enough to clear them), the others the closest
    approach of their sampled flights.
    """
    ids = np.arange(len(fleet.start))
    held = (delays > 0)[:, None]
    centre = 0.5 * (fleet.start + fleet.end)
    radius = np.maximum(np.hypot(*(fleet.start - centre).T), np.where(
        held[:, 0], np.hypot(*(fleet.turn - centre).T), 0.0))
    gaps = pair_distances_m(centre) - radius[:, None] - radius[None, :]
    near = np.flatnonzero((gaps < need).any(axis=1))
    if len(near):
        times = _grid(float(_finish_s(fleet, delays, near, config).max()), sample_s)
        tracks = tracks_m(_chosen(fleet, delays, ids[near]), times, config)
        close = pair_closest_m(tracks)
        gaps[np.ix_(near, near)] = np.maximum(gaps[np.ix_(near, near)], close)
    np.fill_diagonal(gaps, np.inf)
    return gaps


def _resolve(fleet: _Fleet, conflicted: np.ndarray, need: np.ndarray, config: UAVConfig, sample_s: float,
             delay_step_s: float, area_m: np.ndarray | None, passes: int = 2) -> tuple[np.ndarray, _Fleet]:
    """Departure delays and detours (module docstring, step 4); UAVs left over go first in the next pass.

    The first order lets a UAV whose position lies on others' paths leave before them, and one whose
    target lies on others' paths leave after them.
    """
    k = len(fleet.start)
    free = np.setdiff1d(np.arange(k), conflicted)
    flights = _paths(fleet, np.zeros(k), np.arange(k))
    here = path_distances_m(np.repeat(fleet.start[:, None], 2, 1), flights) < need  # I sit on their path
    there = path_distances_m(np.repeat(fleet.end[:, None], 2, 1), flights) < need  # my target is on it
    blocking = here.sum(axis=1) - there.sum(axis=1)
    order = [int(j) for j in conflicted[np.argsort(-blocking[conflicted], kind="stable")]]
    best: tuple[int, float, np.ndarray, _Fleet] | None = None
    for _ in range(passes):
        planned = replace(fleet, turn=fleet.turn.copy(), speed0=fleet.speed0.copy(),  # detours change these
                          after_s=fleet.after_s.copy())
        delays, stuck = _schedule(planned, free, order, need, config, sample_s, delay_step_s, area_m)
        if best is None or (len(stuck), float(delays.sum())) < best[:2]:
            best = (len(stuck), float(delays.sum()), delays, planned)
        if not stuck:
            break
        order = stuck + [j for j in order if j not in stuck]
    assert best is not None
    return best[2], best[3]


def _schedule(fleet: _Fleet, free: np.ndarray, order: list[int], need: np.ndarray, config: UAVConfig,
              sample_s: float, delay_step_s: float, area_m: np.ndarray | None
              ) -> tuple[np.ndarray, list[int]]:
    """Schedule the UAVs of ``order`` one by one against the free ones and those scheduled before.

    A UAV that no delay clears tries a detour around the first UAV whose position or target lies on its
    path (its hold point moved beside it, on either side); its chosen hold point is written into ``fleet``.
    """
    delays = np.zeros(len(fleet.start))
    scheduled = [int(i) for i in free]
    stuck: list[int] = []
    for j in order:
        others = np.array(scheduled, dtype=np.int64)
        if len(others):  # only those whose paths come near either way j may fly
            mine = np.stack([fleet.start[j], fleet.turn[j], fleet.end[j]])[None]
            reach = path_distances_m(mine, _paths(fleet, delays, others))[0]
            others = others[reach < need[j, others]]
        if len(others):
            done_s = float(_finish_s(fleet, delays, others, config).max())
            waits = _waits_s(done_s, delay_step_s)
            choice = _first_clear(fleet, delays, j, others, np.concatenate([[0.0], fleet.brake_s[j] + waits]),
                                  need, config, sample_s)
            detours = [] if choice is not None else _detours(fleet, delays, j, others, need, area_m)
            for via, speed0 in detours:
                fleet.turn[j], fleet.speed0[j] = via, speed0
                fleet.after_s[j] = float(arrival_s(np.hypot(*(fleet.end[j] - via)), 0.0, config))
                reach_s = float(arrival_s(np.hypot(*(via - fleet.start[j])), speed0, config))
                choice = _first_clear(fleet, delays, j, others, reach_s + waits, need, config, sample_s)
                if choice is not None:
                    break
            if choice is None:
                stuck.append(j)
                fleet.turn[j], fleet.speed0[j] = _braking_point(fleet, j, config)
                fleet.after_s[j] = float(arrival_s(np.hypot(*(fleet.end[j] - fleet.turn[j])), 0.0, config))
            delays[j] = 0.0 if choice is None else choice
        scheduled.append(j)
    return delays, stuck


def _braking_point(fleet: _Fleet, j: int, config: UAVConfig) -> tuple[np.ndarray, float]:
    """UAV ``j``'s hold point when it brakes on its heading, and its speed on the way (module docstring)."""
    speed = fleet.brake_s[j] * config.max_accel_m_s2
    return fleet.start[j] + fleet.velocity[j] * speed / (2.0 * config.max_accel_m_s2), float(speed)


def _detours(fleet: _Fleet, delays: np.ndarray, j: int, others: np.ndarray, need: np.ndarray,
             area_m: np.ndarray | None) -> list[tuple[np.ndarray, float]]:
    """Hold points beside the first obstacle on UAV ``j``'s straight path, and the speed to enter the leg.

    Obstacles are the others' hold points (or starts) and targets that lie within ``need`` of the path.
    """
    start, end = fleet.start[j], fleet.end[j]
    line = end - start
    length = float(np.hypot(*line))
    if length < 1e-9:
        return []
    unit = line / length
    held = (delays[others] > 0)[:, None]
    points = np.concatenate([np.where(held, fleet.turn[others], fleet.start[others]), fleet.end[others]])
    gap = np.concatenate([need[j, others], need[j, others]])
    along = np.clip((points - start) @ unit, 0.0, length)
    off = np.hypot(*(points - start - along[:, None] * unit).T)
    blocking = np.flatnonzero(off < gap)
    if len(blocking) == 0:
        return []
    first = blocking[np.argmin(along[blocking])]
    normal = np.array([-unit[1], unit[0]])
    out = []
    for scale in (1.25, 2.0):
        for side in (1.0, -1.0):
            via = points[first] + side * scale * gap[first] * normal
            if area_m is not None and not (np.all(via >= 0.0) and np.all(via <= area_m)):
                continue
            toward = via - start
            entry = fleet.velocity[j] @ toward / max(float(np.hypot(*toward)), 1e-9)
            out.append((via, float(np.clip(entry, 0.0, fleet.speed0[j]))))
    return out


def _waits_s(done_s: float, step_s: float, fine: int = 6, growth: float = 1.4) -> np.ndarray:
    """Waits to try after braking: ``fine`` steps of ``step_s``, then growing by ``growth``, then ``done_s``.

    Examples:
        >>> _waits_s(10.0, 0.5).tolist()
        [0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 4.5, 6.5, 9.5, 10.0]
    """
    waits = list(step_s * np.arange(fine + 1))
    while waits[-1] * growth < done_s:
        waits.append(step_s * np.ceil(waits[-1] * growth / step_s))
    if waits[-1] < done_s:
        waits.append(done_s)
    return np.array(waits)


def _chosen(fleet: _Fleet, delays: np.ndarray, ids: np.ndarray) -> Legs:
    """The legs of UAVs ``ids`` with their delays (0: straight to the target at once)."""
    held = delays[ids] > 0
    return Legs(fleet.start[ids], np.where(held[:, None], fleet.turn[ids], fleet.end[ids]), fleet.end[ids],
                 np.where(held, fleet.speed0[ids], fleet.speed0_direct[ids]),
                 np.where(held, delays[ids], np.inf))


def _first_clear(fleet: _Fleet, delays: np.ndarray, j: int, ids: np.ndarray, candidates: np.ndarray,
                 need: np.ndarray, config: UAVConfig, sample_s: float) -> float | None:
    """The first delay of ``candidates`` with which UAV ``j`` keeps ``need`` to the UAVs ``ids``, or None."""
    flight_s = float(max(fleet.direct_s[j], fleet.after_s[j]))
    times = _grid(max(float(_finish_s(fleet, delays, ids, config).max()), float(candidates.max()) + flight_s),
                  sample_s)
    held = candidates > 0
    n = len(candidates)
    legs = Legs(np.repeat(fleet.start[j:j + 1], n, 0), np.where(held[:, None], fleet.turn[j], fleet.end[j]),
                 np.repeat(fleet.end[j:j + 1], n, 0),
                 np.where(held, fleet.speed0[j], fleet.speed0_direct[j]), np.where(held, candidates, np.inf))
    theirs = tracks_m(_chosen(fleet, delays, ids), times, config)
    index = first_clear(legs, theirs, need[j, ids], times, config)
    return None if index < 0 else float(candidates[index])
