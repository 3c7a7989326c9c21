"""The strategy-2 expert under admission control: the capacitated maximal covering problem.

With admission control (:mod:`uav_swarm.world.comms`, ``RadioConfig.station_limit``) a UAV admits at most
``L = rules.max_users`` users (40: 200 Mbps / 5 Mbps), strongest signal first, and a refused user joins its
next UAV in range. Every admitted user gets at least the minimum rate by construction, so strategy 2
becomes: **place at most ``max_uavs`` UAVs to maximise the users admitted**, every deployed UAV justified
by more than 30 admitted users (the paper's rule as strategy 2 reads it, order-free: every UAV admits at
least ``rules.min_users`` users).

The optimiser (:func:`place_uavs_capacitated`) judges every placement it keeps with the true
association (:func:`uav_swarm.world.admission.admit_stations`), never with a surrogate. It runs from the
greedy's start and from every seed it is given (the expert entry point,
:func:`uav_swarm.missions.wifi.expert.place_uavs`, seeds it with the search expert's placement, whose
31-40 users per UAV leave fewer stranded users than the greedy's full cells), and keeps the best:

1. **Greedy.** Candidates are the points of a square grid (``grid_step_m``) with at least
   ``min_users`` users in range. Each step ranks them by the users they would newly reach (capped at
   ``L``), then by a smooth depth score (``sum(1 - d^2 / r^2)`` over those users), evaluates the best
   ``shortlist`` exactly and adds the one that admits the most users in all; it stops when no
   candidate gains ``min_users``.
2. **Ruin and recreate.** Each UAV in turn is removed and the greedy refills from there; the result
   is kept when it admits more users, or as many with fewer UAVs.
3. **Centring.** Each UAV moves to the centre of the smallest box around its admitted users when
   that admits at least as many users: a canonical position that changes continuously with the crowd.
4. **Rule check.** While a UAV admits fewer than ``min_users`` users, the least loaded one is dropped.

No two UAVs stand closer than ``rules.min_separation_m``: a candidate that close to a UAV already placed
is not feasible for the greedy, a centring move that close to another UAV is not taken, and a seed's
UAV that close to one before it is dropped before the seed is completed. (Two co-located UAVs would
admit twice the station limit over one dense group; the minimum makes them share it from apart.)

The ranking uses only distances and counts, which the 8 symmetries of the square keep, so the
placement of a turned crowd is the turned placement up to exact ties (measured in ``benchmarks/``).
An exact reference on a candidate grid is :func:`uav_swarm.missions.wifi.exact.capacitated_optimum`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from typed_config import Config, param
from uav_swarm.missions.wifi.rules import CoverageRules, candidate_grid, far_from, keep_separated
from uav_swarm.world.admission import admit_stations

__all__ = ["CapacitatedExpertConfig", "admitted_users", "place_uavs_capacitated", "complete_capacitated"]


@dataclass(frozen=True)
class CapacitatedExpertConfig(Config):
    """Settings of the strategy-2 expert under admission control."""

    grid_step_m: float = param(2.5, gt=0.0, le=50.0, doc="spacing of the candidate grid, metres")
    shortlist: int = param(8, ge=1, le=500, doc="best-ranked candidates judged exactly per greedy step")
    ruin_passes: int = param(0, ge=0, le=20, doc="passes of ruin-and-recreate over every UAV")
    centre_passes: int = param(3, ge=0, le=20, doc="passes of the centring step")


def admitted_users(users_m: np.ndarray, uavs_m: np.ndarray, rules: CoverageRules) -> np.ndarray:
    """``(N,)`` association of the users under admission control (``-1``: no network).

    A user is in range within ``rules.radius_m`` (inclusive) and a UAV admits at most ``rules.cap``.
    """
    n_users = len(users_m)
    if len(uavs_m) == 0 or n_users == 0:
        return np.full(n_users, -1, np.int64)
    d2 = ((uavs_m[:, None, :] - users_m[None, :, :]) ** 2).sum(-1)  # (K, N)
    in_range = d2 <= rules.radius_m ** 2
    nearest = np.where(in_range.any(axis=0), d2.argmin(axis=0), -1)
    loads = np.bincount(nearest[nearest >= 0], minlength=len(uavs_m))
    if loads.max(initial=0) <= rules.cap:
        return nearest
    return admit_stations(d2, in_range, np.full(len(uavs_m), rules.cap, np.int64))


class _Search:
    """The greedy, ruin-and-recreate and centring over one crowd."""

    def __init__(self, users_m: np.ndarray, rules: CoverageRules, candidates_m: np.ndarray,
                 config: CapacitatedExpertConfig) -> None:
        self.users_m, self.rules, self.config = users_m, rules, config
        near = cKDTree(candidates_m).sparse_distance_matrix(
            cKDTree(users_m), rules.radius_m * (1 + 1e-9), output_type="ndarray")
        c, u = near["i"].astype(np.int64), near["j"].astype(np.int64)
        d2 = ((candidates_m[c] - users_m[u]) ** 2).sum(-1)
        keep = d2 <= rules.radius_m ** 2
        c, u, d2 = c[keep], u[keep], d2[keep]
        useful = np.bincount(c, minlength=len(candidates_m)) >= rules.min_users
        index = np.cumsum(useful) - 1
        mask = useful[c]
        self.candidates_m = candidates_m[useful]
        self.cand, self.user = index[c[mask]], u[mask]
        self.depth = 1.0 - d2[mask] / rules.radius_m ** 2

    def total(self, uavs_m: np.ndarray) -> int:
        return int(np.count_nonzero(admitted_users(self.users_m, uavs_m, self.rules) >= 0))

    def add_best(self, uavs_m: np.ndarray) -> np.ndarray | None:
        """``uavs_m`` with the best candidate added, or None when none gains ``min_users`` admitted users."""
        m = len(self.candidates_m)
        if m == 0 or len(uavs_m) >= self.rules.max_uavs:
            return None
        free = admitted_users(self.users_m, uavs_m, self.rules) < 0
        fresh = free[self.user]
        reach = np.minimum(np.bincount(self.cand[fresh], minlength=m), self.rules.cap)
        depth = np.bincount(self.cand[fresh], weights=self.depth[fresh], minlength=m)
        order = np.lexsort((np.arange(m), -depth, -reach))
        order = order[reach[order] >= self.rules.min_users]
        order = order[far_from(self.candidates_m[order], uavs_m, self.rules.min_separation_m)]
        order = order[: self.config.shortlist]
        base = int(np.count_nonzero(~free))
        best, best_key = None, (base + self.rules.min_users - 1, -np.inf)
        for j in order:
            trial = np.vstack([uavs_m, self.candidates_m[j]])
            key = (self.total(trial), depth[j])
            if key > best_key:
                best, best_key = trial, key
        return best

    def greedy(self, uavs_m: np.ndarray) -> np.ndarray:
        while (more := self.add_best(uavs_m)) is not None:
            uavs_m = more
        return uavs_m

    def ruin_and_recreate(self, uavs_m: np.ndarray) -> np.ndarray:
        score = (self.total(uavs_m), -len(uavs_m))
        for _ in range(self.config.ruin_passes):
            improved = False
            k = len(uavs_m)
            gap = np.sqrt(((uavs_m[:, None, :] - uavs_m[None, :, :]) ** 2).sum(-1))
            groups = [[i] for i in range(k)] + [
                [i, j] for i in range(k) for j in range(i + 1, k) if gap[i, j] <= 2.0 * self.rules.radius_m]
            for group in groups:
                if max(group) >= len(uavs_m) or len(uavs_m) != k:
                    break
                trial = self.greedy(np.delete(uavs_m, group, axis=0))
                trial_score = (self.total(trial), -len(trial))
                if trial_score > score:
                    uavs_m, score, improved = trial, trial_score, True
            if not improved:
                break
        return uavs_m

    def centre(self, uavs_m: np.ndarray) -> np.ndarray:
        for _ in range(self.config.centre_passes):
            moved = False
            for k in range(len(uavs_m)):
                association = admitted_users(self.users_m, uavs_m, self.rules)
                mine = self.users_m[association == k]
                if len(mine) == 0:
                    continue
                target = 0.5 * (mine.min(axis=0) + mine.max(axis=0))
                if np.allclose(target, uavs_m[k], atol=1e-6) or not far_from(
                        target, np.delete(uavs_m, k, axis=0), self.rules.min_separation_m)[0]:
                    continue
                trial = uavs_m.copy()
                trial[k] = target
                if self.total(trial) >= np.count_nonzero(association >= 0):
                    uavs_m, moved = trial, True
            if not moved:
                break
        return uavs_m

    def separate(self, uavs_m: np.ndarray) -> np.ndarray:
        """A start's UAVs, each dropped when closer than the minimum separation to one before it."""
        uavs_m = np.asarray(uavs_m, np.float64).reshape(-1, 2)
        return uavs_m[keep_separated(uavs_m, self.rules.min_separation_m)]

    def justify(self, uavs_m: np.ndarray) -> np.ndarray:
        """Drop the least loaded UAV while one admits fewer than ``min_users`` users."""
        while len(uavs_m):
            association = admitted_users(self.users_m, uavs_m, self.rules)
            loads = np.bincount(association[association >= 0], minlength=len(uavs_m))
            if loads.min() >= self.rules.min_users:
                break
            uavs_m = np.delete(uavs_m, int(np.argmin(loads)), axis=0)
        return uavs_m


