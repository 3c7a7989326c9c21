"""Exact minimum set cover with a deterministic tie-break, by integer programming (HiGHS).

The instance is a boolean matrix ``cover`` of shape ``(rows, columns)``: ``cover[r, c]`` is
true when column ``c`` (a guard) covers row ``r`` (a witness). :func:`min_set_cover` returns
the columns of a cover of all rows that

1. has the fewest columns (stage 1: ``min sum x``), then
2. among those, has the smallest total ``cost`` (stage 2: ``min cost . x`` subject to
   ``sum x = k*``, with ``k*`` fixed from stage 1, so the tie-break can never change the count).

Both stages are solved to proven optimality (``mip_rel_gap = 0``) by
``scipy.optimize.milp``; HiGHS is deterministic, so the same instance gives the same answer.

Before solving, the instance is reduced, repeating until nothing changes:

* duplicate rows are merged; a row whose column set contains another row's is dropped
  (covering the smaller row covers it);
* a row with a single column forces that column into every cover;
* a column is dropped when another covers a superset of its rows at no larger cost
  (ties between identical columns keep the cheaper, then the lower index). Swapping the
  dropped column for its dominator keeps a cover, never adds a column and never raises
  the cost, so both stages keep their optimal values.

Examples:
    >>> cover = np.array([[1, 1, 0], [0, 1, 1], [1, 0, 1]], dtype=bool)
    >>> min_set_cover(cover, cost=np.array([0, 1, 2])).tolist()
    [0, 1]
"""

from __future__ import annotations

import logging

import numpy as np
from scipy.optimize import Bounds, LinearConstraint, milp
from scipy.sparse import csr_array
from scipy.spatial import cKDTree

__all__ = ["min_set_cover", "small_cover", "separated_cover", "prune_cover", "InfeasibleCoverError"]

logger = logging.getLogger(__name__)


class InfeasibleCoverError(ValueError):
    """Some row is covered by no column."""


def _drop_duplicate_rows(cover: np.ndarray) -> np.ndarray:
    packed = np.packbits(cover, axis=1)
    _, first = np.unique(packed, axis=0, return_index=True)
    return cover[np.sort(first)]


def _unique_columns(cover: np.ndarray, cost: np.ndarray) -> np.ndarray:
    """Bool mask keeping, of each group of identical columns, the cheapest (then lowest index)."""
    order = np.lexsort((np.arange(len(cost)), cost))
    packed = np.packbits(cover[:, order], axis=0).T
    _, first = np.unique(packed, axis=0, return_index=True)
    keep = np.zeros(len(cost), dtype=bool)
    keep[order[first]] = True
    return keep


def _drop_superset_rows(cover: np.ndarray) -> np.ndarray:
    """Drop every row that contains another row (rows must be distinct)."""
    m = cover.astype(np.float32)
    shared = m @ m.T  # shared[i, j] = |row i & row j|
    sizes = m.sum(axis=1)
    contains_other = (shared == sizes[:, None]) & ~np.eye(len(m), dtype=bool)  # row i within row j
    return cover[~np.any(contains_other, axis=0)]


def _dominated_columns(cover: np.ndarray, cost: np.ndarray) -> np.ndarray:
    """Bool mask of columns dominated by another column (superset at no larger cost, strict order)."""
    m = cover.astype(np.float32)
    shared = m.T @ m  # shared[a, b] = |col a & col b|
    sizes = m.sum(axis=0)
    a_within_b = shared == sizes[:, None]
    b_within_a = shared == sizes[None, :]
    order = np.lexsort((np.arange(len(cost)), cost))
    rank = np.empty(len(cost), dtype=np.int64)
    rank[order] = np.arange(len(cost))
    cheaper_or_equal = cost[None, :] <= cost[:, None]  # cost[b] <= cost[a]
    strictly_better = ~b_within_a | (rank[None, :] < rank[:, None])
    dominated = a_within_b & cheaper_or_equal & strictly_better
    np.fill_diagonal(dominated, False)
    return np.any(dominated, axis=1) | (sizes == 0)


