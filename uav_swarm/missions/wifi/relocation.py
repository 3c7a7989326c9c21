"""Relocating single UAVs of a strategy-2 placement: every UAV to every candidate, scored at once.

A **relocation** takes one UAV away and puts it back at a candidate position (appended last,
so it captures a user only when strictly nearer than the user's other UAVs, as an addition does
in :mod:`uav_swarm.missions.wifi.expert`). Under strategy 2 (a UAV is justified by the users it
*serves*, between ``min_users`` and ``max_users``), :func:`relocation_scores` scores all ``K x M``
relocations of a placement in a handful of passes over the (candidate, user) pairs:

- for users whose nearest UAV is not the moved one, nothing changes but the capture by the
  candidate (the same counts as adding a UAV there);
- for users the moved UAV served, their association falls back to their second-nearest UAV
  (or to none), and the candidate captures them against that one instead.

Each relocation gets the placement's **violation** afterwards (users missing below ``min_users``
plus users beyond ``max_users``, summed over UAVs) and its **served** users. :func:`relocate`
applies the best relocation while it lowers ``(violation, -served)`` lexicographically: on a
valid placement it raises the served users and keeps the rules; on a broken one (learned proposals,
overloaded or unjustified UAVs) it repairs first. Moves that "jump" a UAV across the area are
scored as cheaply as small shifts, which is what makes room for a missing UAV or packs UAVs to
their 40 users. A relocation that puts the UAV closer than ``rules.min_separation_m`` to another UAV is
not feasible.

Examples:
    >>> from uav_swarm.missions.wifi.expert import CandidatePairs, PlacementSearch
    >>> from uav_swarm.missions.wifi.rules import CoverageRules, candidate_grid
    >>> rules = CoverageRules(radius_m=30.0, min_users=31, max_users=40, max_uavs=10)
    >>> users = np.random.default_rng(0).normal([150.0, 60.0], 4.0, size=(35, 2))
    >>> search = PlacementSearch(users, rules, CandidatePairs(users, candidate_grid(200, 200, 5.0)[0], rules))
    >>> state = adopt_by_relocation(search, np.array([[40.0, 40.0]]), max_moves=5)  # serves nobody
    >>> state.n_served, bool(np.hypot(*(search.uavs_m[0] - [150.0, 60.0])) < 30.0)
    (35, True)
"""

from __future__ import annotations

import functools

import numba
import numpy as np

from uav_swarm.missions.wifi.expert import CandidatePairs, PlacementSearch, separated_candidates
from uav_swarm.missions.wifi.rules import (
    Assignment,
    CoverageRules,
    assign_users,
    far_from,
    is_valid_placement,
    keep_separated,
    squared_distances,
)

__all__ = ["placement_violation", "relocation_scores", "relocate", "adopt_by_relocation",
           "insert_by_relocation", "warm_up"]


def placement_violation(counts: np.ndarray, rules: CoverageRules) -> np.ndarray:
    """Users missing below ``min_users`` plus users beyond ``max_users``, elementwise over ``counts``."""
    counts = np.asarray(counts)
    short = np.maximum(rules.min_users - counts, 0)
    return short if rules.max_users is None else short + np.maximum(counts - rules.max_users, 0)


def _nearest_two(users_m: np.ndarray, uavs_m: np.ndarray) -> tuple[np.ndarray, ...]:
    """Per user: nearest UAV, its squared distance, second-nearest UAV (-1 if none), its squared distance.

    Ties go to the lower UAV index, as :func:`uav_swarm.missions.wifi.rules.assign_users` breaks them.
    """
    n, k = len(users_m), len(uavs_m)
    d2 = squared_distances(users_m, uavs_m)
    rows = np.arange(n)
    if k == 1:
        return np.zeros(n, np.int64), d2[:, 0], np.full(n, -1), np.full(n, np.inf)
    first = np.argmin(d2, axis=1)
    e1 = d2[rows, first]
    d2[rows, first] = np.inf
    second = np.argmin(d2, axis=1)
    return first, e1, second, d2[rows, second]