def place_uavs_capacitated(users_m: np.ndarray, rules: CoverageRules, width_m: float, height_m: float,
                           config: CapacitatedExpertConfig | None = None,
                           candidates_m: np.ndarray | None = None,
                           seeds: list[np.ndarray] | None = None) -> np.ndarray:
    """The expert's placement of one crowd under admission control (module docstring).

    Args:
        users_m: ``(N, 2)`` user positions, metres.
        rules: Radius, station limit (``max_users``), ``min_users`` and UAV budget; strategy 2's.
        width_m: Area width, metres.
        height_m: Area height, metres.
        config: The optimiser's effort; defaults if None.
        candidates_m: ``(M, 2)`` candidate positions replacing the grid.
        seeds: Other ``(k, 2)`` starting placements (another expert's); each is completed and improved
            like the greedy's, and the placement admitting the most users wins (ties: fewer UAVs, then
            the greedy's).

    Returns:
        ``(k, 2)`` float64 UAV positions, ``0 <= k <= rules.max_uavs``, sorted by ``(y, x)``; every UAV
        admits between ``rules.min_users`` and ``rules.max_users`` users; every pair stands at least
        ``rules.min_separation_m`` apart.

    Raises:
        ValueError: ``users_m`` is not a finite ``(N, 2)`` array, or ``rules`` have no station limit.
    """
    config = config or CapacitatedExpertConfig()
    users_m = np.asarray(users_m, dtype=np.float64)
    if users_m.ndim != 2 or users_m.shape[1] != 2 or not np.all(np.isfinite(users_m)):
        raise ValueError(f"users_m must be a finite (N, 2) array, got shape {users_m.shape}")
    if rules.max_users is None or rules.exclusive:
        raise ValueError("the capacitated expert needs strategy-2 rules with a station limit (max_users)")
    if len(users_m) < rules.min_users or rules.max_uavs == 0:
        return np.zeros((0, 2))
    if candidates_m is None:
        candidates_m, _ = candidate_grid(width_m, height_m, config.grid_step_m)
    search = _Search(users_m, rules, np.asarray(candidates_m, np.float64), config)
    best, best_key = np.zeros((0, 2)), (-1, 0, 0)
    for rank, start in enumerate([search.greedy(np.zeros((0, 2))), *(seeds or [])]):
        uavs_m = search.separate(start)[: rules.max_uavs]
        uavs_m = search.justify(search.centre(search.ruin_and_recreate(search.greedy(uavs_m))))
        key = (search.total(uavs_m), -len(uavs_m), -rank)
        if key > best_key:
            best, best_key = uavs_m, key
    uavs_m = best
    return uavs_m[np.lexsort((uavs_m[:, 0], uavs_m[:, 1]))] if len(uavs_m) else np.zeros((0, 2))


