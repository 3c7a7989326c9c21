"""The Wi-Fi placement problem in geometric form: rules, user association and candidate grids.

Shared by the greedy expert (:mod:`uav_swarm.missions.wifi.expert`, which describes the problem) and
the exact MILP (:mod:`uav_swarm.missions.wifi.exact`): a user is covered within ``radius_m`` of a UAV
and associates with the nearest one (ties to the lower index); every UAV must be justified by
``min_users`` users and may serve at most ``max_users``; no two UAVs stand closer than
``min_separation_m`` (horizontal distance: a placement's positions are targets, whichever UAV flies to
them, so the horizontal minimum also holds in 3-D with altitude layers). Every optimiser treats a candidate
closer than the minimum to a UAV already placed as infeasible (:func:`far_from`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

__all__ = ["CoverageRules", "Assignment", "squared_distances", "assign_users", "is_valid_placement",
           "candidate_grid", "far_from", "is_separated", "keep_separated"]


@dataclass(frozen=True)
class CoverageRules:
    """The placement constraints in geometric form.

    Attributes:
        radius_m: Horizontal coverage radius (a user at this distance is still covered).
        min_users: Every deployed UAV is justified by at least this many users.
        max_users: Every deployed UAV serves at most this many users (``None``: no cap).
        max_uavs: Largest number of UAVs.
        exclusive: How ``min_users`` counts: True (strategy 1) the users this UAV alone
            covers (who would lose the network without it); False (strategy 2) the users it
            serves (its association).
        admission_control: The radio's UAVs admit at most ``max_users`` stations and refuse the
            next (:mod:`uav_swarm.world.comms`); False: the paper's model, every user in range joins.
        min_separation_m: No two UAVs of a placement stand closer than this, metres (0: no minimum).
    """

    radius_m: float
    min_users: int
    max_users: int | None
    max_uavs: int
    exclusive: bool = False
    admission_control: bool = False
    min_separation_m: float = 0.0

    def __post_init__(self) -> None:
        if not (self.radius_m > 0.0 and math.isfinite(self.radius_m)):
            raise ValueError(f"CoverageRules.radius_m = {self.radius_m!r} must be finite and > 0")
        if self.min_users < 1:
            raise ValueError(f"CoverageRules.min_users = {self.min_users} must be >= 1")
        if self.max_users is not None and self.max_users < self.min_users:
            raise ValueError(
                f"CoverageRules.max_users = {self.max_users} must be >= min_users = {self.min_users}")
        if self.max_uavs < 0:
            raise ValueError(f"CoverageRules.max_uavs = {self.max_uavs} must be >= 0")
        if not (self.min_separation_m >= 0.0 and math.isfinite(self.min_separation_m)):
            raise ValueError(f"CoverageRules.min_separation_m = {self.min_separation_m!r}: allowed >= 0")

    @property
    def cap(self) -> int:
        """``max_users`` as an int (a huge number when uncapped)."""
        return np.iinfo(np.int64).max // 4 if self.max_users is None else self.max_users


@dataclass(frozen=True)
class Assignment:
    """Users' association with a placement.

    Attributes:
        association: ``(N,)`` index of the serving UAV, -1 when uncovered.
        distance_sq_m2: ``(N,)`` squared distance to the nearest UAV (``inf`` without UAVs).
        counts: ``(K,)`` number of users each UAV serves.
        n_covering: ``(N,)`` number of UAVs within the radius of each user.
        exclusive_counts: ``(K,)`` number of users each UAV alone covers.
    """

    association: np.ndarray
    distance_sq_m2: np.ndarray
    counts: np.ndarray
    n_covering: np.ndarray
    exclusive_counts: np.ndarray

    @property
    def n_served(self) -> int:
        """Number of covered (served) users."""
        return int(np.count_nonzero(self.association >= 0))


def squared_distances(users_m: np.ndarray, uavs_m: np.ndarray) -> np.ndarray:
    """``(N, K)`` squared horizontal distances from every user to every UAV, metres squared."""
    dx = users_m[:, 0, None] - uavs_m[None, :, 0]
    dy = users_m[:, 1, None] - uavs_m[None, :, 1]
    return dx * dx + dy * dy


@numba.njit(cache=True, nogil=True)
def _associate(users_m: np.ndarray, uavs_m: np.ndarray, radius_sq: float
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`assign_users`'s arrays in one compiled pass.

    The squared distances are :func:`squared_distances`', operation for operation (``dx * dx + dy * dy``);
    ties go to the lower index.
    """
    n, k = users_m.shape[0], uavs_m.shape[0]
    association = np.full(n, -1, np.int64)
    best = np.empty(n)
    counts = np.zeros(k, np.int64)
    n_covering = np.zeros(n, np.int64)
    exclusive = np.zeros(k, np.int64)
    for i in range(n):
        arg, low, covering = 0, np.inf, 0
        for j in range(k):
            dx = users_m[i, 0] - uavs_m[j, 0]
            dy = users_m[i, 1] - uavs_m[j, 1]
            d2 = dx * dx + dy * dy
            if d2 < low:
                arg, low = j, d2
            if d2 <= radius_sq:
                covering += 1
        best[i] = low
        n_covering[i] = covering
        if low <= radius_sq:
            association[i] = arg
            counts[arg] += 1
            if covering == 1:
                exclusive[arg] += 1
    return association, best, counts, n_covering, exclusive


