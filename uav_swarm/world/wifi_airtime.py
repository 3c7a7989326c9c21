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

import functools

import numpy as np

__all__ = ["MAX_CONTENDERS", "carrier_sense_graph", "csma_airtime", "hidden_interferers"]

MAX_CONTENDERS = 16
"""The most APs per world: the airtime enumerates all 2^K subsets."""


def carrier_sense_graph(ap_power_dbm: np.ndarray, channels: np.ndarray, cca_threshold_dbm: float
                        ) -> np.ndarray:
    """``(B, K, K)`` bool: APs ``i != j`` on the same channel that receive each other at >= the threshold.

    Args:
        ap_power_dbm: (B, K, K) power AP ``i`` receives from AP ``j`` (dBm).
        channels: (B, K) channel number of each AP.
        cca_threshold_dbm: The carrier-sense threshold at the channel width.
    """
    n_uavs = channels.shape[1]
    co_channel = channels[:, :, None] == channels[:, None, :]
    return co_channel & (ap_power_dbm >= cca_threshold_dbm) & ~np.eye(n_uavs, dtype=bool)


@functools.lru_cache(maxsize=MAX_CONTENDERS + 1)
def _subsets(n_uavs: int) -> np.ndarray:
    """(2^K, K) float64 membership of every subset of K APs (row ``s``: the bits of ``s``)."""
    rows = np.arange(2**n_uavs, dtype=np.int64)[:, None] >> np.arange(n_uavs, dtype=np.int64)
    members = (rows & 1).astype(np.float64)
    members.setflags(write=False)
    return members


def csma_airtime(graph: np.ndarray, active: np.ndarray, access_intensity: float) -> np.ndarray:
    """``(B, K)`` airtime of each AP under ideal CSMA among the active APs (0 for an inactive AP).

    Args:
        graph: (B, K, K) bool carrier-sense graph (:func:`carrier_sense_graph`).
        active: (B, K) bool, the AP has stations to serve.
        access_intensity: ``rho > 0``.

    Raises:
        ValueError: More than :data:`MAX_CONTENDERS` APs per world.
    """
    n_worlds, n_uavs = active.shape
    if n_uavs > MAX_CONTENDERS:
        raise ValueError(f"the 802.11 airtime model takes at most {MAX_CONTENDERS} UAVs per world, "
                         f"got {n_uavs}")
    if n_uavs == 0:
        return np.zeros((n_worlds, 0))
    members = _subsets(n_uavs)  # (S, K)
    edges = np.einsum("sk,bkl,sl->bs", members, graph.astype(np.float64), members, optimize=True)  # (B, S)
    outside = members @ (~active).T.astype(np.float64)  # (S, B): inactive members of each subset
    size = members.sum(axis=1)  # (S,)
    allowed = (edges == 0.0) & (outside.T == 0.0)
    # rho^|S| relative to the largest allowed set (no overflow for any rho).
    log_weight = np.where(allowed, size * np.log(access_intensity), -np.inf)
    weight = np.exp(log_weight - log_weight.max(axis=1, keepdims=True))  # (B, S); the empty set is allowed
    return (weight @ members) / weight.sum(axis=1, keepdims=True)


def hidden_interferers(graph: np.ndarray, channels: np.ndarray, active: np.ndarray, airtime: np.ndarray,
                       airtime_weighting: float) -> np.ndarray:
    """``(B, K, J)`` weight with which AP ``j``'s signal counts as interference at AP ``k``'s stations.

    AP ``j`` interferes when it is active, on ``k``'s channel, ``j != k`` and not heard by ``k`` (it then
    transmits regardless of ``k``); its weight is ``(1 - w) + w * airtime_j``, ``w`` the table's
    ``interference_airtime_weighting`` (0: always on). Zero elsewhere.
    """
    n_uavs = channels.shape[1]
    co_channel = channels[:, :, None] == channels[:, None, :]
    hidden = co_channel & ~graph & ~np.eye(n_uavs, dtype=bool) & active[:, None, :]
    duty = (1.0 - airtime_weighting) + airtime_weighting * airtime  # (B, J)
    return np.where(hidden, duty[:, None, :], 0.0)
