"""Targets kept apart: the last step of every assignment, a projection onto separated positions.

The placements the planners propose are separated by construction (the optimisers treat a position
closer than the minimum as infeasible). What the assignment adds to them is not: a spare UAV holding its
position, a kept target that drifted with its users, a proposal aimed where its users walk. The
projection :func:`separate_targets` takes the targets in priority order and moves each one closer than
the minimum to a target placed before it to the nearest free point it finds (pushed straight away from
each target it is too close to, else on rings of a quarter of the minimum around it; inside the area).
In an area so crowded that the search finds no free point for some target, every target moves to a point
of the fleet's layout (:func:`uav_swarm.world.separation.fleet_slots_m`, the points the fleet check
counts), assigned by the least sum of squared moves. Every pair of the result is at least the minimum
apart whenever the fleet check accepts the fleet in the area; a fleet it refuses is refused here too.

Examples:
    >>> import numpy as np
    >>> targets = separate_targets(np.array([[50.0, 50.0], [52.0, 50.0]]), 5.0)
    >>> round(float(np.linalg.norm(targets[1] - targets[0])), 2)
    5.0
"""

from __future__ import annotations

import logging

import numpy as np
from scipy.optimize import linear_sum_assignment

from uav_swarm.world.separation import check_fleet_fits, fleet_slots_m

__all__ = ["separate_targets"]

logger = logging.getLogger(__name__)

_RINGS = 40  # rings searched around a target: up to ten times the minimum away


def separate_targets(targets_m: np.ndarray, min_gap_m: float, order: np.ndarray | None = None,
                     upper_m: np.ndarray | None = None, *, keep: int = 0, field: str = "uav.min_separation_m"
                     ) -> np.ndarray:
    """``(n, 2)`` targets at least ``min_gap_m`` apart, each moved as little as the search finds.

    Args:
        targets_m: ``(n, 2)`` wanted targets, metres.
        min_gap_m: The minimum distance between two targets (0: the targets as they are).
        order: Priority (indices, first placed first; a target placed earlier never moves for a later one,
            unless the search fails and all move to the layout); default ``0 ... n-1``.
        upper_m: ``(2,)`` the area's upper corner; moved targets stay in ``[0, upper_m]`` (None: no area).
        keep: The first ``keep`` targets of ``order`` never move, not even to the layout (they must be
            ``min_gap_m`` apart already): reserved points, such as an operator's targets.
        field: The setting ``min_gap_m`` comes from, named when the fleet cannot keep it in the area.

    Returns:
        A new array. Without an area, a target for which no free point lies within ten minima keeps its
        place (logged).

    Raises:
        typed_config.ConfigError: ``n`` targets cannot be ``min_gap_m`` apart in the area
            (:func:`uav_swarm.world.separation.check_fleet_fits`).
    """
    out = np.array(targets_m, dtype=np.float64).reshape(-1, 2)
    if min_gap_m <= 0.0 or len(out) < 2:
        return out
    if upper_m is not None:
        check_fleet_fits(len(out), min_gap_m, float(upper_m[0]), float(upper_m[1]), field=field)
    order = np.arange(len(out)) if order is None else np.asarray(order, dtype=np.int64)
    step = min_gap_m / 4.0
    placed: list[int] = []
    failed = False
    for i in order.tolist():
        if placed and np.min(np.linalg.norm(out[placed] - out[i], axis=1)) < min_gap_m:
            free = _nearest_free(out[i], out[placed], min_gap_m, step, upper_m)
            failed |= free is None
            out[i] = out[i] if free is None else free
        placed.append(i)
    if not failed:
        return out
    if upper_m is None:
        logger.warning("no free point within %.1f m of some targets: they stay closer than %.1f m",
                       _RINGS * step, min_gap_m)
        return out
    slots = fleet_slots_m(min_gap_m, float(upper_m[0]), float(upper_m[1]))
    wanted = np.array(targets_m, dtype=np.float64).reshape(-1, 2)
    fixed, movable = order[:keep], order[keep:]
    if keep:  # the layout's points clear of the reserved ones
        slots = slots[np.linalg.norm(slots[:, None] - wanted[fixed][None], axis=-1).min(axis=1) >= min_gap_m]
        if len(slots) < len(movable):
            logger.warning("no room for %d targets %.1f m from the %d reserved ones: some stay closer",
                           len(movable), min_gap_m, keep)
            return out
    rows, cols = linear_sum_assignment(((wanted[movable][:, None] - slots[None]) ** 2).sum(axis=-1))
    out[movable[rows]] = slots[cols]
    return out


def _nearest_free(wanted: np.ndarray, others: np.ndarray, min_gap_m: float, step: float,
                  upper_m: np.ndarray | None) -> np.ndarray | None:
    """The point nearest ``wanted`` at least ``min_gap_m`` from ``others`` (pushes, then rings), or None."""
    away = wanted - others
    length = np.linalg.norm(away, axis=1)
    direction = np.where(length[:, None] > 1e-9, away / np.maximum(length, 1e-9)[:, None], [1.0, 0.0])
    pushes = others + direction * min_gap_m * (1.0 + 1e-9)  # each conflict resolved on its own
    rings = [pushes]
    for radius in step * np.arange(1, _RINGS + 1):
        count = max(8, int(np.ceil(2.0 * np.pi * radius / step)))
        angles = np.linspace(0.0, 2.0 * np.pi, count, endpoint=False)
        rings.append(wanted + radius * np.stack([np.cos(angles), np.sin(angles)], axis=1))
        points = np.concatenate(rings)
        rings = []
        if upper_m is not None:
            points = np.clip(points, 0.0, upper_m)
        free = np.linalg.norm(points[:, None, :] - others[None], axis=-1).min(axis=1) >= min_gap_m
        if np.any(free):
            shift = np.where(free, np.linalg.norm(points - wanted, axis=1), np.inf)
            return points[int(np.argmin(shift))]
    return None