def _reduce(cover: np.ndarray, cost: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """Reduce the instance; returns (reduced cover, kept column indices, forced column indices)."""
    columns = np.arange(cover.shape[1])
    forced: list[int] = []
    while cover.shape[0] > 0:
        shape = cover.shape
        single = cover.sum(axis=1) == 1
        if np.any(single):
            picks = np.unique(np.argmax(cover[single], axis=1))
            forced.extend(int(columns[p]) for p in picks)
            cover = cover[~np.any(cover[:, picks], axis=1)]
            keep = np.ones(len(columns), dtype=bool)
            keep[picks] = False
            cover, columns = cover[:, keep], columns[keep]
            continue
        cover = _drop_superset_rows(_drop_duplicate_rows(cover))
        keep = _unique_columns(cover, cost[columns])
        cover, columns = cover[:, keep], columns[keep]
        keep = ~_dominated_columns(cover, cost[columns])
        cover, columns = cover[:, keep], columns[keep]
        if cover.shape == shape:
            break
    return cover, columns, forced


def _solve(cover: np.ndarray, objective: np.ndarray, count: int | None) -> np.ndarray:
    """One MILP: min objective . x, cover >= 1, optionally sum x == count; returns chosen columns."""
    n = cover.shape[1]
    constraints = [LinearConstraint(csr_array(cover.astype(np.float64)), lb=1.0, ub=np.inf)]
    if count is not None:
        constraints.append(LinearConstraint(np.ones((1, n)), lb=count, ub=count))
    result = milp(
        objective.astype(np.float64),
        integrality=np.ones(n),
        bounds=Bounds(0.0, 1.0),
        constraints=constraints,
        options={"mip_rel_gap": 0.0},
    )
    if not result.success or result.x is None:
        raise RuntimeError(f"HiGHS failed on a feasible set cover ({cover.shape}): {result.message}")
    return np.flatnonzero(result.x > 0.5)


def min_set_cover(cover: np.ndarray, cost: np.ndarray | None = None, *, single_solve: bool = False
                  ) -> np.ndarray:
    """Fewest columns covering every row, ties broken by the smallest total ``cost``.

    Args:
        cover: ``(rows, columns)`` bool incidence matrix.
        cost: ``(columns,)`` secondary cost (e.g. integers); ``None`` means all zero.
        single_solve: Solve one MILP whose objective weighs each column above any total cost
            (``sum(cost) + 1`` per column, plus its cost) instead of the two stages: the same optimal
            count and total cost, about half the time, but among tied covers HiGHS may return
            another one than the two stages do. Needs non-negative costs.

    Returns:
        Sorted int64 indices of the chosen columns (empty when there are no rows).

    Raises:
        InfeasibleCoverError: A row is covered by no column.
        ValueError: Shapes do not match, or a negative cost with ``single_solve``.
    """
    cover = np.asarray(cover, dtype=bool)
    if cover.ndim != 2:
        raise ValueError(f"cover must be a 2-D bool matrix, got shape {cover.shape}")
    cost = np.zeros(cover.shape[1]) if cost is None else np.asarray(cost, dtype=np.float64)
    if cost.shape != (cover.shape[1],):
        raise ValueError(f"cost has shape {cost.shape}; expected ({cover.shape[1]},) (one per column)")
    if single_solve and np.any(cost < 0):
        raise ValueError("single_solve needs non-negative costs")
    uncovered = ~np.any(cover, axis=1)
    if np.any(uncovered):
        raise InfeasibleCoverError(
            f"{np.count_nonzero(uncovered)} of {cover.shape[0]} rows are covered by no column (first: row "
            f"{int(np.argmax(uncovered))})")
    reduced, columns, forced = _reduce(cover, cost)
    logger.debug("set cover %s reduced to %s with %d forced columns", cover.shape, reduced.shape, len(forced))
    chosen = list(forced)
    if reduced.shape[0] > 0 and single_solve:
        kept_cost = cost[columns]
        picks = _solve(reduced, kept_cost.sum() + 1.0 + kept_cost, None)
        chosen.extend(int(c) for c in columns[picks])
    elif reduced.shape[0] > 0:
        count = len(_solve(reduced, np.ones(reduced.shape[1]), None))
        picks = _solve(reduced, cost[columns], count)
        chosen.extend(int(c) for c in columns[picks])
    return np.array(sorted(chosen), dtype=np.int64)


def _greedy_cover(sees: np.ndarray, cost: np.ndarray) -> np.ndarray:
    """Rows of ``sees`` (candidates) covering every column (witness): most newly seen first, then cheapest."""
    order = np.lexsort((np.arange(len(cost)), cost))
    ordered = sees[order]
    uncovered = np.ones(sees.shape[1], dtype=bool)
    picks: list[int] = []
    while np.any(uncovered):
        gains = np.count_nonzero(ordered[:, uncovered], axis=1)
        best = int(order[np.argmax(gains)])  # argmax takes the first, i.e. cheapest, of the best gains
        picks.append(best)
        uncovered &= ~sees[best]
    return np.array(picks, dtype=np.int64)


def _disjoint_witnesses(sees: np.ndarray) -> int:
    """Size of a set of witnesses no two of which share a candidate (a lower bound on any cover)."""
    free = np.ones(sees.shape[1], dtype=bool)
    count = 0
    for w in np.argsort(sees.sum(axis=0), kind="stable"):  # the most constrained witnesses first
        if free[w]:
            count += 1
            free &= ~np.any(sees[sees[:, w]], axis=0)  # what shares a candidate with w
    return count


def _clashes(points_m: np.ndarray, min_separation_m: float) -> np.ndarray:
    """``(P, 2)`` pairs of points closer than ``min_separation_m``."""
    if min_separation_m <= 0.0 or len(points_m) < 2:
        return np.zeros((0, 2), np.int64)
    return cKDTree(points_m).query_pairs(min_separation_m * (1.0 - 1e-12), output_type="ndarray")


def separated_cover(sees: np.ndarray, cost: np.ndarray, points_m: np.ndarray, min_separation_m: float
                    ) -> np.ndarray:
    """Fewest candidates (rows) seeing every witness, no two closer than ``min_separation_m`` (HiGHS).

    One exclusion row ``x_a + x_b <= 1`` per pair of candidates closer than the minimum; among the
    smallest covers, the one of least total cost (non-negative costs).

    Raises:
        InfeasibleCoverError: No cover keeps the minimum.

    Examples:
        >>> sees = np.array([[1, 1, 0], [0, 1, 1], [1, 0, 1]], dtype=bool)  # any two candidates see all
        >>> points = np.array([[0.0, 0.0], [3.0, 0.0], [9.0, 0.0]])
        >>> separated_cover(sees, np.zeros(3), points, 5.0).tolist()
        [0, 2]
    """
    n = len(sees)
    clashes = _clashes(np.asarray(points_m, np.float64), min_separation_m)
    constraints = [LinearConstraint(csr_array(sees.T.astype(np.float64)), lb=1.0, ub=np.inf)]
    if len(clashes):
        rows = np.repeat(np.arange(len(clashes)), 2)
        pairs = csr_array((np.ones(len(rows)), (rows, clashes.ravel())), shape=(len(clashes), n))
        constraints.append(LinearConstraint(pairs, lb=-np.inf, ub=1.0))
    cost = np.asarray(cost, np.float64)
    result = milp(cost.sum() + 1.0 + cost, integrality=np.ones(n), bounds=Bounds(0.0, 1.0),
                  constraints=constraints, options={"mip_rel_gap": 0.0})
    if result.x is None:
        raise InfeasibleCoverError(f"min_separation_m = {min_separation_m:g} is the cause: no guards "
                                   f"{min_separation_m:g} m apart see every witness (the UAVs' minimum "
                                   "separation): lower it, or add candidate positions")
    return np.flatnonzero(result.x > 0.5)


def small_cover(sees: np.ndarray, cost: np.ndarray, points_m: np.ndarray | None = None,
                min_separation_m: float = 0.0) -> np.ndarray:
    """Fewest candidates (rows) seeing every witness (column), preferring cheap candidates.

    The greedy cover (cheapest first among equal gains) is kept when it is provably as small as any,
    i.e. when as many witnesses as it has guards pairwise share no candidate; otherwise the exact set
    cover decides (HiGHS; among the smallest covers, the one of least total cost). With candidate
    positions ``points_m`` and a minimum separation, a cover with two candidates closer than that is
    replaced by :func:`separated_cover`'s.
    """
    picks = _small_cover(sees, cost)
    if points_m is None or min_separation_m <= 0.0 or len(_clashes(points_m[picks], min_separation_m)) == 0:
        return picks
    return separated_cover(sees, cost, points_m, min_separation_m)


def _small_cover(sees: np.ndarray, cost: np.ndarray) -> np.ndarray:
    """:func:`small_cover` without a minimum separation."""
    order = np.lexsort((np.arange(len(cost)), cost))  # of candidates seeing the same, keep the cheapest
    _, first = np.unique(np.packbits(sees[order], axis=1), axis=0, return_index=True)
    distinct = np.sort(order[first])
    sees, cost = sees[distinct], cost[distinct]
    greedy = _greedy_cover(sees, cost)
    if len(greedy) <= _disjoint_witnesses(sees):
        return distinct[np.sort(greedy)]
    return distinct[min_set_cover(sees.T, cost, single_solve=True)]


def prune_cover(seen_by: np.ndarray) -> np.ndarray:
    """Indices of the guards (rows of ``seen_by``, guard x witness) kept after dropping redundant ones.

    A guard is redundant when every witness it sees is seen by another kept guard; the guards seeing
    the fewest witnesses are dropped first.
    """
    keep = np.ones(len(seen_by), dtype=bool)
    counts = seen_by.sum(axis=0)
    for g in np.argsort(seen_by.sum(axis=1), kind="stable"):
        if np.all(counts[seen_by[g]] >= 2):
            keep[g] = False
            counts -= seen_by[g]
    return np.flatnonzero(keep)
