"""The exact Wi-Fi placement on a candidate set: a MILP solved by HiGHS (``scipy.optimize.milp``).

It solves exactly the problem of :mod:`uav_swarm.missions.wifi.expert` restricted
to a finite candidate set ``C`` (for instance a coarse grid): open at most
``max_uavs`` candidates, maximise the covered users, then minimise the number of
UAVs (objective ``covered - open / (max_uavs + 1)``), subject to the strategy's rule.

Strategy 1 (``rules.exclusive``): every open candidate alone covers at least
``min_users`` users; see :func:`_exclusive_model` (linear in the number of
user-candidate pairs).

Strategy 2: every user within the radius of an open candidate is served by the
nearest open one (ties to the lower candidate index) and every open candidate
serves between ``min_users`` and ``max_users`` users. Variables ``y_j`` (open,
binary) and ``x_ij`` (user i served by j, continuous in [0, 1])::

    sum_j x_ij <= 1                         each user served at most once
    x_ij <= y_j                             only by open candidates
    sum_{l: d_il <= d_ij} x_il >= y_j       nearest-open association ("closest assignment")
    min_users y_j <= sum_i x_ij <= max_users y_j
    sum_j y_j <= max_uavs

Given integral ``y`` the association rows force ``x`` to the 0/1 nearest-open
assignment, so ``x`` needs no integrality. This model has ``sum_i |C_i|^2 / 2``
non-zeros (``C_i``: candidates within the radius of user ``i``) and a weak LP
relaxation: keep it for small scenes.

Candidates covering fewer than ``min_users`` users can never be opened and are
left out of both models.

Both models (and :func:`capacitated_optimum`) keep the UAVs ``rules.min_separation_m`` apart with one
exclusion row per pair of candidates closer than that: ``y_a + y_b <= 1``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.optimize import Bounds, LinearConstraint, milp
from scipy.spatial import cKDTree

from uav_swarm.missions.wifi.rules import CoverageRules

__all__ = ["ExactPlacement", "exact_placement", "capacitated_optimum"]


@dataclass(frozen=True)
class ExactPlacement:
    """The MILP's answer.

    Attributes:
        uavs_m: ``(k, 2)`` chosen candidates, metres, sorted by ``(y, x)``.
        n_served: Served users of that placement.
        optimal: Whether HiGHS proved optimality (False: time limit hit, best found).
        solve_s: Wall time of the solve, seconds.
    """

    uavs_m: np.ndarray
    n_served: int
    optimal: bool
    solve_s: float


def _pairs(users_m: np.ndarray, candidates_m: np.ndarray, radius_m: float) -> tuple[np.ndarray, ...]:
    """(user, candidate, squared distance) for every pair within the radius."""
    near = cKDTree(users_m).sparse_distance_matrix(
        cKDTree(candidates_m), radius_m * (1.0 + 1e-9) + 1e-9, output_type="ndarray")
    u, c = near["i"].astype(np.int64), near["j"].astype(np.int64)
    d2 = ((users_m[u] - candidates_m[c]) ** 2).sum(axis=1)
    keep = d2 <= radius_m ** 2
    return u[keep], c[keep], d2[keep]


def _useful_pairs(users_m: np.ndarray, candidates_m: np.ndarray, rules: CoverageRules
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The pairs of the candidates in reach of ``min_users`` users (the others are never opened).

    Returns ``(user, candidate, squared distance, candidates)``, the candidates re-indexed.
    """
    candidates_m = np.asarray(candidates_m, np.float64).reshape(-1, 2)
    u, c, d2 = _pairs(users_m, candidates_m, rules.radius_m) if len(users_m) and len(candidates_m) else (
        np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0))
    useful = np.bincount(c, minlength=len(candidates_m)) >= rules.min_users
    keep = useful[c]
    index = np.cumsum(useful) - 1
    return u[keep], index[c[keep]], d2[keep], candidates_m[useful]