@numba.njit(cache=True, nogil=True)
def _captures(cand: np.ndarray, user: np.ndarray, pair_d2: np.ndarray, owner: np.ndarray,
              fallback: np.ndarray, e1: np.ndarray, e2: np.ndarray, k: int, m: int
              ) -> tuple[np.ndarray, np.ndarray]:
    """The captures of every candidate, in one pass over the (candidate, user) pairs.

    Returns ``base`` ``(K + 1, M)``: per owner + 1 (0: uncovered) and candidate, the users the
    candidate captures against the current placement (row ``j + 1``: the users UAV ``j`` would lose to
    it, which its own relocation gives back); and ``gained`` ``(K + 1, K, M)``: per fallback + 1
    (0: none), moved UAV and candidate, the moved UAV's users the candidate captures against their
    fallback instead.
    """
    base = np.zeros((k + 1, m), np.int64)
    gained = np.zeros((k + 1, k, m), np.int64)
    for p in range(len(cand)):
        u, c, d = user[p], cand[p], pair_d2[p]
        o = owner[u]
        if d < e1[u]:
            base[o + 1, c] += 1
        if o >= 0 and (fallback[u] < 0 or d < e2[u]):
            gained[fallback[u] + 1, o, c] += 1
    return base, gained


@functools.cache
def warm_up() -> None:
    """Load the compiled capture pass once per process (about half a second) before the first search."""
    none = np.zeros(1, np.int64)
    _captures(none, none, np.zeros(1), none, none - 1, np.ones(1), np.ones(1), 1, 1)


def relocation_scores(
    pairs: CandidatePairs, users_m: np.ndarray, uavs_m: np.ndarray, rules: CoverageRules,
) -> tuple[np.ndarray, np.ndarray]:
    """The placement after moving UAV ``j`` to candidate ``c``, for every ``j`` and ``c`` (module docstring).

    Args:
        pairs: The (candidate, user) pairs within the coverage radius.
        users_m: ``(N, 2)`` user positions, metres.
        uavs_m: ``(K, 2)`` UAV positions, metres, ``K >= 1``.
        rules: Strategy 2's rules (``exclusive=False``).

    Returns:
        ``(K, M)`` violation and ``(K, M)`` served users of every relocation.

    Raises:
        ValueError: ``rules`` are strategy 1's (users a UAV alone covers), or there is no UAV.
    """
    if rules.exclusive:
        raise ValueError("relocation scores strategy 2's rules (users a UAV serves), not exclusive coverage")
    k, m = len(uavs_m), len(pairs.candidates_m)
    if k == 0:
        raise ValueError("relocation needs at least one UAV")
    r2 = rules.radius_m ** 2
    nearest, e1, second, e2 = _nearest_two(users_m, uavs_m)
    owner = np.where(e1 <= r2, nearest, -1)
    fallback = np.where((owner >= 0) & (e2 <= r2), second, -1)  # who serves the user without its UAV
    counts = np.bincount(owner[owner >= 0], minlength=k)
    served = int(np.count_nonzero(owner >= 0))
    back = fallback >= 0
    counts_without = np.tile(counts, (k, 1)) + np.bincount(
        nearest[back] * k + fallback[back], minlength=k * k).reshape(k, k)
    served_without = served - counts + np.bincount(nearest[back], minlength=k)

    base, gained = _captures(pairs.cand, pairs.user, pairs.d2, owner, fallback, e1, e2, k, m)

    load = base.sum(axis=0)[None, :] - base[1:] + gained.sum(axis=0)
    newly = base[0][None, :] + gained[0]
    stolen = base[1:].astype(np.int32)
    left = counts_without.T.astype(np.int32)[:, :, None] - stolen[:, None, :] - gained[1:].astype(np.int32)
    others = placement_violation(left, rules)  # (K, K, M): the other UAVs' violations
    others[np.arange(k), np.arange(k), :] = 0  # the moved UAV's own row is its new load
    violation = others.sum(axis=0) + placement_violation(load, rules)
    return violation, served_without[:, None] + newly


def _key(violation: np.ndarray | int, served: np.ndarray | int, n_users: int) -> np.ndarray | int:
    """``(violation, -served)`` as one integer, lower is better."""
    return violation * (n_users + 1) - served


def _crowded(uavs_m: np.ndarray, candidates_m: np.ndarray, min_separation_m: float) -> np.ndarray | None:
    """``(K, M)`` True where UAV ``j`` moved to candidate ``c`` is closer than the minimum to another UAV."""
    if min_separation_m <= 0.0 or len(uavs_m) < 2:
        return None
    close = squared_distances(uavs_m, candidates_m) < min_separation_m ** 2  # (K, M)
    return close.sum(axis=0)[None, :] - close > 0


