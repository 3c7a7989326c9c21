"""A channel for each UAV's access point: greedy colouring of the APs' carrier-sense graph, few changes.

Two APs *conflict* when they would hear each other on one channel (received power at or above the
carrier-sense threshold, :func:`uav_swarm.world.wifi.coverage.channel_conflicts`): on one channel they
share airtime, on two they do not. A plan is *valid* when no two conflicting APs share a channel.

:func:`plan_channels`, for each world:

1. a ``previous`` plan that is still valid (channels usable, no conflict on one channel) is kept as it is;
2. otherwise the APs are taken by decreasing number of conflicts (ties: lower index); each keeps its previous
   channel when no AP already given a channel conflicts with it there, else takes the first usable channel
   (in the config's order) free of conflicts;
3. an AP with no free channel takes the one where the conflicting APs already on it are received weakest in
   total (milliwatts; ties: the earlier channel): the least shared airtime.

Deterministic. Greedy colouring never needs more than ``max conflicts + 1`` channels: with that many usable
channels the plan is valid.

Examples:
    >>> import numpy as np
    >>> from uav_swarm.world.comms import RadioConfig
    >>> radio = RadioConfig(propagation="802.11")
    >>> uavs = np.array([[[0.0, 0.0], [10.0, 0.0], [5000.0, 0.0]]])
    >>> plan_channels(uavs, radio, np.full(3, 10.0)).tolist()  # the far UAV reuses the first channel
    [[36, 40, 36]]
"""

from __future__ import annotations

import numba
import numpy as np

from uav_swarm.world.radio_config import RadioConfig
from uav_swarm.world.wifi.coverage import access_points_on, channel_conflicts
from uav_swarm.world.wifi.phy import dbm_to_mw

__all__ = ["plan_channels", "plan_is_valid"]


def plan_is_valid(plan: np.ndarray, conflict: np.ndarray, usable: tuple[int, ...]) -> bool:
    """One world's ``plan`` (K,) uses usable channels only and puts no two conflicting APs on one channel."""
    return bool(_valid(np.asarray(plan, np.int64), np.asarray(conflict, np.bool_),
                       np.asarray(usable, np.int64)))


@numba.njit(cache=True, nogil=True)
def _valid(plan: np.ndarray, conflict: np.ndarray, usable: np.ndarray) -> bool:
    """:func:`plan_is_valid` of one world, compiled."""
    n_uavs = plan.size
    for k in range(n_uavs):
        if not np.any(usable == plan[k]):
            return False
        for j in range(n_uavs):
            if conflict[k, j] and plan[j] == plan[k]:
                return False
    return True


@numba.njit(cache=True, nogil=True)
def _numpy_sum(values: np.ndarray) -> float:
    """``values.sum()`` as numpy adds a short float64 array (pairwise: eight partial sums from 8 values)."""
    n = values.size
    if n < 8:
        total = 0.0  # numpy starts from -0.0 and adds in order: the same for these sums of powers
        for i in range(n):
            total += values[i]
        return total
    partial = values[:8].copy()
    i = 8
    while i + 8 <= n:
        for j in range(8):
            partial[j] += values[i + j]
        i += 8
    total = ((partial[0] + partial[1]) + (partial[2] + partial[3])) + ((partial[4] + partial[5])
                                                                       + (partial[6] + partial[7]))
    while i < n:
        total += values[i]
        i += 1
    return total