def _separation_rows(candidates_m: np.ndarray, min_separation_m: float, y0: int, width: int
                     ) -> list[LinearConstraint]:
    """``y_a + y_b <= 1`` for every pair of candidates closer than ``min_separation_m`` (none if 0)."""
    if min_separation_m <= 0.0 or len(candidates_m) < 2:
        return []
    near = cKDTree(candidates_m).query_pairs(min_separation_m * (1.0 - 1e-12), output_type="ndarray")
    if len(near) == 0:
        return []
    rows = np.repeat(np.arange(len(near)), 2)
    matrix = sparse.csr_array((np.ones(len(rows)), (rows, y0 + near.ravel())), shape=(len(near), width))
    return [LinearConstraint(matrix, -np.inf, 1.0)]


def exact_placement(
    users_m: np.ndarray,
    rules: CoverageRules,
    candidates_m: np.ndarray,
    time_limit_s: float = 60.0,
) -> ExactPlacement:
    """Solve the placement problem exactly over ``candidates_m``.

    Args:
        users_m: ``(N, 2)`` user positions, metres.
        rules: Radius, per-UAV load bounds and UAV budget.
        candidates_m: ``(M, 2)`` candidate UAV positions, metres.
        time_limit_s: HiGHS time limit, seconds.

    Returns:
        The optimal placement (or the best found within the time limit).

    Raises:
        RuntimeError: HiGHS found no feasible point (cannot happen: no UAV is feasible).
    """
    start = time.perf_counter()
    users_m = np.asarray(users_m, np.float64).reshape(-1, 2)
    u, c, d2, cands = _useful_pairs(users_m, candidates_m, rules)
    if len(cands) == 0 or rules.max_uavs == 0:
        return ExactPlacement(np.zeros((0, 2)), 0, True, time.perf_counter() - start)
    n_users, m = len(users_m), len(cands)

    if rules.exclusive:
        cost, integrality, constraints, y0, upper = _exclusive_model(u, c, n_users, m, rules)
    else:
        cost, integrality, constraints, y0, upper = _served_model(u, c, d2, n_users, m, rules)
    constraints = constraints + _separation_rows(cands, rules.min_separation_m, y0, len(cost))
    result = milp(cost, constraints=constraints, integrality=integrality, bounds=Bounds(0.0, upper),
                  options={"time_limit": time_limit_s})
    if result.x is None:
        raise RuntimeError(f"HiGHS found no feasible placement: {result.message}")
    chosen = np.flatnonzero(result.x[y0:y0 + m] > 0.5)
    uavs_m = cands[chosen]
    uavs_m = uavs_m[np.lexsort((uavs_m[:, 0], uavs_m[:, 1]))] if len(uavs_m) else np.zeros((0, 2))
    served = np.unique(u[np.isin(c, chosen)]).size  # covered users of the chosen candidates
    return ExactPlacement(uavs_m, int(served), bool(result.status == 0), time.perf_counter() - start)


