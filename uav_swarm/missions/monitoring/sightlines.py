"""The guard-witness sight-line test of :func:`uav_swarm.missions.monitoring.outline.visibility`, compiled.

One pair ``(g, w)`` at a time, with :mod:`numba`: rule 2 (the segment leaves ``w`` into the mission's
region), then rules 1 and 3 against each wall but ``w``'s own, stopping at the first wall that blocks.
A wall is skipped without arithmetic when the guard's and the witness's codes share a bit (both beyond
the wall's line on the region's side, or both on one side of the wall's box grown by the margin: the
segment cannot come nearer than the margin); otherwise the distance between the segment and the wall
is computed exactly, in float64, and compared with the margin (``touch_m`` for a wall near ``w``).

The arithmetic is the one the numpy version used, term for term (no fast-math, so no reassociation):
the answers do not depend on the order in which pairs or walls are taken. The first call in a fresh
environment compiles the kernel (about a second) and caches it on disk (``cache=True``); later processes
load it.
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["sees"]


@numba.njit(cache=True, nogil=True)
def _cross(ax: float, ay: float, bx: float, by: float) -> float:
    return ax * by - ay * bx


@numba.njit(cache=True, nogil=True)
def _to_segment(x: float, y: float, sx: float, sy: float, ex: float, ey: float) -> float:
    """Distance from ``(x, y)`` to the segment ``s e``."""
    wx, wy = ex - sx, ey - sy
    t = ((x - sx) * wx + (y - sy) * wy) / max(wx * wx + wy * wy, 1e-300)
    t = min(max(t, 0.0), 1.0)
    return math.hypot(x - sx - t * wx, y - sy - t * wy)


@numba.njit(cache=True, nogil=True)
def _segment_distance(px: float, py: float, qx: float, qy: float, ax: float, ay: float, bx: float, by: float
                      ) -> float:
    """Distance between segments ``p q`` and ``a b`` (zero when they cross)."""
    o1 = _cross(qx - px, qy - py, ax - px, ay - py)
    o2 = _cross(qx - px, qy - py, bx - px, by - py)
    o3 = _cross(bx - ax, by - ay, px - ax, py - ay)
    o4 = _cross(bx - ax, by - ay, qx - ax, qy - ay)
    if o1 * o2 < 0 and o3 * o4 < 0:
        return 0.0
    return min(min(_to_segment(px, py, ax, ay, bx, by), _to_segment(qx, qy, ax, ay, bx, by)),
               min(_to_segment(ax, ay, px, py, qx, qy), _to_segment(bx, by, px, py, qx, qy)))


@numba.njit(cache=True, nogil=True)
def _leaves_into(walls: np.ndarray, here: int, ending: int, dx: float, dy: float, interior: bool) -> bool:
    """Whether direction ``(dx, dy)`` from a witness on wall ``here`` points into the region.

    A witness at a corner has ``ending >= 0``, the wall ending there; the region is the interior if
    ``interior``, else the exterior.
    """
    vx, vy = walls[here, 2] - walls[here, 0], walls[here, 3] - walls[here, 1]
    left_here = _cross(vx, vy, dx, dy)
    if ending < 0:
        return left_here > 0 if interior else left_here < 0
    ux, uy = walls[ending, 2] - walls[ending, 0], walls[ending, 3] - walls[ending, 1]
    left_ending = _cross(ux, uy, dx, dy)
    convex = _cross(ux, uy, vx, vy) > 0
    if interior:
        return (left_here > 0 and left_ending > 0) if convex else (left_here > 0 or left_ending > 0)
    return (left_here < 0 or left_ending < 0) if convex else (left_here < 0 and left_ending < 0)


@numba.njit(cache=True, nogil=True)
def sees(walls: np.ndarray, guards: np.ndarray, points: np.ndarray, own: np.ndarray, near: np.ndarray,
         guard_codes: np.ndarray, point_codes: np.ndarray, far_limit_m: float, touch_m: float,
         interior: bool) -> np.ndarray:
    """``(G, W)`` bool: guard ``g`` sees witness ``w`` (rules 1-3 of the outline module).

    Args:
        walls: ``(E, 4)`` walls ``ax, ay, bx, by``, metres.
        guards: ``(G, 2)`` guard positions, metres.
        points: ``(W, 2)`` witness positions, metres.
        own: ``(W, 2)`` int64 walls each witness lies on, ``-1`` for none.
        near: ``(W, E)`` bool: walls held only to ``touch_m`` for that witness.
        guard_codes: ``(G, E)`` uint8 codes of the guards (:func:`outline._codes`).
        point_codes: ``(W, E)`` uint8 codes of the witnesses, for the same margin and region.
        far_limit_m: Least distance a sight line keeps from every other wall.
        touch_m: Least distance from a wall near the witness.
        interior: The region is the building's interior (else its exterior).
    """
    n_guards, n_points, n_walls = len(guards), len(points), len(walls)
    seen = np.zeros((n_guards, n_points), dtype=np.bool_)
    for g in range(n_guards):
        gx, gy = guards[g, 0], guards[g, 1]
        for w in range(n_points):
            px, py = points[w, 0], points[w, 1]
            here, ending = own[w, 0], own[w, 1]
            if here >= 0 and not _leaves_into(walls, here, ending, gx - px, gy - py, interior):
                continue
            visible = True
            for e in range(n_walls):
                if e == here or e == ending or (guard_codes[g, e] & point_codes[w, e]) != 0:
                    continue
                limit = touch_m if near[w, e] else far_limit_m
                ax, ay, bx, by = walls[e, 0], walls[e, 1], walls[e, 2], walls[e, 3]
                if _segment_distance(gx, gy, px, py, ax, ay, bx, by) < limit:
                    visible = False
                    break
            seen[g, w] = visible
    return seen
