"""The Wi-Fi experts: where to put up to 10 UAVs over a crowd (strategies 1 and 2).

The radio model of :mod:`uav_swarm.world.comms` reduces, for placement, to two
facts: a user is covered when its horizontal distance to a UAV is at most the
coverage radius, and a covered user associates with the strongest, i.e. the
nearest, UAV (ties go to the lower UAV index, as ``argmax`` does). A UAV's
capacity is shared equally by its associated users.

**The problem both experts solve** (:class:`uav_swarm.missions.wifi.rules.CoverageRules`): choose at most
``max_uavs`` positions, maximise the number of covered users, then use as few UAVs
as possible, under the paper's rule "a UAV is deployed only for a group of more
than 30 users" made order-free:

- strategy 1 (``exclusive=True``): every UAV alone covers more than 30 users, i.e.
  removing any UAV would leave more than 30 users without network (the last UAV
  deployed always found more than 30 users not yet covered);
- strategy 2 (``exclusive=False``): every UAV serves (is the association of) between
  31 and ``max_users`` = capacity / minimum rate = 200 / 5 = 40 users, so every covered
  user gets >= 5 Mbps and the expert's strategy-2 QoS equals its strategy-1 QoS. The
  lower bound counts served users, not exclusive ones, so that two UAVs may split a
  group of 70 between them (each then serves 35 users that the other also reaches).

Both are judged with the real association, so they can be checked on any placement
with ``comms.evaluate_coverage``.

**The optimiser** (:func:`place_uavs`): greedy on a candidate grid (each step
adds the candidate that newly covers the most users while keeping the placement
valid; ties go to the candidate closest to the users it newly covers, then to the
lowest index), then ruin-and-recreate local search until no move helps (remove one
UAV, or two UAVs less than two radii apart, and refill greedily from the grid
candidates nearby; keep the result when it covers more users, or as many with
fewer UAVs), and a continuous refinement that moves each UAV to the centroid of
the users it serves whenever that keeps the placement valid and loses no user
(a canonical, "centred" position, which makes the demonstrations consistent).
Every step keeps the UAVs ``rules.min_separation_m`` apart: a candidate closer than that to a UAV
already placed is not feasible, nor is a centring move that comes that close to another UAV.
Everything is deterministic.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy.spatial import cKDTree

from typed_config import Config, ConfigError, param
from uav_swarm.missions.wifi.capacitated import (
    CapacitatedExpertConfig,
    complete_capacitated,
    place_uavs_capacitated,
)
from uav_swarm.missions.wifi.group_expert import GroupExpertConfig, place_uavs_by_groups
from uav_swarm.missions.wifi.ieee80211_expert import Ieee80211ExpertConfig
from uav_swarm.missions.wifi.replan_expert import ReplanExpertConfig
from uav_swarm.missions.wifi.rules import (
    Assignment,
    CoverageRules,
    assign_users,
    candidate_grid,
    far_from,
    is_valid_placement,
    keep_separated,
)
from uav_swarm.missions.wifi.stable_expert import StableExpertConfig, place_uavs_stable

__all__ = ["WifiExpertConfig", "CandidatePairs", "PlacementSearch", "separated_candidates", "place_uavs",
           "adopt_placement"]


@dataclass(frozen=True)
class WifiExpertConfig(Config):
    """Settings of the Wi-Fi experts (shared by both strategies)."""

    max_uavs: int = param(10, ge=1, le=10, doc="largest number of UAVs the expert may deploy")
    min_group_size: int = param(
        30, ge=0, le=10_000, doc="a UAV is deployed only when it serves MORE than this many users")
    grid_step_m: float = param(2.5, gt=0.0, le=50.0, doc="spacing of the expert's candidate grid, metres")
    max_moves: int = param(
        20, ge=0, le=1000, doc="improving ruin-and-recreate moves allowed after the greedy (0: greedy only)")
    branching: int = param(
        4, ge=1, le=50, doc="greedy fills try this many separated first candidates and keep the best")
    refine_passes: int = param(3, ge=0, le=100, doc="passes of the continuous centroid refinement")
    method: Literal["auto", "search", "groups", "capacitated", "stable"] = param(
        "auto", doc="'search' (greedy + ruin-and-recreate), 'groups' (strategy 2 only, "
        "uav_swarm.missions.wifi.group_expert), 'capacitated' (strategy 2 under admission control, "
        "uav_swarm.missions.wifi.capacitated), 'stable' (strategy 2 only: the consensus of jittered "
        "solves of the capacitated expert under admission control, else of the search, "
        "uav_swarm.missions.wifi.stable_expert) or 'auto' (strategy 1: search; strategy 2: capacitated "
        "under admission control, else groups); under the 802.11 radio the 802.11 expert runs "
        "(uav_swarm.missions.wifi.ieee80211_expert), which 'auto' picks")
    groups: GroupExpertConfig = param(GroupExpertConfig(), doc="the group expert ([task.expert.groups])")
    capacitated: CapacitatedExpertConfig = param(
        CapacitatedExpertConfig(), doc="the expert under admission control ([task.expert.capacitated])")
    stable: StableExpertConfig = param(StableExpertConfig(), doc="the stable expert ([task.expert.stable])")
    ieee80211: Ieee80211ExpertConfig = param(
        Ieee80211ExpertConfig(), doc="the expert under the 802.11 radio ([task.expert.ieee80211])")
    replan: ReplanExpertConfig = param(
        ReplanExpertConfig(), doc="the expert's replans in flight ([task.expert.replan])")

    def method_for(self, rules: CoverageRules) -> str:
        """The method that runs under ``rules``: ``"search"``, ``"groups"``, ``"capacitated"``, ``"stable"``.

        Raises:
            ConfigError: a strategy-2 method asked for strategy 1 (exclusive rules), or ``"capacitated"``
                without admission control.
        """
        if self.method in ("groups", "capacitated", "stable") and rules.exclusive:
            raise ConfigError(f"WifiExpertConfig.method = {self.method!r} is strategy 2's; strategy 1 uses "
                              "'search'")
        if self.method == "capacitated" and not rules.admission_control:
            raise ConfigError("WifiExpertConfig.method = 'capacitated' needs admission control: set "
                              "[task.radio] station_limit (an integer or 'auto')")
        if self.method == "auto":
            return "search" if rules.exclusive else "capacitated" if rules.admission_control else "groups"
        return self.method


class CandidatePairs:
    """Sparse (candidate, user) pairs within the coverage radius, over useful candidates only."""

    def __init__(self, users_m: np.ndarray, candidates_m: np.ndarray, rules: CoverageRules) -> None:
        r2 = rules.radius_m ** 2
        near = cKDTree(users_m).sparse_distance_matrix(
            cKDTree(candidates_m), rules.radius_m * (1.0 + 1e-9) + 1e-9, output_type="ndarray")
        u, c = near["i"].astype(np.int64), near["j"].astype(np.int64)
        dx = users_m[:, 0][u] - candidates_m[:, 0][c]
        dy = users_m[:, 1][u] - candidates_m[:, 1][c]
        d = dx * dx + dy * dy  # exact, not the tree's rounding
        inside = d <= r2
        u, c, d = u[inside], c[inside], d[inside]
        useful = np.bincount(c, minlength=len(candidates_m)) >= rules.min_users
        keep = useful[c]
        index = np.cumsum(useful) - 1
        self.candidates_m = candidates_m[useful]
        self.cand = index[c[keep]]
        self.user = u[keep]
        self.d2 = d[keep]
        self.r2 = r2

    def restrict(self, keep: np.ndarray) -> CandidatePairs:
        """The pairs of the candidates where ``keep`` (``(M,)`` bool) is True, re-indexed."""
        sub = object.__new__(CandidatePairs)
        mask = keep[self.cand]
        index = np.cumsum(keep) - 1
        sub.candidates_m = self.candidates_m[keep]
        sub.cand = index[self.cand[mask]]
        sub.user = self.user[mask]
        sub.d2 = self.d2[mask]
        sub.r2 = self.r2
        return sub


def _best_addition(
    pairs: CandidatePairs, state: Assignment, rules: CoverageRules, min_gain: int,
) -> tuple[np.ndarray, np.ndarray]:
    """The candidates whose addition keeps the placement valid, best first.

    The new UAV is appended last, so it captures a user only when strictly nearer
    than the user's current UAV. Candidates rank by newly covered users, then by
    closeness to the users they capture, then by index.

    Returns:
        The valid candidates newly covering at least ``min_gain`` users, best first,
        and the ``(M,)`` number of users each candidate would newly cover.
    """
    m, k = len(pairs.candidates_m), len(state.counts)
    if m == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    if rules.exclusive:
        return _best_exclusive_addition(pairs, state, rules, min_gain)
    captured = pairs.d2 < state.distance_sq_m2[pairs.user]
    c, u = pairs.cand[captured], pairs.user[captured]
    owner = state.association[u]
    load = np.bincount(c, minlength=m)
    newly = np.bincount(c[owner < 0], minlength=m)
    ok = (load >= rules.min_users) & (load <= rules.cap) & (newly >= min_gain)
    if k:
        stolen = owner >= 0
        loss = np.bincount(c[stolen] * k + owner[stolen], minlength=m * k).reshape(m, k)
        left = state.counts[None, :] - loss
        ok &= np.all((left >= rules.min_users) & (left <= rules.cap), axis=1)
    closeness = np.bincount(c, weights=pairs.r2 - pairs.d2[captured], minlength=m)
    order = np.lexsort((np.arange(m), -closeness, -newly))
    return order[ok[order]], newly


def _best_exclusive_addition(
    pairs: CandidatePairs, state: Assignment, rules: CoverageRules, min_gain: int,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_best_addition` when ``min_users`` counts users a UAV alone covers (strategy 1)."""
    m, k = len(pairs.candidates_m), len(state.counts)
    covering = state.n_covering[pairs.user]
    fresh = covering == 0
    newly = np.bincount(pairs.cand[fresh], minlength=m)
    load = np.bincount(pairs.cand[pairs.d2 < state.distance_sq_m2[pairs.user]], minlength=m)
    ok = (newly >= max(rules.min_users, min_gain)) & (load <= rules.cap)
    if k:
        shared = covering == 1  # these users stop being their UAV's alone
        owner = state.association[pairs.user[shared]]
        loss = np.bincount(pairs.cand[shared] * k + owner, minlength=m * k).reshape(m, k)
        ok &= np.all(state.exclusive_counts[None, :] - loss >= rules.min_users, axis=1)
    closeness = np.bincount(pairs.cand, weights=(pairs.r2 - pairs.d2) * fresh, minlength=m)
    order = np.lexsort((np.arange(m), -closeness, -newly))
    return order[ok[order]], newly


