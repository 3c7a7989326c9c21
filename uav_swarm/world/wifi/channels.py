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

import numpy as np

from uav_swarm.world.radio_config import RadioConfig
from uav_swarm.world.wifi.coverage import channel_conflicts
from uav_swarm.world.wifi.phy import dbm_to_mw

__all__ = ["plan_channels", "plan_is_valid"]


def plan_is_valid(plan: np.ndarray, conflict: np.ndarray, usable: tuple[int, ...]) -> bool:
    """One world's ``plan`` (K,) uses usable channels only and puts no two conflicting APs on one channel."""
    if not set(np.asarray(plan).tolist()) <= set(usable):
        return False
    same = plan[:, None] == plan[None, :]
    return not bool(np.any(same & conflict))


def _colour(conflict: np.ndarray, power_mw: np.ndarray, usable: tuple[int, ...], previous: np.ndarray | None
            ) -> np.ndarray:
    """One world's greedy colouring (steps 2-3 of the module docstring)."""
    n_uavs = conflict.shape[0]
    degree = conflict.sum(axis=1)
    order = np.lexsort((np.arange(n_uavs), -degree))
    plan = np.full(n_uavs, -1, np.int64)
    for k in order:
        taken = conflict[k] & (plan >= 0)
        busy = {int(c) for c in plan[taken]}
        if previous is not None and int(previous[k]) in usable and int(previous[k]) not in busy:
            plan[k] = previous[k]
            continue
        free = [c for c in usable if c not in busy]
        if free:
            plan[k] = free[0]
            continue
        loads = [float(power_mw[k][taken & (plan == c)].sum()) for c in usable]
        plan[k] = usable[int(np.argmin(loads))]
    return plan


def plan_channels(uavs_m: np.ndarray, config: RadioConfig, altitudes_m: np.ndarray | None = None,
                  previous: np.ndarray | None = None) -> np.ndarray:
    """A channel for each UAV of each world (module docstring).

    Args:
        uavs_m: (K, 2) or (B, K, 2) UAV positions, metres.
        config: The radio model; its ``ieee80211.usable_channels`` are the colours.
        altitudes_m: (K,) or (B, K) each UAV's altitude; None: ``config.altitude_m``.
        previous: (K,) or (B, K) the plan in force, kept where it stays valid; None: none.

    Returns:
        (K,) or (B, K) int channel numbers, the shape of ``uavs_m`` without its last axis.

    Raises:
        ValueError: ``previous`` of another shape than the plan.
    """
    uavs = np.asarray(uavs_m, dtype=np.float64)
    single = uavs.ndim == 2
    worlds = uavs[None] if single else uavs
    power_dbm, conflict = channel_conflicts(worlds, config, altitudes_m)
    power_mw = dbm_to_mw(power_dbm)
    usable = config.ieee80211.usable_channels
    before = None if previous is None else np.asarray(previous, dtype=np.int64)
    if before is not None:
        if before.shape != worlds.shape[:2] and before.shape != worlds.shape[1:2]:
            raise ValueError(f"previous must have shape {worlds.shape[1:2]} or {worlds.shape[:2]}, "
                             f"got {before.shape}")
        before = np.broadcast_to(before, worlds.shape[:2])
    plans = np.empty(worlds.shape[:2], np.int64)
    for c in range(len(worlds)):
        old = None if before is None else before[c]
        if old is not None and plan_is_valid(old, conflict[c], usable):
            plans[c] = old
        else:
            plans[c] = _colour(conflict[c], power_mw[c], usable, old)
    return plans[0] if single else plans
