"""The crowd's pedestrian pair forces, compiled once for B worlds: :func:`pair_forces` (numba).

Both :class:`~uav_swarm.world.crowd.CrowdSim` (one world) and
:class:`~uav_swarm.world.crowd_batch.BatchedCrowd` (B worlds stacked) call this one kernel. The
pedestrians of world ``w`` are ``world_starts[w]:world_starts[w + 1]``; no pair spans two worlds.

Neighbour sweep, per world: the pedestrians are sorted by (row, x, index), rows being bands of height
just over the cutoff (an insertion sort from the previous step's order, almost linear as people move
little per step). A pedestrian's candidates are those after it in its row within the cutoff along x,
then those of the next row within the cutoff along x (a pointer that only moves forward); the exact
distance decides. Each pair closer than the cutoff is visited once: the sweep lists the close pairs
(without a branch on the distance), then their forces are added in the order listed.

Each pair ``lo < hi`` gets the anisotropic exponential repulsion of the crowd's module docstring,
computed operation for operation as numpy did it before (``dx = p_lo - p_hi``; coincident pedestrians
pushed apart along a fixed angle per pair). The order in which a pedestrian's pair forces are added
depends only on its own world's positions, so a world stepped in a batch moves bit for bit as the same
world stepped alone.

Examples:
    >>> p = np.array([[0.0, 0.0], [1.0, 0.0], [5.0, 5.0]])
    >>> force = pair_forces(p, np.zeros((3, 2)), np.array([0, 3]), np.arange(3), 1.5, 2.1, 0.3, 0.5, 0.5)
    >>> bool(force[0, 0] < 0.0 < force[1, 0]), force[2].tolist()
    (True, [0.0, 0.0])
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["PAIRS_AT_ONCE", "pair_forces", "pair_forces_into"]

_ROW_GROWTH = 1.0 + 1e-9  # rows are this much taller than the cutoff: a pair spans at most two rows
_SWEEP_SLACK_M = 1e-6  # the sweep's x windows reach this much farther; the exact distance then decides
_COINCIDENT_M = 1e-9  # pedestrians closer than this are pushed apart along a fixed angle per pair
_GOLDEN_ANGLE_RAD = 2.399963229728653
_INSERTION_MOVES = 16  # per pedestrian: more, and the sweep order is sorted afresh
PAIRS_AT_ONCE = 4096  # close pairs found before their forces are added (the buffer of pair_forces_into)


@numba.njit(cache=True, nogil=True)
def _before(row_a: int, x_a: float, a: int, row_b: int, x_b: float, b: int) -> bool:
    """Whether pedestrian ``a`` sorts before ``b`` by (row, x, index)."""
    if row_a != row_b:
        return row_a < row_b
    if x_a != x_b:
        return x_a < x_b
    return a < b


@numba.njit(cache=True, nogil=True)
def _sort_world(order: np.ndarray, rows: np.ndarray, p: np.ndarray, start: int, end: int) -> None:
    """Sort ``order[start:end]`` by (row, x, index), in place.

    An insertion sort from the given order (the previous step's: almost linear); past a budget of
    moves (a new world, or one whose order was lost) two stable merge sorts instead.
    """
    budget = _INSERTION_MOVES * (end - start)
    for a in range(start + 1, end):
        item = order[a]
        row, x = rows[item], p[item, 0]
        b = a - 1
        while b >= start and _before(row, x, item, rows[order[b]], p[order[b], 0], order[b]):
            order[b + 1] = order[b]
            b -= 1
        order[b + 1] = item
        budget -= a - 1 - b
        if budget < 0:
            by_x = start + np.argsort(p[start:end, 0], kind="mergesort")  # ties: by index
            order[start:end] = by_x[np.argsort(rows[by_x], kind="mergesort")]
            return


@numba.njit(cache=True, nogil=True)
def _add_pairs(p: np.ndarray, d: np.ndarray, pairs: np.ndarray, count: int, start: int, strength: float,
               range_m: float, contact_m: float, front: float, half: float, out: np.ndarray) -> None:
    """Add the repulsion of the first ``count`` pairs ``pairs[:, k]`` (world from ``start``), in order."""
    for k in range(count):
        i, j = pairs[0, k], pairs[1, k]
        lo, hi = min(i, j), max(i, j)
        dx = p[lo, 0] - p[hi, 0]  # from hi to lo
        dy = p[lo, 1] - p[hi, 1]
        dist = math.sqrt(dx * dx + dy * dy)
        if dist < _COINCIDENT_M:
            angle = _GOLDEN_ANGLE_RAD * float((lo - start) * 7 + (hi - start))
            dx, dy, dist = math.cos(angle), math.sin(angle), 1.0
        magnitude = strength * math.exp((contact_m - dist) / range_m)
        magnitude /= dist
        # cos of the angle between a pedestrian's heading and the other: the one in front counts more
        w_lo = front - half * (d[lo, 0] * dx + d[lo, 1] * dy) / dist
        w_hi = front + half * (d[hi, 0] * dx + d[hi, 1] * dy) / dist
        f_lo, f_hi = magnitude * w_lo, -magnitude * w_hi
        out[lo, 0] += f_lo * dx
        out[lo, 1] += f_lo * dy
        out[hi, 0] += f_hi * dx
        out[hi, 1] += f_hi * dy


@numba.njit(cache=True, nogil=True)
def pair_forces(positions_m: np.ndarray, directions: np.ndarray, world_starts: np.ndarray, order: np.ndarray,
                cutoff_m: float, strength_m_s2: float, range_m: float, radius_m: float,
                anisotropy: float) -> np.ndarray:
    """``(N, 2)`` pedestrian repulsion (m/s²) summed over the pairs closer than ``cutoff_m`` in each world.

    The force on ``i`` from ``j`` is ``A exp((2 r - d) / B) n_ji`` weighted by
    ``lambda + (1 - lambda) (1 + cos phi) / 2``, ``phi`` the angle between ``i``'s desired direction and
    the direction to ``j``.

    Args:
        positions_m: ``(N, 2)`` positions, the worlds one after the other.
        directions: ``(N, 2)`` desired unit directions (zero rows: no preference).
        world_starts: ``(B + 1,)`` int64; world ``w`` is ``world_starts[w]:world_starts[w + 1]``.
        order: ``(N,)`` int64 permutation that keeps each world's pedestrians within its range (any such
            permutation; ``np.arange(N)`` at first); sorted in place into this step's sweep order, which is
            the best start for the next step.
        cutoff_m: Pairs farther apart are ignored.
        strength_m_s2: ``A``.
        range_m: ``B``.
        radius_m: Body radius ``r``.
        anisotropy: ``lambda`` (1: isotropic).
    """
    n = positions_m.shape[0]
    out = np.empty((n, 2))
    pair_forces_into(positions_m, directions, world_starts, order, cutoff_m, strength_m_s2, range_m, radius_m,
                     anisotropy, out, np.empty((2, n), np.int64), np.empty((2, n)),
                     np.empty((2, PAIRS_AT_ONCE), np.int64))
    return out


@numba.njit(cache=True, nogil=True)
def pair_forces_into(positions_m: np.ndarray, directions: np.ndarray, world_starts: np.ndarray,
                     order: np.ndarray, cutoff_m: float, strength_m_s2: float, range_m: float,
                     radius_m: float, anisotropy: float, out: np.ndarray, rows: np.ndarray,
                     sorted_m: np.ndarray, pairs: np.ndarray) -> None:
    """:func:`pair_forces` written into ``out`` ``(N, 2)``, allocating nothing.

    Buffers: ``rows`` ``(2, N)`` int64 (each pedestrian's row, and the rows in sweep order), ``sorted_m``
    ``(2, N)`` (the positions in sweep order), ``pairs`` ``(2, PAIRS_AT_ONCE)`` int64 (the close pairs
    found, whose forces are then added in the order found).
    """
    n = positions_m.shape[0]
    out[:] = 0.0
    row_scale = 1.0 / (cutoff_m * _ROW_GROWTH)
    window = cutoff_m + _SWEEP_SLACK_M
    cutoff2 = cutoff_m * cutoff_m
    contact_m = 2 * radius_m
    half = 0.5 * (1.0 - anisotropy)
    front = anisotropy + half
    capacity = pairs.shape[1]
    p = positions_m
    row_of, rs, xs, ys = rows[0], rows[1], sorted_m[0], sorted_m[1]
    for k in range(n):
        row_of[k] = math.floor(p[k, 1] * row_scale)
    for w in range(world_starts.shape[0] - 1):
        start, end = world_starts[w], world_starts[w + 1]
        _sort_world(order, row_of, p, start, end)
        for a in range(start, end):  # the sweep reads contiguous copies
            rs[a], xs[a], ys[a] = row_of[order[a]], p[order[a], 0], p[order[a], 1]
        q = start  # first of the next row within the window of the current pedestrian
        count = 0  # pairs found, their forces not added yet
        for a in range(start, end):
            i = order[a]
            row, x, y = rs[a], xs[a], ys[a]
            b = a + 1
            while b < end and rs[b] == row and xs[b] - x <= window:
                if count == capacity:
                    _add_pairs(p, directions, pairs, count, start, strength_m_s2, range_m, contact_m, front,
                               half, out)
                    count = 0
                dx, dy = x - xs[b], y - ys[b]
                pairs[0, count], pairs[1, count] = i, order[b]
                count += dx * dx + dy * dy <= cutoff2  # kept only if close: no branch to mispredict
                b += 1
            while q < end and (rs[q] <= row or (rs[q] == row + 1 and xs[q] < x - window)):
                q += 1
            b = q
            while b < end and rs[b] == row + 1 and xs[b] <= x + window:
                if count == capacity:
                    _add_pairs(p, directions, pairs, count, start, strength_m_s2, range_m, contact_m, front,
                               half, out)
                    count = 0
                dx, dy = x - xs[b], y - ys[b]
                pairs[0, count], pairs[1, count] = i, order[b]
                count += dx * dx + dy * dy <= cutoff2
                b += 1
        _add_pairs(p, directions, pairs, count, start, strength_m_s2, range_m, contact_m, front, half, out)
