"""Admission control, as a deployed access point does it: a full UAV refuses a station, which tries the next.

A UAV admits at most a fixed number of stations (hostapd's ``max_num_sta``) and refuses the next one
(802.11 status 17); the refused station then asks its next-strongest UAV in range. The radio model
(:mod:`uav_swarm.world.comms`) decides who is in range of whom and calls :func:`admit_stations` when a
station limit is set; this module holds only the admission itself, on plain arrays.

Examples:
    >>> import numpy as np
    >>> d2 = np.array([[1.0, 4.0, 9.0], [16.0, 9.0, 1.0]])  # (K = 2 UAVs, N = 3 users)
    >>> admit_stations(d2, d2 < 100.0, np.array([1, 1])).tolist()  # one place each
    [0, -1, 1]
"""

from __future__ import annotations

import numpy as np

__all__ = ["admit_stations"]


def admit_stations(d2: np.ndarray, in_range: np.ndarray, free: np.ndarray,
                   association: np.ndarray | None = None) -> np.ndarray:
    """Admission control: pairs strongest first, a full UAV refuses, a refused user tries its next UAV.

    The (user, UAV) pairs in range are ordered by squared distance (strongest signal first), then
    UAV index, then user index; a pair is admitted while its user has no UAV and its UAV has a free
    place. Because both sides rank pairs by the same order, this greedy gives the unique stable
    matching, which deferred acceptance computes in vectorised rounds: every waiting user
    asks its strongest UAV that has not refused it, and every UAV keeps its strongest askers up to
    its free places.

    Args:
        d2: (K, N) squared UAV-user distances.
        in_range: (K, N) bool, the user is in range of the UAV.
        free: (K,) int, places each UAV still has.
        association: (N,) int, users already associated (kept as they are, not re-admitted); -1 waits.

    Returns:
        (N,) int association, -1 for users refused everywhere or out of range.
    """
    n_uavs, n_users = d2.shape
    result = np.full(n_users, -1, np.int64) if association is None else association.copy()
    waiting = result < 0
    # Each waiting user's UAVs in range, strongest first (a stable sort keeps the lower index on ties).
    order = np.argsort(np.where(in_range, d2, np.inf), axis=0, kind="stable")  # (K, N)
    reach = in_range.sum(axis=0)
    tried = np.zeros(n_users, np.int64)
    held = np.zeros(n_users, bool)  # a tentative place (deferred acceptance)
    while True:
        asking = np.flatnonzero(waiting & ~held & (tried < reach))
        if asking.size == 0:
            break
        choice = order[tried[asking], asking]
        tried[asking] += 1
        holders = np.flatnonzero(held)
        cand_u = np.concatenate([holders, asking])
        cand_k = np.concatenate([result[holders], choice])
        # Each UAV keeps its strongest candidates (ties: lower user index) up to its free places.
        rank_key = np.lexsort((cand_u, d2[cand_k, cand_u], cand_k))
        cand_u, cand_k = cand_u[rank_key], cand_k[rank_key]
        first = np.searchsorted(cand_k, cand_k, side="left")
        keep = (np.arange(cand_k.size) - first) < free[cand_k]
        held[:] = False
        result[waiting] = -1
        held[cand_u[keep]] = True
        result[cand_u[keep]] = cand_k[keep]
    return result