def separated_candidates(
    candidates_m: np.ndarray, ranked: np.ndarray, count: int, separation_m: float,
) -> list[int]:
    """Up to ``count`` candidates in rank order, each ``separation_m`` from those already taken."""
    taken: list[int] = []
    for j in ranked[:200]:
        if all(np.hypot(*(candidates_m[j] - candidates_m[t])) >= separation_m for t in taken):
            taken.append(int(j))
            if len(taken) == count:
                break
    return taken


class PlacementSearch:
    """Greedy + ruin-and-recreate local search + centroid refinement over one crowd."""

    def __init__(self, users_m: np.ndarray, rules: CoverageRules, pairs: CandidatePairs) -> None:
        self.users_m = users_m
        self.rules = rules
        self.pairs = pairs
        self.uavs_m = np.zeros((0, 2))
        self.state = assign_users(users_m, self.uavs_m, rules.radius_m)
        self.branching = 1

    def _assess(self, uavs_m: np.ndarray) -> Assignment | None:
        """The assignment of a placement, or None when it breaks the rules."""
        state = assign_users(self.users_m, uavs_m, self.rules.radius_m)
        return state if is_valid_placement(state, self.rules) else None

    def _fill(
        self, uavs_m: np.ndarray, pairs: CandidatePairs, branching: int = 1,
    ) -> tuple[np.ndarray, Assignment] | None:
        """Add UAVs greedily (first repairing an overloaded placement); None if still invalid.

        With ``branching > 1`` the first addition tries that many well-separated
        top-ranked candidates, each completed greedily, and keeps the best outcome.
        """
        state = assign_users(self.users_m, uavs_m, self.rules.radius_m)
        while len(uavs_m) < self.rules.max_uavs:
            valid = is_valid_placement(state, self.rules)
            ranked, _ = _best_addition(pairs, state, self.rules, min_gain=1 if valid else 0)
            ranked = ranked[far_from(pairs.candidates_m[ranked], uavs_m, self.rules.min_separation_m)]
            if len(ranked) == 0:
                break
            if branching > 1:
                firsts = separated_candidates(pairs.candidates_m, ranked, branching, self.rules.radius_m / 2)
                outcomes = [self._fill(np.vstack([uavs_m, pairs.candidates_m[j]]), pairs) for j in firsts]
                return max((o for o in outcomes if o is not None), default=None,
                           key=lambda o: (o[1].n_served, -len(o[0])))
            uavs_m = np.vstack([uavs_m, pairs.candidates_m[ranked[0]]])
            state = assign_users(self.users_m, uavs_m, self.rules.radius_m)
        return (uavs_m, state) if is_valid_placement(state, self.rules) else None

    def adopt(self, uavs_m: np.ndarray) -> None:
        """Start from a given placement, first made valid.

        A UAV closer than the minimum separation to one before it is dropped first. Then, while it breaks
        the rules: beyond the UAV budget or with an unjustified UAV, the least
        justified UAV is dropped; with only overloaded UAVs (strategy 2), UAVs are added to take
        users over (:meth:`_fill`), and when no addition can, the most loaded UAV is dropped.
        """
        uavs_m = np.asarray(uavs_m, dtype=np.float64).reshape(-1, 2)
        uavs_m = uavs_m[keep_separated(uavs_m, self.rules.min_separation_m)]
        while True:
            state = assign_users(self.users_m, uavs_m, self.rules.radius_m)
            if is_valid_placement(state, self.rules):
                break
            justified = state.exclusive_counts if self.rules.exclusive else state.counts
            if len(uavs_m) > self.rules.max_uavs or np.any(justified < self.rules.min_users):
                uavs_m = np.delete(uavs_m, int(np.argmin(justified)), axis=0)
                continue
            filled = self._fill(uavs_m, self.pairs)
            if filled is not None:
                uavs_m, state = filled
                break
            uavs_m = np.delete(uavs_m, int(np.argmax(state.counts)), axis=0)
        self.uavs_m, self.state = uavs_m, state

    def _accept(self, result: tuple[np.ndarray, Assignment] | None) -> bool:
        """Keep ``result`` when it serves more users, or as many with fewer UAVs."""
        if result is None:
            return False
        uavs_m, state = result
        if (state.n_served, -len(uavs_m)) <= (self.state.n_served, -len(self.uavs_m)):
            return False
        self.uavs_m, self.state = uavs_m, state
        return True

    def greedy(self) -> None:
        """Add UAVs while one newly covers at least one user and the placement stays valid."""
        self._accept(self._fill(self.uavs_m, self.pairs, self.branching))

    def _ruin_once(self) -> bool:
        """Try removing one UAV, or two interacting ones, and refilling nearby; True on improvement."""
        k = len(self.uavs_m)
        gap = np.sqrt(((self.uavs_m[:, None, :] - self.uavs_m[None, :, :]) ** 2).sum(-1))
        groups = [[i] for i in range(k)] + [
            [i, j] for i in range(k) for j in range(i + 1, k) if gap[i, j] <= 2.0 * self.rules.radius_m]
        for group in groups:
            removed = self.uavs_m[group]
            near = np.min(((self.pairs.candidates_m[:, None, :] - removed[None]) ** 2).sum(-1), axis=1)
            pairs = self.pairs.restrict(near <= (3.0 * self.rules.radius_m) ** 2)
            if self._accept(self._fill(np.delete(self.uavs_m, group, axis=0), pairs, self.branching)):
                return True
        return False

    def ruin_and_recreate(self, max_moves: int) -> None:
        """Apply improving ruin-and-recreate moves until none helps (at most ``max_moves``)."""
        for _ in range(max_moves):
            if not self._ruin_once():
                return

    def refine(self, passes: int) -> None:
        """Move each UAV to the centroid of its users when that loses nobody, stays valid and separated."""
        for _ in range(passes):
            moved = False
            for k in range(len(self.uavs_m)):
                target = self.users_m[self.state.association == k].mean(axis=0)
                if np.allclose(target, self.uavs_m[k], atol=1e-6) or not far_from(
                        target, np.delete(self.uavs_m, k, axis=0), self.rules.min_separation_m)[0]:
                    continue
                trial = self.uavs_m.copy()
                trial[k] = target
                state = self._assess(trial)
                if state is not None and state.n_served >= self.state.n_served:
                    self.uavs_m, self.state = trial, state
                    moved = True
            if not moved:
                return

    def run(self, config: WifiExpertConfig) -> np.ndarray:
        """The full optimiser; returns the ``(k, 2)`` placement in metres."""
        self.branching = config.branching
        self.greedy()
        self.ruin_and_recreate(config.max_moves)
        self.refine(config.refine_passes)
        before = len(self.uavs_m)
        self.greedy()
        if len(self.uavs_m) != before:
            self.refine(config.refine_passes)
        return self.uavs_m


