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

**Collisions.** Ideal CSMA has none; real backoffs do. AP ``k``'s *contenders* are itself plus, for each
neighbour ``j`` it hears, the probability (under the same product form) that ``j`` counts its backoff down
while ``k`` does: ``n_k = 1 + sum over neighbours j of Z(no AP of N[k] or N[j] transmits) / Z(no AP of
N[k] transmits)``, ``N[k]`` being ``k`` and its neighbours. In a clique of ``m`` this is ``m``; at the end
of a chain whose middle AP is starved it is about 1. Bianchi's saturation model (IEEE JSAC 18(3), 2000)
with ``n_k`` stations, a minimum contention window ``cw_min`` and ``backoff_stages`` doublings gives the
probability ``P_s`` that a transmission succeeds; the share of the AP's airtime that carries data is
``P_s / (P_s + (1 - P_s) r)``, ``r`` the table's collision time over success time (:func:`collision_success`).

Examples:
    >>> chain = np.array([[[False, True, False], [True, False, True], [False, True, False]]])
    >>> csma_airtime(chain, np.ones((1, 3), bool), 50.0).round(3).tolist()
    [[0.962, 0.019, 0.962]]
    >>> airtime, contenders = contention(chain, np.ones((1, 3), bool), 50.0)
    >>> contenders.round(2).tolist()  # the ends rarely count down with the starved middle
    [[1.02, 3.0, 1.02]]
    >>> round(collision_success(10.0, 15, 6, 1.0), 3)  # ten contenders, CWmin 15, CWmax 1023
    0.775
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["MAX_CONTENDERS", "carrier_sense_graph", "csma_airtime", "independent_set_airtime", "contention",
           "collision_success", "collision_success_shares", "check_contenders", "hidden_interferers"]

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
def contention(graph: np.ndarray, active: np.ndarray, rho: float) -> tuple[np.ndarray, np.ndarray]:
    """``(B, K)`` airtime of each AP (:func:`csma_airtime`) and ``(B, K)`` its contenders (module docstring).

    Compiled, without the size check (callable from compiled code). An active AP that hears no other active
    AP (nor is heard) gets ``rho / (1 + rho)``, its own factor of the product form; the subsets of the
    others are built up from their lowest member: ``S`` is independent when ``S`` without its lowest member
    ``k`` is and no other member of ``S`` is a neighbour of ``k``; its weight is ``rho`` times that subset's
    (the factors of the lone APs cancel out of every airtime and contender count). An AP that
    hears another gets its contenders from sums of these weights over the subsets of the APs it does not
    hear (a walk over the submasks: one term for an AP of a clique). Inactive APs: airtime 0, 1 contender.
    """
    n_worlds, n_uavs = active.shape
    airtime = np.zeros((n_worlds, n_uavs))
    contenders = np.ones((n_worlds, n_uavs))
    members = np.empty(n_uavs, np.int64)
    alone = rho / (1.0 + rho)  # an active AP that hears no other active AP: its factor of the product form
    for c in range(n_worlds):
        m = 0
        for k in range(n_uavs):
            if active[c, k]:
                linked = False
                for j in range(n_uavs):
                    if j != k and active[c, j] and (graph[c, k, j] or graph[c, j, k]):
                        linked = True
                if linked:
                    members[m] = k
                    m += 1
                else:
                    airtime[c, k] = alone
        if m == 0:
            continue
        neighbours = np.zeros(m, np.int64)  # bit masks over the active APs' local indices
        heard = False
        for i in range(m):
            for j in range(m):
                if graph[c, members[i], members[j]]:
                    neighbours[i] |= 1 << j
                    heard = True
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
        if not heard:
            continue
        everyone = (1 << m) - 1
        for i in range(m):
            if neighbours[i] == 0:
                continue
            closed_i = neighbours[i] | (1 << i)
            quiet_i = _subset_sum(weight, everyone & ~closed_i)
            count = 1.0
            for j in range(m):
                if (neighbours[i] >> j) & 1:
                    count += _subset_sum(weight, everyone & ~(closed_i | neighbours[j] | (1 << j))) / quiet_i
            contenders[c, members[i]] = count
    return airtime, contenders


@numba.njit(cache=True, nogil=True)
def _subset_sum(weight: np.ndarray, mask: int) -> float:
    """The sum of ``weight`` over the subsets of ``mask`` (a walk over its submasks)."""
    total = 0.0
    subset = mask
    while True:
        total += weight[subset]
        if subset == 0:
            return total
        subset = (subset - 1) & mask


@numba.njit(cache=True, nogil=True)
def independent_set_airtime(graph: np.ndarray, active: np.ndarray, rho: float) -> np.ndarray:
    """:func:`csma_airtime` without the size check (compiled; callable from compiled code)."""
    return contention(graph, active, rho)[0]


@numba.njit(cache=True, nogil=True)
def collision_success(contenders: float, cw_min: int, backoff_stages: int, collision_time_ratio: float
                      ) -> float:
    """Share of an AP's airtime that carries data with ``contenders`` saturated stations (Bianchi 2000).

    With ``W = cw_min + 1`` and ``m = backoff_stages``, the attempt probability per slot ``tau`` and the
    collision probability ``p`` solve ``tau = 2 / (1 + W + p W sum_{i<m} (2p)^i)`` and
    ``p = 1 - (1 - tau)^(n-1)`` (bisection; ``n`` may be fractional); a transmission succeeds with
    ``P_s = n tau (1 - tau)^(n-1) / (1 - (1 - tau)^n)`` and the share is ``P_s / (P_s + (1 - P_s) r)``.
    1 for ``n <= 1`` or ``r = 0``.
    """
    n = contenders
    if n <= 1.0 + 1e-12 or collision_time_ratio == 0.0:
        return 1.0
    window = cw_min + 1.0
    low, high = 0.0, 2.0 / (1.0 + window)  # tau - 2 / (...) rises with tau: negative at 0, >= 0 at the top
    for _ in range(60):
        tau = 0.5 * (low + high)
        p = 1.0 - (1.0 - tau) ** (n - 1.0)
        series = 0.0
        for i in range(backoff_stages):
            series += (2.0 * p) ** i
        if tau - 2.0 / (1.0 + window + p * window * series) < 0.0:
            low = tau
        else:
            high = tau
    tau = 0.5 * (low + high)
    success = n * tau * (1.0 - tau) ** (n - 1.0) / (1.0 - (1.0 - tau) ** n)
    return success / (success + (1.0 - success) * collision_time_ratio)


@numba.njit(cache=True, nogil=True)
def collision_success_shares(contenders: np.ndarray, cw_min: int, backoff_stages: int,
                             collision_time_ratio: float) -> np.ndarray:
    """:func:`collision_success` of every AP of ``(B, K)`` contenders.

    Solved once per run of equal values (the APs of a clique share theirs).
    """
    shares = np.ones(contenders.shape)
    last_n, last_share = 1.0, 1.0
    for c in range(contenders.shape[0]):
        for k in range(contenders.shape[1]):
            n = contenders[c, k]
            if n > 1.0 + 1e-12:
                if n != last_n:
                    last_n, last_share = n, collision_success(n, cw_min, backoff_stages, collision_time_ratio)
                shares[c, k] = last_share
    return shares


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
