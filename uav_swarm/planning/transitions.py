"""Transitions between two plans: every UAV flies to its new target and no two come closer than the minimum.

A replan gives each UAV a new target; this module decides *when* (and by where) each one leaves, so that the
flights between the two plans keep ``[uav] min_separation_m`` (3-D with altitude layers, ``[uav]
layer_step_m``) when flown by the env's kinematics, with no guard:

1. **Assignment without crossings.** The planners assign targets by the least sum of *squared* travel
   (distance in :func:`uav_swarm.planning.assignment.assign_targets`, time to reach in planning in
   motion): a convex cost, so two assigned straight paths do not cross where an exchange of their targets
   would shorten the sum (the CAPT argument of Turpin et al.). :func:`squared_assignment` is that step.
2. **Prediction is the flight.** Each UAV's flight is computed step by step with the env's own
   waypoint controller and kinematics (:mod:`uav_swarm.planning.trajectory`, steps of ``step_s``, the
   env's step): speed across the line to the target, speed away from it, one acceleration limit shared by
   braking and turning, the clamp to the area are all in it. Every pair is checked at every step and
   exactly between steps (the env moves on straight lines within a step).
3. **Required distance.** A pair needs the minimum plus ``margin_m`` (3-D with layers) at every step; a
   pair that starts or is planned closer than that (the waypoint controller may carry a UAV up to half a
   step's flight past its target before it settles) needs the minimum itself, never less. Targets closer
   than the minimum (coincident ones included) cannot be resolved, nor can targets at the minimum where
   the landing carries one UAV toward the other: they are reported.
4. **Resolution.** UAVs in no conflict leave at once. A UAV in conflict *holds*: it flies to its braking
   point (where braking at the limit stops it on its heading), waits there at rest and leaves at the first
   departure (steps of ``delay_step_s`` for 3 s, then growing by 40 %, at most until every UAV placed
   before has arrived) whose flight keeps every pair's required distance to the UAVs placed before. A UAV
   that no departure clears *detours*: its hold point moves beside the first UAV on its path (1.25 or 2
   times the distance needed, either side, inside the area), it flies there and on after the same choice
   of departures. Pairs that no choice clears (in two orders) are reported in
   :attr:`Transition.unresolved`: every pair whose flight comes under its required distance, the pairs the
   step guard of :mod:`uav_swarm.world.step_guard` may have to hold. Every other pair keeps its required
   distance when the transition is flown without the guard (:attr:`Transition.tracks_m` is that flight).

The caller flies :meth:`Transition.targets_at` at the env's steps (the hold point until a UAV's departure,
then its target).

Examples:
    >>> from uav_swarm.world.uav import UAVConfig
    >>> starts = np.array([[20.0, 50.0], [50.0, 20.0]])  # two flights that cross at (50, 50)
    >>> targets = np.array([[80.0, 50.0], [50.0, 80.0]])
    >>> plan = plan_transition(starts, np.zeros((2, 2)), targets, UAVConfig(min_separation_m=5.0))
    >>> plan.held.tolist(), bool(plan.closest_m >= 6.0), plan.unresolved.shape
    ([False, True], True, (0, 2))
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from uav_swarm.planning.departures import plan_departures
from uav_swarm.world.separation import pair_distances_m, required_distances_m
from uav_swarm.world.uav import UAVConfig

__all__ = ["Transition", "plan_transition", "required_gaps_m", "squared_assignment", "warm_up"]


@dataclass(frozen=True)
class Transition:
    """When each UAV leaves for its new target.

    Attributes:
        targets_m: ``(K, 2)`` the new targets.
        hold_m: ``(K, 2)`` where a held UAV flies first and waits until it leaves: its braking point, or a
            detour beside a UAV on its path (a UAV that leaves at once: its target).
        delays_s: ``(K,)`` seconds from the replan until the UAV leaves its hold point (0: at once), a whole
            number of steps.
        step_s: The env's step the transition was planned for.
        closest_m: The predicted closest approach of any pair over the transition (3-D with layers).
        unresolved: ``(M, 2)`` pairs ``i < j`` predicted closer than their required distance.
        tracks_m: ``(K, T + 1, 2)`` the predicted flight: each UAV's position after ``0 ... T`` steps, until
            the last one is at rest on its target (with fewer than two UAVs or no minimum, nothing is
            predicted: the positions and the targets).
    """

    targets_m: np.ndarray
    hold_m: np.ndarray
    delays_s: np.ndarray
    step_s: float
    closest_m: float
    unresolved: np.ndarray
    tracks_m: np.ndarray

    @property
    def held(self) -> np.ndarray:
        """``(K,)`` True for a UAV that waits before it leaves."""
        return self.delays_s > 0

    def targets_at(self, elapsed_s: float) -> np.ndarray:
        """``(K, 2)`` what each UAV flies to ``elapsed_s`` after the replan: hold point, then target.

        The step that starts at ``delays_s`` is the first flown to the target (half a step of rounding
        allowed in ``elapsed_s``).
        """
        waiting = elapsed_s < self.delays_s - 0.5 * self.step_s
        return np.where(waiting[:, None], self.hold_m, self.targets_m)


def squared_assignment(starts_m: np.ndarray, goals_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(rows, cols)``: start ``rows[i]`` flies to goal ``cols[i]``, the least sum of squared distances.

    Examples:
        >>> starts = np.array([[0.0, 0.0], [10.0, 0.0]])
        >>> squared_assignment(starts, np.array([[12.0, 0.0], [2.0, 0.0]]))[1].tolist()
        [1, 0]
    """
    diff = np.asarray(starts_m, np.float64)[:, None, :] - np.asarray(goals_m, np.float64)[None, :, :]
    return linear_sum_assignment(np.einsum("ijc,ijc->ij", diff, diff))