def place_uavs(
    users_m: np.ndarray,
    rules: CoverageRules,
    width_m: float,
    height_m: float,
    config: WifiExpertConfig,
    candidates_m: np.ndarray | None = None,
    velocities_m_s: np.ndarray | None = None,
) -> np.ndarray:
    """The expert's placement for one crowd.

    Args:
        users_m: ``(N, 2)`` user positions, metres.
        rules: The constraints (radius, per-UAV load bounds, UAV budget).
        width_m: Area width (x extent), metres.
        height_m: Area height (y extent), metres.
        config: Expert settings (method, grid step, search effort).
        candidates_m: Optional ``(M, 2)`` candidate positions replacing the grid (search only).
        velocities_m_s: Optional ``(N, 2)`` user velocities; the group expert plans over its horizon
            with them (a crowd at rest without).

    Returns:
        ``(k, 2)`` float64 UAV positions in metres, ``0 <= k <= rules.max_uavs``,
        sorted by ``(y, x)``; every UAV serves ``[min_users, max_users]`` users; every pair stands at
        least ``rules.min_separation_m`` apart.

    Raises:
        ValueError: ``users_m`` is not a finite ``(N, 2)`` array.
        ConfigError: the group method asked for strategy 1.
    """
    users_m = np.asarray(users_m, dtype=np.float64)
    if users_m.ndim != 2 or users_m.shape[1] != 2 or not np.all(np.isfinite(users_m)):
        raise ValueError(f"users_m must be a finite (N, 2) array, got shape {users_m.shape}")
    method = config.method_for(rules)
    if method == "groups":
        return place_uavs_by_groups(users_m, rules, config.groups, velocities_m_s)
    if method == "capacitated":
        return _capacitated_placement(users_m, rules, width_m, height_m, config)
    w, h = width_m, height_m
    if method == "stable" and rules.admission_control:
        return place_uavs_stable(
            users_m, config.stable, lambda crowd: _capacitated_placement(crowd, rules, w, h, config),
            lambda crowd, uavs: complete_capacitated(crowd, uavs, rules, w, h, config.capacitated))
    if method == "stable":
        return place_uavs_stable(
            users_m, config.stable, lambda crowd: _search_placement(crowd, rules, w, h, config, None),
            lambda crowd, uavs: adopt_placement(crowd, uavs, rules, w, h, config))
    return _search_placement(users_m, rules, width_m, height_m, config, candidates_m)