def relocate(search: PlacementSearch, max_moves: int) -> int:
    """Apply the best relocation while it lowers ``(violation, -served)``; at most ``max_moves``.

    Returns:
        The number of relocations applied.
    """
    rules, n = search.rules, len(search.users_m)
    for moves in range(max_moves):
        if len(search.uavs_m) == 0 or len(search.pairs.candidates_m) == 0:
            return moves
        current = _key(int(placement_violation(search.state.counts, rules).sum()), search.state.n_served, n)
        violation, served = relocation_scores(search.pairs, search.users_m, search.uavs_m, rules)
        key = np.asarray(_key(violation, served, n))
        crowded = _crowded(search.uavs_m, search.pairs.candidates_m, rules.min_separation_m)
        if crowded is not None:
            key = np.where(crowded, np.iinfo(np.int64).max, key)
        j, c = np.unravel_index(int(np.argmin(key)), key.shape)
        if key[j, c] >= current:
            return moves
        uavs_m = np.vstack([np.delete(search.uavs_m, j, axis=0), search.pairs.candidates_m[c]])
        search.uavs_m, search.state = uavs_m, assign_users(search.users_m, uavs_m, rules.radius_m)
    return max_moves


def adopt_by_relocation(search: PlacementSearch, proposals_m: np.ndarray, max_moves: int) -> Assignment:
    """Start ``search`` from the proposals, made valid by relocations.

    A proposal closer than the minimum separation to one before it is dropped, and beyond the UAV
    budget the least loaded UAV; then relocations repair the placement,
    and while it still breaks the rules the UAV with the largest violation is dropped and the
    repair resumes. Returns the final (valid) assignment, also set on ``search``.
    """
    rules = search.rules
    uavs_m = np.asarray(proposals_m, np.float64).reshape(-1, 2)
    uavs_m = uavs_m[keep_separated(uavs_m, rules.min_separation_m)]
    while True:
        state = assign_users(search.users_m, uavs_m, rules.radius_m)
        if len(uavs_m) > rules.max_uavs:
            uavs_m = np.delete(uavs_m, int(np.argmin(state.counts)), axis=0)
            continue
        search.uavs_m, search.state = uavs_m, state
        relocate(search, max_moves)
        if is_valid_placement(search.state, rules):
            return search.state
        worst = int(np.argmax(placement_violation(search.state.counts, rules)))
        uavs_m = np.delete(search.uavs_m, worst, axis=0)


def insert_by_relocation(search: PlacementSearch, max_moves: int, tries: int) -> bool:
    """Add one UAV where the most uncovered users are, then repair its neighbours by relocation.

    The greedy addition of :class:`uav_swarm.missions.wifi.expert.PlacementSearch` adds a UAV only
    where it is valid at once; here the new UAV may first take users its neighbours need, and
    relocations move the neighbours until the placement is valid again. Up to ``tries`` well-separated
    places are tried (most uncovered users first); the first that ends valid and serving more users is
    kept. Returns whether a UAV was added.
    """
    rules, pairs = search.rules, search.pairs
    if tries == 0 or len(search.uavs_m) >= rules.max_uavs or len(pairs.candidates_m) == 0:
        return False
    uncovered = search.state.association[pairs.user] < 0
    newly = np.bincount(pairs.cand[uncovered], minlength=len(pairs.candidates_m))
    ranked = np.lexsort((np.arange(len(newly)), -newly))
    ranked = ranked[newly[ranked] > 0]
    ranked = ranked[far_from(pairs.candidates_m[ranked], search.uavs_m, rules.min_separation_m)]
    start_uavs, start_state = search.uavs_m, search.state
    for c in separated_candidates(pairs.candidates_m, ranked, tries, rules.radius_m):
        uavs_m = np.vstack([start_uavs, pairs.candidates_m[c]])
        search.uavs_m, search.state = uavs_m, assign_users(search.users_m, uavs_m, rules.radius_m)
        relocate(search, max_moves)
        if is_valid_placement(search.state, rules) and search.state.n_served > start_state.n_served:
            return True
        search.uavs_m, search.state = start_uavs, start_state
    return False