def required_gaps_m(positions_m: np.ndarray, targets_m: np.ndarray, min_separation_m: float,
                    altitudes_m: np.ndarray | None = None, margin_m: float = 1.0, landing_m: float = 0.0
                    ) -> np.ndarray:
    """``(K, K)`` horizontal distance each pair must keep over a transition (module docstring, rule 3).

    ``landing_m``: how far past their targets the controller may carry two UAVs before they settle (the
    transition passes ``max_speed * dt``: the waypoint controller brakes up to a step late, half a step's
    flight each); targets closer than the minimum plus the margin plus this keep only the minimum.

    Examples:
        >>> starts, targets = np.array([[0.0, 0.0], [20.0, 0.0]]), np.array([[0.0, 9.0], [5.0, 9.0]])
        >>> float(required_gaps_m(starts, targets, 5.0)[0, 1])  # planned exactly 5 m apart: the minimum
        5.0
    """
    p = np.asarray(positions_m, np.float64).reshape(-1, 2)
    k = len(p)
    minimum = required_distances_m(min_separation_m, altitudes_m, k)
    need = required_distances_m(min_separation_m + margin_m, altitudes_m, k)
    targets = pair_distances_m(np.asarray(targets_m, np.float64).reshape(-1, 2))
    roomy = (pair_distances_m(p) >= need) & (targets >= need + landing_m)
    return np.where(minimum > 0, np.where(roomy, need, minimum), 0.0)


def plan_transition(positions_m: np.ndarray, velocities_m_s: np.ndarray, targets_m: np.ndarray,
                    config: UAVConfig, altitudes_m: np.ndarray | None = None, *, margin_m: float = 1.0,
                    step_s: float = 0.1, delay_step_s: float = 0.5, area_m: np.ndarray | None = None
                    ) -> Transition:
    """Departures that keep every pair apart between the current state and the new targets.

    Args:
        positions_m: ``(K, 2)`` UAV positions now.
        velocities_m_s: ``(K, 2)`` UAV velocities now.
        targets_m: ``(K, 2)`` the new plan's targets (assigned already).
        config: Speed and acceleration limits and ``min_separation_m`` (0: every UAV leaves at once).
        altitudes_m: ``(K,)`` the UAVs' altitudes (layers), or None for one altitude.
        margin_m: Kept beyond the minimum where the starts and targets allow (module docstring, rule 3).
        step_s: The env's step (the transition is flown with its commands changing every step).
        delay_step_s: Granularity of the departures (rounded to whole steps).
        area_m: ``(2,)`` the area's upper corner: the env clamps to it and detours stay inside (None: none).

    Returns:
        The :class:`Transition` (module docstring).
    """
    p = np.asarray(positions_m, np.float64).reshape(-1, 2)
    v = np.asarray(velocities_m_s, np.float64).reshape(-1, 2)
    targets = np.asarray(targets_m, np.float64).reshape(-1, 2)
    k = len(p)
    if k < 2 or config.min_separation_m <= 0:
        return Transition(targets.copy(), targets.copy(), np.zeros(k), step_s, math.inf,
                          np.zeros((0, 2), np.int64), np.stack([p, targets], axis=1))
    req = required_gaps_m(p, targets, config.min_separation_m, altitudes_m, margin_m,
                          config.max_speed_m_s * step_s)
    upper = np.full(2, np.inf) if area_m is None else np.asarray(area_m, np.float64)
    points = np.concatenate([p, targets])
    reach_m = float(np.hypot(*(points.max(axis=0) - points.min(axis=0)))) + 4.0 * float(req.max())
    speed_m_s = config.max_speed_m_s
    flight_s = 3.0 * reach_m / speed_m_s + 4.0 * speed_m_s / config.max_accel_m_s2 + 5.0
    holds, departs, gaps, tracks = plan_departures(
        p, v, targets, req, step_s, speed_m_s, config.max_accel_m_s2, float(upper[0]), float(upper[1]),
        int(math.ceil(flight_s / step_s)), max(1, round(delay_step_s / step_s)))
    unresolved = np.argwhere(np.triu(gaps < req - 1e-9, 1)).astype(np.int64)
    if altitudes_m is not None:
        dz = np.asarray(altitudes_m, np.float64)
        gaps = np.sqrt(gaps**2 + (dz[:, None] - dz[None, :]) ** 2)
    return Transition(targets.copy(), holds, np.maximum(departs, 0) * step_s, step_s, float(gaps.min()),
                      unresolved, tracks)


def warm_up() -> None:
    """Compile (or load from the cache) the kernels now rather than at the first replan."""
    starts = np.array([[0.0, 0.0], [10.0, 0.0]])
    plan_transition(starts, np.zeros((2, 2)), starts[::-1] + 1.0, UAVConfig(min_separation_m=5.0))