def _capacitated_placement(users_m: np.ndarray, rules: CoverageRules, width_m: float, height_m: float,
                           config: WifiExpertConfig) -> np.ndarray:
    """The capacitated expert's placement, seeded with the search expert's."""
    seed = _search_placement(users_m, rules, width_m, height_m, config, None)
    return place_uavs_capacitated(users_m, rules, width_m, height_m, config.capacitated, seeds=[seed])


def adopt_placement(users_m: np.ndarray, uavs_m: np.ndarray, rules: CoverageRules, width_m: float,
                    height_m: float, config: WifiExpertConfig) -> np.ndarray:
    """``uavs_m`` made valid over ``users_m`` (paper's association), then improved by the search's steps."""
    if len(users_m) < rules.min_users or rules.max_uavs == 0:
        return np.zeros((0, 2))
    candidates_m, _ = candidate_grid(width_m, height_m, config.grid_step_m)
    search = PlacementSearch(users_m, rules, CandidatePairs(users_m, candidates_m, rules))
    search.adopt(uavs_m)
    search.branching = config.branching
    search.refine(config.refine_passes)
    search.greedy()
    search.refine(config.refine_passes)
    adopted = search.uavs_m
    return adopted[np.lexsort((adopted[:, 0], adopted[:, 1]))] if len(adopted) else np.zeros((0, 2))


def _search_placement(users_m: np.ndarray, rules: CoverageRules, width_m: float, height_m: float,
                      config: WifiExpertConfig, candidates_m: np.ndarray | None) -> np.ndarray:
    """The search expert's placement (greedy + ruin-and-recreate + centring) under the paper's association."""
    if candidates_m is None:
        candidates_m, _ = candidate_grid(width_m, height_m, config.grid_step_m)
    if len(users_m) < rules.min_users or rules.max_uavs == 0:
        return np.zeros((0, 2))
    pairs = CandidatePairs(users_m, np.asarray(candidates_m, np.float64), rules)
    search = PlacementSearch(users_m, rules, pairs)
    uavs_m = search.run(config)
    return uavs_m[np.lexsort((uavs_m[:, 0], uavs_m[:, 1]))] if len(uavs_m) else np.zeros((0, 2))