def _served_model(
    u: np.ndarray, c: np.ndarray, d2: np.ndarray, n_users: int, m: int, rules: CoverageRules,
) -> tuple[np.ndarray, np.ndarray, list[LinearConstraint], int, np.ndarray]:
    """Strategy 2: bounds on the users each open candidate serves (nearest-open association)."""
    n_pairs = len(u)
    # Pairs grouped by user, nearest first (ties: lower candidate index).
    order = np.lexsort((c, d2, u))
    u, c, d2 = u[order], c[order], d2[order]
    first = np.searchsorted(u, u, side="left")  # index of each pair's user's first pair
    rank = np.arange(n_pairs) - first
    # Variables: x (pairs) then y (candidates).
    y0 = n_pairs
    rows_pairs = np.arange(n_pairs)
    served_once = sparse.csr_array((np.ones(n_pairs), (u, rows_pairs)), shape=(n_users, y0 + m))
    open_only = sparse.csr_array(
        (np.r_[np.ones(n_pairs), -np.ones(n_pairs)],
         (np.r_[rows_pairs, rows_pairs], np.r_[rows_pairs, y0 + c])), shape=(n_pairs, y0 + m))
    lengths = rank + 1
    row = np.repeat(rows_pairs, lengths)
    within = np.arange(lengths.sum()) - np.repeat(np.cumsum(lengths) - lengths, lengths)
    col = np.repeat(first, lengths) + within  # the pairs of the same user at rank <= this one
    nearest = sparse.csr_array(
        (np.r_[np.ones(len(row)), -np.ones(n_pairs)], (np.r_[row, rows_pairs], np.r_[col, y0 + c])),
        shape=(n_pairs, y0 + m))

    def load(per_uav: float) -> sparse.csr_array:
        """Rows ``sum_i x_ij + per_uav * y_j`` for every candidate j."""
        values = np.r_[np.ones(n_pairs), np.full(m, per_uav)]
        return sparse.csr_array((values, (np.r_[c, np.arange(m)], np.r_[rows_pairs, y0 + np.arange(m)])),
                                shape=(m, y0 + m))

    budget = sparse.csr_array((np.ones(m), (np.zeros(m, np.int64), y0 + np.arange(m))), shape=(1, y0 + m))
    constraints = [
        LinearConstraint(served_once, -np.inf, 1.0),
        LinearConstraint(open_only, -np.inf, 0.0),
        LinearConstraint(nearest, 0.0, np.inf),
        LinearConstraint(load(-float(rules.min_users)), 0.0, np.inf),
        LinearConstraint(budget, 0.0, float(rules.max_uavs)),
    ]
    if rules.max_users is not None:
        constraints.append(LinearConstraint(load(-float(rules.max_users)), -np.inf, 0.0))
    cost = np.r_[-np.ones(n_pairs), np.full(m, 1.0 / (rules.max_uavs + 1))]
    return cost, np.r_[np.zeros(n_pairs), np.ones(m)], constraints, y0, np.ones(n_pairs + m)


def _exclusive_model(
    u: np.ndarray, c: np.ndarray, n_users: int, m: int, rules: CoverageRules,
) -> tuple[np.ndarray, np.ndarray, list[LinearConstraint], int, np.ndarray]:
    """Strategy 1: every open candidate alone covers at least ``min_users`` users.

    Variables: ``e_ij`` (pairs: user i covered by j alone), then ``y_j``, then
    ``z_i`` (user i covered) and ``n_i`` (number of open candidates covering i, in
    [0, max_uavs]). Rows: ``n_i = sum_j y_j``; ``z_i <= n_i``; ``e_ij <= y_j``;
    ``e_ij + n_i + (M - 1) y_j <= M + 1`` with ``M = max_uavs`` (with j open, e_ij = 1
    only when n_i = 1; with j closed the row is slack); ``sum_i e_ij >= min_users y_j``.
    """
    n_pairs, big = len(u), float(rules.max_uavs)
    y0, z0 = n_pairs, n_pairs + m
    n0 = z0 + n_users
    width = n0 + n_users
    pairs, users, cands = np.arange(n_pairs), np.arange(n_users), np.arange(m)

    def rows(values: list, row_idx: list, col_idx: list, n_rows: int) -> sparse.csr_array:
        return sparse.csr_array((np.concatenate(values), (np.concatenate(row_idx), np.concatenate(col_idx))),
                                shape=(n_rows, width))

    count = rows([np.ones(n_users), -np.ones(n_pairs)], [users, u], [n0 + users, y0 + c], n_users)
    covered = rows([np.ones(n_users), -np.ones(n_users)], [users, users], [z0 + users, n0 + users], n_users)
    open_only = rows([np.ones(n_pairs), -np.ones(n_pairs)], [pairs, pairs], [pairs, y0 + c], n_pairs)
    alone = rows([np.ones(n_pairs), np.ones(n_pairs), np.full(n_pairs, big - 1.0)],
                 [pairs, pairs, pairs], [pairs, n0 + u, y0 + c], n_pairs)
    justified = rows([np.ones(n_pairs), np.full(m, -float(rules.min_users))],
                     [c, cands], [pairs, y0 + cands], m)
    budget = rows([np.ones(m)], [np.zeros(m, np.int64)], [y0 + cands], 1)
    constraints = [
        LinearConstraint(count, 0.0, 0.0),
        LinearConstraint(covered, -np.inf, 0.0),
        LinearConstraint(open_only, -np.inf, 0.0),
        LinearConstraint(alone, -np.inf, big + 1.0),
        LinearConstraint(justified, 0.0, np.inf),
        LinearConstraint(budget, 0.0, big),
    ]
    cost = np.r_[np.zeros(n_pairs), np.full(m, 1.0 / (rules.max_uavs + 1)),
                 -np.ones(n_users), np.zeros(n_users)]
    integrality = np.r_[np.zeros(n_pairs), np.ones(m), np.zeros(2 * n_users)]
    return cost, integrality, constraints, y0, np.r_[np.ones(n_pairs + m + n_users), np.full(n_users, big)]


