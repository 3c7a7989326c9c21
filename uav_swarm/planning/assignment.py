"""Assigning UAVs to placement targets: Hungarian matching with hysteresis and a fallback.

The planner turns a utility map into at most ``n`` candidate positions; this
module decides which UAV flies to which candidate:

1. **Hysteresis (no churn).** A UAV whose previous target is within
   ``hysteresis_m`` of a new candidate keeps its previous target (the closest such
   candidate is consumed), so small crowd motion does not reshuffle the swarm.
   Which previous targets survive is itself decided by a Hungarian matching
   between previous targets and candidates, so two UAVs never claim one candidate.
2. **Hungarian assignment.** The remaining candidates go to the remaining UAVs by
   :func:`scipy.optimize.linear_sum_assignment` on *squared* travel distance
   (:func:`uav_swarm.planning.transitions.squared_assignment`): a convex cost, so no two
   assigned straight paths cross where exchanging their targets would shorten the sum
   (the transition between two plans then has fewer conflicts to resolve).
3. **Fallback.** With fewer candidates than UAVs, the spare UAVs *hold their
   current position*. Targets are always at least ``min_gap_m`` apart (the planners pass the
   UAVs' minimum separation): a previous target is kept only when it stays that far from the other
   candidates, and a spare UAV too close to another target is given the nearest free position
   (:func:`uav_swarm.planning.spacing.separate_targets`).

Examples:
    >>> import numpy as np
    >>> uavs = np.array([[0.0, 0.0], [100.0, 0.0]])
    >>> assign_targets(uavs, np.array([[90.0, 5.0], [10.0, 5.0]])).targets_m
    array([[10.,  5.],
           [90.,  5.]])
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from uav_swarm.planning.spacing import separate_targets
from uav_swarm.planning.transitions import squared_assignment

__all__ = ["Assignment", "assign_targets"]


@dataclass(frozen=True)
class Assignment:
    """The outcome of one assignment.

    Attributes:
        targets_m: ``(n, 2)`` target of each UAV, metres.
        candidate_index: ``(n,)`` index of the candidate each UAV flies to, ``-1`` for a
            UAV that holds position (fallback).
        kept: ``(n,)`` True where the UAV kept its previous target (hysteresis).
    """

    targets_m: np.ndarray
    candidate_index: np.ndarray
    kept: np.ndarray


def _pairwise(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.linalg.norm(a[:, None, :] - b[None, :, :], axis=-1)


def assign_targets(
    uav_positions_m: np.ndarray,
    candidates_m: np.ndarray,
    previous_targets_m: np.ndarray | None = None,
    hysteresis_m: float = 0.0,
    min_gap_m: float = 1.0,
    upper_m: np.ndarray | None = None,
) -> Assignment:
    """Assign each UAV one target among the candidates.

    Args:
        uav_positions_m: ``(n, 2)`` current UAV positions.
        candidates_m: ``(k, 2)`` candidate positions, best first; only the first ``n`` are used.
        previous_targets_m: ``(n, 2)`` targets of the previous plan, or None on the first plan.
        hysteresis_m: A UAV keeps its previous target while a candidate stays within this distance.
        min_gap_m: Smallest distance between two targets: a previous target closer than this to another
            candidate is not kept; spares holding position are moved off the others.
        upper_m: ``(2,)`` the area's upper corner; a moved spare stays inside (None: no area).

    Returns:
        The :class:`Assignment`.

    Raises:
        ValueError: Arrays of the wrong shape, or a negative hysteresis.
    """
    uavs = np.asarray(uav_positions_m, dtype=np.float64)
    cands = np.asarray(candidates_m, dtype=np.float64).reshape(-1, 2)
    if uavs.ndim != 2 or uavs.shape[1] != 2:
        raise ValueError(f"uav_positions_m must have shape (n, 2), got {uavs.shape}")
    if hysteresis_m < 0:
        raise ValueError(f"hysteresis_m = {hysteresis_m} must be >= 0")
    n = len(uavs)
    cands = cands[:n]
    targets = uavs.copy()
    index = np.full(n, -1, dtype=np.int64)
    kept = np.zeros(n, dtype=bool)
    free_uavs = np.ones(n, dtype=bool)
    free_cands = np.ones(len(cands), dtype=bool)

    if previous_targets_m is not None and hysteresis_m > 0 and len(cands):
        previous = np.asarray(previous_targets_m, dtype=np.float64)
        if previous.shape != uavs.shape:
            raise ValueError(f"previous_targets_m must have shape {uavs.shape}, got {previous.shape}")
        dist = _pairwise(previous, cands)
        rows, cols = linear_sum_assignment(dist)
        for uav, cand in zip(rows, cols, strict=True):
            others = np.delete(cands, cand, axis=0)
            crowded = len(others) and np.min(np.linalg.norm(others - previous[uav], axis=1)) < min_gap_m
            if dist[uav, cand] <= hysteresis_m and not crowded:
                targets[uav] = previous[uav]
                index[uav] = cand
                kept[uav] = True
                free_uavs[uav] = False
                free_cands[cand] = False

    uav_ids = np.flatnonzero(free_uavs)
    cand_ids = np.flatnonzero(free_cands)
    if len(uav_ids) and len(cand_ids):
        rows, cols = squared_assignment(uavs[uav_ids], cands[cand_ids])
        targets[uav_ids[rows]] = cands[cand_ids[cols]]
        index[uav_ids[rows]] = cand_ids[cols]
    targets = separate_targets(targets, min_gap_m, np.argsort(index < 0, kind="stable"), upper_m)
    return Assignment(targets_m=targets, candidate_index=index, kept=kept)