@numba.njit(cache=True, nogil=True)
def _colour(conflict: np.ndarray, power_mw: np.ndarray, usable: np.ndarray, previous: np.ndarray,
            has_previous: bool) -> np.ndarray:
    """One world's greedy colouring (steps 2-3 of the module docstring)."""
    n_uavs, n_usable = conflict.shape[0], usable.size
    degree = np.zeros(n_uavs, np.int64)
    for k in range(n_uavs):
        for j in range(n_uavs):
            degree[k] += conflict[k, j]
    order = np.argsort(-degree, kind="mergesort")  # stable: ties by the lower index
    plan = np.full(n_uavs, -1, np.int64)
    busy = np.zeros(n_usable, np.bool_)
    for k in order:
        busy[:] = False
        for j in range(n_uavs):
            if conflict[k, j] and plan[j] >= 0:
                for u in range(n_usable):
                    if usable[u] == plan[j]:
                        busy[u] = True
        if has_previous:
            for u in range(n_usable):
                if usable[u] == previous[k] and not busy[u]:
                    plan[k] = previous[k]
            if plan[k] >= 0:
                continue
        for u in range(n_usable):
            if not busy[u]:
                plan[k] = usable[u]
                break
        if plan[k] >= 0:
            continue
        best, best_load = 0, np.inf
        for u in range(n_usable):
            on_channel = np.empty(n_uavs)
            m = 0
            for j in range(n_uavs):
                if conflict[k, j] and plan[j] == usable[u]:
                    on_channel[m] = power_mw[k, j]
                    m += 1
            load = _numpy_sum(on_channel[:m])
            if load < best_load:
                best, best_load = u, load
        plan[k] = usable[best]
    return plan


@numba.njit(cache=True, nogil=True)
def _plan_worlds(conflict: np.ndarray, power_mw: np.ndarray, usable: np.ndarray, previous: np.ndarray,
                 has_previous: bool) -> np.ndarray:
    """Steps 1-3 of the module docstring for every world: ``(B, K)`` channels."""
    plans = np.empty(conflict.shape[:2], np.int64)
    for c in range(conflict.shape[0]):
        if has_previous and _valid(previous[c], conflict[c], usable):
            plans[c] = previous[c]
        else:
            plans[c] = _colour(conflict[c], power_mw[c], usable, previous[c], has_previous)
    return plans


def plan_channels(uavs_m: np.ndarray, config: RadioConfig, altitudes_m: np.ndarray | None = None,
                  previous: np.ndarray | None = None, enabled: np.ndarray | None = None) -> np.ndarray:
    """A channel for each UAV of each world (module docstring).

    Args:
        uavs_m: (K, 2) or (B, K, 2) UAV positions, metres.
        config: The radio model; its ``ieee80211.usable_channels`` are the colours.
        altitudes_m: (K,) or (B, K) each UAV's altitude; None: ``config.altitude_m``.
        previous: (K,) or (B, K) the plan in force, kept where it stays valid; None: none.
        enabled: (K,) or (B, K) bool, the UAVs whose access point is on; an AP that is off conflicts with
            none (it keeps a channel for when it is on again). None: every AP on.

    Returns:
        (K,) or (B, K) int channel numbers, the shape of ``uavs_m`` without its last axis.

    Raises:
        ValueError: ``previous`` of another shape than the plan.
    """
    uavs = np.asarray(uavs_m, dtype=np.float64)
    single = uavs.ndim == 2
    worlds = uavs[None] if single else uavs
    power_dbm, conflict = channel_conflicts(worlds, config, altitudes_m)
    if enabled is not None:
        on = access_points_on(enabled, *worlds.shape[:2])
        conflict = conflict & on[:, :, None] & on[:, None, :]
    power_mw = dbm_to_mw(power_dbm)
    usable = config.ieee80211.usable_channels
    before = None if previous is None else np.asarray(previous, dtype=np.int64)
    if before is not None:
        if before.shape != worlds.shape[:2] and before.shape != worlds.shape[1:2]:
            raise ValueError(f"previous must have shape {worlds.shape[1:2]} or {worlds.shape[:2]}, "
                             f"got {before.shape}")
        before = np.broadcast_to(before, worlds.shape[:2])
    has_previous = before is not None
    previous_plan = np.ascontiguousarray(np.zeros(worlds.shape[:2], np.int64) if before is None else before)
    plans = _plan_worlds(np.ascontiguousarray(conflict), np.ascontiguousarray(power_mw),
                         np.asarray(usable, dtype=np.int64), previous_plan, has_previous)
    return plans[0] if single else plans