def capacitated_optimum(users_m: np.ndarray, rules: CoverageRules, candidates_m: np.ndarray,
                        time_limit_s: float = 60.0) -> ExactPlacement:
    """The capacitated maximal covering problem over ``candidates_m``, solved exactly (admission control).

    Open at most ``max_uavs`` candidates and assign users to open candidates in range, each candidate taking
    between ``min_users`` and ``max_users`` users, to maximise the users assigned (then the fewest UAVs).
    Variables ``y_j`` (open, binary) and ``x_ij`` (user i assigned to j, continuous in [0, 1])::

        sum_j x_ij <= 1                                   each user at most once
        min_users y_j <= sum_i x_ij <= max_users y_j      the station limit and the deployment rule
        sum_j y_j <= max_uavs

    Given integral ``y`` the rest is a transportation problem, whose optimum is integral. The assignment is
    the best one, not the radio's strongest-first admission: ``n_served`` bounds from above what any
    placement on these candidates admits (:func:`uav_swarm.missions.wifi.capacitated.admitted_users` judges
    the chosen positions with the radio's own rule).

    Raises:
        ValueError: ``rules`` without a station limit (``max_users``).
        RuntimeError: HiGHS found no feasible point.
    """
    if rules.max_users is None:
        raise ValueError("capacitated_optimum needs rules.max_users (the station limit)")
    start = time.perf_counter()
    users_m = np.asarray(users_m, np.float64).reshape(-1, 2)
    u, c, _, cands = _useful_pairs(users_m, candidates_m, rules)
    if len(cands) == 0 or rules.max_uavs == 0:
        return ExactPlacement(np.zeros((0, 2)), 0, True, time.perf_counter() - start)
    n_users, m, p = len(users_m), len(cands), len(u)
    # Variables: x (p pairs), then y (m candidates).
    cost = np.concatenate([-np.ones(p), np.full(m, 1.0 / (rules.max_uavs + 1))])
    pair = np.arange(p)
    once = sparse.csr_array((np.ones(p), (u, pair)), shape=(n_users, p + m))
    load = sparse.csr_array((np.ones(p), (c, pair)), shape=(m, p + m))
    open_y = sparse.csr_array((np.ones(m), (np.arange(m), p + np.arange(m))), shape=(m, p + m))
    budget = sparse.csr_array((np.ones(m), (np.zeros(m, np.int64), p + np.arange(m))), shape=(1, p + m))
    constraints = [
        LinearConstraint(once, -np.inf, 1.0),
        LinearConstraint(load - rules.max_users * open_y, -np.inf, 0.0),
        LinearConstraint(load - rules.min_users * open_y, 0.0, np.inf),
        LinearConstraint(budget, 0.0, rules.max_uavs),
        *_separation_rows(cands, rules.min_separation_m, p, p + m),
    ]
    integrality = np.concatenate([np.zeros(p), np.ones(m)])
    result = milp(cost, constraints=constraints, integrality=integrality, bounds=Bounds(0.0, 1.0),
                  options={"time_limit": time_limit_s})
    if result.x is None:
        raise RuntimeError(f"HiGHS found no feasible placement: {result.message}")
    chosen = np.flatnonzero(result.x[p:] > 0.5)
    uavs_m = cands[chosen]
    uavs_m = uavs_m[np.lexsort((uavs_m[:, 0], uavs_m[:, 1]))] if len(uavs_m) else np.zeros((0, 2))
    served = int(round(result.x[:p].sum()))
    return ExactPlacement(uavs_m, served, bool(result.status == 0), time.perf_counter() - start)