def complete_capacitated(users_m: np.ndarray, uavs_m: np.ndarray, rules: CoverageRules, width_m: float,
                         height_m: float, config: CapacitatedExpertConfig | None = None) -> np.ndarray:
    """A placement completed and centred under admission control, as the expert does from its seeds.

    UAVs are added greedily while one admits ``min_users`` more users (judged by the radio's admission),
    each UAV is centred on its admitted users when that admits no fewer, and UAVs admitting fewer than
    ``min_users`` are dropped. It never admits fewer users than ``uavs_m`` justified by the rule.

    Raises:
        ValueError: ``rules`` have no station limit.
    """
    config = config or CapacitatedExpertConfig()
    if rules.max_users is None or rules.exclusive:
        raise ValueError("complete_capacitated needs strategy-2 rules with a station limit (max_users)")
    users_m = np.asarray(users_m, dtype=np.float64).reshape(-1, 2)
    uavs_m = np.asarray(uavs_m, dtype=np.float64).reshape(-1, 2)[: rules.max_uavs]
    if len(users_m) < rules.min_users or rules.max_uavs == 0:
        return np.zeros((0, 2))
    candidates_m, _ = candidate_grid(width_m, height_m, config.grid_step_m)
    search = _Search(users_m, rules, candidates_m, config)
    uavs_m = search.justify(search.centre(search.greedy(search.justify(search.separate(uavs_m)))))
    return uavs_m[np.lexsort((uavs_m[:, 0], uavs_m[:, 1]))] if len(uavs_m) else np.zeros((0, 2))