def assign_users(users_m: np.ndarray, uavs_m: np.ndarray, radius_m: float) -> Assignment:
    """Associate every user with its nearest UAV within ``radius_m``.

    Args:
        users_m: ``(N, 2)`` user positions, metres.
        uavs_m: ``(K, 2)`` UAV positions, metres.
        radius_m: Coverage radius, metres.

    Examples:
        >>> state = assign_users(np.array([[0.0, 0.0], [5.0, 0.0], [50.0, 0.0]]),
        ...                      np.array([[1.0, 0.0], [6.0, 0.0]]), 10.0)
        >>> state.association.tolist(), state.counts.tolist(), state.exclusive_counts.tolist()
        ([0, 1, -1], [1, 1], [0, 0])
    """
    n, k = len(users_m), len(uavs_m)
    if k == 0:
        none = np.zeros(0, np.int64)
        return Assignment(np.full(n, -1, np.int64), np.full(n, np.inf), none, np.zeros(n, np.int64), none)
    users = np.ascontiguousarray(users_m, dtype=np.float64).reshape(-1, 2)
    uavs = np.ascontiguousarray(uavs_m, dtype=np.float64).reshape(-1, 2)
    return Assignment(*_associate(users, uavs, float(radius_m) * float(radius_m)))


def is_valid_placement(state: Assignment, rules: CoverageRules) -> bool:
    """Whether a placement's assignment obeys the rules (UAV budget, per-UAV bounds)."""
    justified = state.exclusive_counts if rules.exclusive else state.counts
    return bool(len(state.counts) <= rules.max_uavs and np.all(justified >= rules.min_users)
                and np.all(state.counts <= rules.cap))


def candidate_grid(width_m: float, height_m: float, step_m: float) -> tuple[np.ndarray, int]:
    """Cell centres of a regular grid over the area, row-major from the lower-left corner.

    Returns:
        The ``(M, 2)`` candidate positions in metres and the number of columns.
    """
    nx = max(1, int(math.floor(width_m / step_m)))
    ny = max(1, int(math.floor(height_m / step_m)))
    xs = (np.arange(nx) + 0.5) * (width_m / nx)
    ys = (np.arange(ny) + 0.5) * (height_m / ny)
    gx, gy = np.meshgrid(xs, ys)
    return np.stack([gx.ravel(), gy.ravel()], axis=1), nx


def far_from(points_m: np.ndarray, uavs_m: np.ndarray, min_separation_m: float) -> np.ndarray:
    """``(M,)`` True where a point stands at least ``min_separation_m`` from every UAV (horizontal).

    Examples:
        >>> far_from(np.array([[0.0, 0.0], [3.0, 3.0]]), np.array([[3.0, 4.0]]), 5.0).tolist()
        [True, False]
    """
    points = np.asarray(points_m, dtype=np.float64).reshape(-1, 2)
    uavs = np.asarray(uavs_m, dtype=np.float64).reshape(-1, 2)
    if min_separation_m <= 0.0 or len(uavs) == 0 or len(points) == 0:
        return np.ones(len(points), dtype=bool)
    return squared_distances(points, uavs).min(axis=1) >= min_separation_m ** 2


def is_separated(uavs_m: np.ndarray, min_separation_m: float) -> bool:
    """Whether every pair of UAVs stands at least ``min_separation_m`` apart (horizontal)."""
    uavs = np.asarray(uavs_m, dtype=np.float64).reshape(-1, 2)
    if min_separation_m <= 0.0 or len(uavs) < 2:
        return True
    d2 = squared_distances(uavs, uavs)
    np.fill_diagonal(d2, np.inf)
    return bool(d2.min() >= min_separation_m ** 2)


def keep_separated(uavs_m: np.ndarray, min_separation_m: float) -> np.ndarray:
    """Indices of the UAVs kept in order: a UAV closer than the minimum to one kept before is dropped.

    Examples:
        >>> keep_separated(np.array([[0.0, 0.0], [2.0, 0.0], [9.0, 0.0]]), 5.0).tolist()
        [0, 2]
    """
    uavs = np.asarray(uavs_m, dtype=np.float64).reshape(-1, 2)
    kept: list[int] = []
    for i in range(len(uavs)):
        if far_from(uavs[i], uavs[kept], min_separation_m)[0]:
            kept.append(i)
    return np.array(kept, dtype=np.int64)
