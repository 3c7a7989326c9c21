"""Who shares the medium with whom, and how much airtime each access point gets (ideal CSMA).

**Carrier-sense graph.** Two APs *hear each other* when they are on the same channel and each receives the
other at or above the carrier-sense threshold (free space between UAVs, equal powers: the relation is
symmetric). An AP defers while a neighbour in this graph transmits; co-channel APs that do not hear each
other transmit at the same time and interfere at each other's stations (:func:`hidden_interferers`).

**Airtime: ideal CSMA.** Only *active* APs (those with stations to serve) contend. Saturated CSMA is
modelled by its classic product form (Boorstyn et al. 1987; Wang and Kar 2005): the set ``S`` of APs
transmitting at an instant is an independent set of the carrier-sense graph among active APs, with
probability ``rho^|S| / Z``, where ``rho`` (the *access intensity*, mean transmission over mean backoff time)
is a table value and ``Z`` sums ``rho^|S|`` over all independent sets (the empty set included). An AP's
*airtime* is the probability that it transmits, ``sum over S containing k of rho^|S| / Z``. This is
deterministic, exact for K <= 16 (all 2^K subsets are enumerated), and shows what the clique rules miss: a
lone AP gets ``rho / (1 + rho)``; two APs that hear each other get ``rho / (1 + 2 rho)`` each; an AP
between two neighbours that do not hear each other is starved (``rho / (1 + 3 rho + rho^2)``), as ns-3 shows.

Examples:
    >>> chain = np.array([[[False, True, False], [True, False, True], [False, True, False]]])
    >>> csma_airtime(chain, np.ones((1, 3), bool), 50.0).round(3).tolist()
    [[0.962, 0.019, 0.962]]
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["MAX_CONTENDERS", "carrier_sense_graph", "csma_airtime", "independent_set_airtime",
           "check_contenders", "hidden_interferers"]

MAX_CONTENDERS = 16
"""The most APs per world: the airtime enumerates all 2^K subsets."""


@numba.njit(cache=True, nogil=True)
def carrier_sense_graph(ap_power_dbm: np.ndarray, channels: np.ndarray, cca_threshold_dbm: float
                        ) -> np.ndarray:
    """``(B, K, K)`` bool: APs ``i != j`` on the same channel that receive each other at >= the threshold.

    Args:
        ap_power_dbm: (B, K, K) power AP ``i`` receives from AP ``j`` (dBm).
        channels: (B, K) channel number of each AP (int64).
        cca_threshold_dbm: The carrier-sense threshold at the channel width.
    """
    n_worlds, n_uavs = channels.shape
    graph = np.zeros((n_worlds, n_uavs, n_uavs), np.bool_)
    for c in range(n_worlds):
        for i in range(n_uavs):
            for j in range(n_uavs):
                graph[c, i, j] = i != j and channels[c, i] == channels[c, j] \
                    and ap_power_dbm[c, i, j] >= cca_threshold_dbm
    return graph


@numba.njit(cache=True, nogil=True)
def independent_set_airtime(graph: np.ndarray, active: np.ndarray, rho: float) -> np.ndarray:
    """:func:`csma_airtime` without the size check (compiled; callable from compiled code).

    Each world's subsets of active APs are built up from their lowest member: ``S`` is independent when ``S``
    without its lowest member ``k`` is and no other member of ``S`` is a neighbour of ``k``; its weight is
    ``rho`` times that subset's.
    """
    n_worlds, n_uavs = active.shape
    airtime = np.zeros((n_worlds, n_uavs))
    members = np.empty(n_uavs, np.int64)
    for c in range(n_worlds):
        m = 0
        for k in range(n_uavs):
            if active[c, k]:
                members[m] = k
                m += 1
        if m == 0:
            continue
        neighbours = np.zeros(m, np.int64)  # bit masks over the active APs' local indices
        for i in range(m):
            for j in range(m):
                if graph[c, members[i], members[j]]:
                    neighbours[i] |= 1 << j
        weight = np.zeros(1 << m)
        weight[0] = 1.0
        total = 1.0
        share = np.zeros(m)
        for subset in range(1, 1 << m):
            lowest = 0
            while not (subset >> lowest) & 1:
                lowest += 1
            rest = subset ^ (1 << lowest)
            if weight[rest] == 0.0 or neighbours[lowest] & rest:
                continue
            weight[subset] = weight[rest] * rho
            total += weight[subset]
            for i in range(m):
                if (subset >> i) & 1:
                    share[i] += weight[subset]
        for i in range(m):
            airtime[c, members[i]] = share[i] / total
    return airtime


def check_contenders(n_uavs: int) -> None:
    """Refuse more than :data:`MAX_CONTENDERS` APs per world.

    Raises:
        ValueError: Too many.
    """
    if n_uavs > MAX_CONTENDERS:
        raise ValueError(f"the 802.11 airtime model takes at most {MAX_CONTENDERS} UAVs per world, "
                         f"got {n_uavs}")


def csma_airtime(graph: np.ndarray, active: np.ndarray, access_intensity: float) -> np.ndarray:
    """``(B, K)`` airtime of each AP under ideal CSMA among the active APs (0 for an inactive AP).

    Args:
        graph: (B, K, K) bool carrier-sense graph (:func:`carrier_sense_graph`).
        active: (B, K) bool, the AP has stations to serve.
        access_intensity: ``rho > 0``.

    Raises:
        ValueError: More than :data:`MAX_CONTENDERS` APs per world.
    """
    check_contenders(active.shape[1])
    return independent_set_airtime(np.ascontiguousarray(graph, dtype=np.bool_),
                                   np.ascontiguousarray(active, dtype=np.bool_), float(access_intensity))


@numba.njit(cache=True, nogil=True)
def hidden_interferers(graph: np.ndarray, channels: np.ndarray, active: np.ndarray, airtime: np.ndarray,
                       airtime_weighting: float) -> np.ndarray:
    """``(B, K, J)`` weight with which AP ``j``'s signal counts as interference at AP ``k``'s stations.

    AP ``j`` interferes when it is active, on ``k``'s channel, ``j != k`` and not heard by ``k`` (it then
    transmits regardless of ``k``); its weight is ``(1 - w) + w * airtime_j``, ``w`` the table's
    ``interference_airtime_weighting`` (0: always on). Zero elsewhere. Compiled (callable from compiled code).
    """
    n_worlds, n_uavs = channels.shape
    weights = np.zeros((n_worlds, n_uavs, n_uavs))
    for c in range(n_worlds):
        for k in range(n_uavs):
            for j in range(n_uavs):
                if j != k and active[c, j] and channels[c, j] == channels[c, k] and not graph[c, k, j]:
                    weights[c, k, j] = (1.0 - airtime_weighting) + airtime_weighting * airtime[c, j]
    return weights
