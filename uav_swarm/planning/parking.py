"""Where a spare UAV parks: the nearest point with no user within reach, searched on rings, compiled.

Under a user cap (strategy 2) a UAV that neither follows users nor flies to a proposal must not take users
from a planned UAV, so planning in motion (:mod:`uav_swarm.planning.motion`) parks it where no user is
within ``reach_m``. :func:`parking_spot` tries, from ``start`` outwards, rings of radius 0, 5, 10, ... m up
to the area's diagonal, each with one point every 5 m of circumference (``max(1, ceil(2 pi r / 5))`` points
at angles ``2 pi i / count`` from East), clipped into the area. The first point in that order that has no
user within ``reach_m`` (squared distance ``<= reach_m ** 2``) and stands at least ``min_gap_m`` from every
other target is the spot; with none, the UAV holds ``start``.

The loop is compiled (numba) and stops at the first user within reach of a point, so a crowd that leaves no
free spot (the 802.11 radio's reach spans most of the area) costs microseconds per point rather than a
k-d tree query per ring.

Examples:
    >>> users = np.array([[0.0, 0.0]])
    >>> parking_spot(users, np.array([1.0, 0.0]), np.zeros((0, 2)), np.array([100.0, 100.0]), 10.0,
    ...              5.0).tolist()  # 5 m rings: the first free point is on the 10 m ring
    [11.0, 0.0]
    >>> parking_spot(users, np.array([1.0, 0.0]), np.zeros((0, 2)), np.array([10.0, 10.0]), 50.0,
    ...              5.0).tolist()  # nowhere in the area is free: the UAV holds
    [1.0, 0.0]
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["RING_STEP_M", "parking_spot", "warm_up"]

RING_STEP_M = 5.0
"""Spacing of the rings, and of the points along each ring, metres."""


@numba.njit(cache=True, nogil=True)
def _search(users: np.ndarray, start: np.ndarray, others: np.ndarray, area: np.ndarray, reach_sq: float,
            gap_sq: float, step: float) -> np.ndarray:
    """The module docstring's search; ``start`` when no point is free."""
    diagonal = math.sqrt(area[0] * area[0] + area[1] * area[1])
    n_rings = int(math.ceil(diagonal / step))
    for r in range(n_rings):
        radius = r * step
        count = max(1, int(math.ceil(2.0 * math.pi * radius / step)))
        angle_step = 2.0 * math.pi / count
        for i in range(count):
            angle = i * angle_step
            x = min(max(start[0] + radius * math.cos(angle), 0.0), area[0])
            y = min(max(start[1] + radius * math.sin(angle), 0.0), area[1])
            free = True
            for n in range(users.shape[0]):
                dx, dy = users[n, 0] - x, users[n, 1] - y
                if dx * dx + dy * dy <= reach_sq:
                    free = False
                    break
            if not free:
                continue
            for k in range(others.shape[0]):
                dx, dy = others[k, 0] - x, others[k, 1] - y
                if dx * dx + dy * dy < gap_sq:
                    free = False
                    break
            if free:
                return np.array([x, y])
    return start.copy()


def parking_spot(users_m: np.ndarray, start_m: np.ndarray, others_m: np.ndarray, area_m: np.ndarray,
                 reach_m: float, min_gap_m: float) -> np.ndarray:
    """The spot a spare UAV parks at (module docstring).

    Args:
        users_m: ``(N, 2)`` the users (as predicted), metres.
        start_m: ``(2,)`` where the search starts (the UAV's last target).
        others_m: ``(M, 2)`` the other UAVs' targets, metres.
        area_m: ``(2,)`` the area's width and height, metres (points are clipped into ``[0, area]``).
        reach_m: No user within this distance of the spot, metres.
        min_gap_m: The spot stands at least this far from every other target, metres.

    Returns:
        ``(2,)`` float64 spot, ``start_m`` itself when no point of the search is free.
    """
    users = np.ascontiguousarray(users_m, dtype=np.float64).reshape(-1, 2)
    others = np.ascontiguousarray(others_m, dtype=np.float64).reshape(-1, 2)
    return _search(users, np.asarray(start_m, dtype=np.float64), others, np.asarray(area_m, dtype=np.float64),
                   float(reach_m) ** 2, float(min_gap_m) ** 2, RING_STEP_M)


def warm_up() -> None:
    """Load the compiled search once per process, so that no replan pays for it."""
    parking_spot(np.zeros((1, 2)), np.zeros(2), np.zeros((0, 2)), np.ones(2), 1.0, 0.0)
