"""Step 4 of the 802.11 model: which AP each user joins (docs/radio.md, the association).

Incumbents stay on their AP while in range (with admission on rate: strongest first, each while its rate
holds, the AP's test passing with it); the other users, strongest received power first (ties: the lower
row), try their APs in range from the strongest (ties: the lower index), and an AP admits a user
when it has room under the station limit and, with admission on rate, when every station of the AP, the
user included, keeps the minimum rate at the pass-1 airtime and rates. All worlds at once (compiled;
:func:`~uav_swarm.world.wifi.coverage.wifi_links` calls it).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["admit", "disturbance_mw", "mcs_of"]


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def mcs_of(sinr: float, thresholds: np.ndarray) -> int:
    """The highest MCS whose (linear, non-decreasing) threshold ``sinr`` reaches, -1 below MCS 0."""
    best = -1
    for m in range(thresholds.size):
        if sinr < thresholds[m]:
            break
        best = m
    return best


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def disturbance_mw(power_mw: np.ndarray, n: int, k: int, weights: np.ndarray, c: int, noise_mw: float
                    ) -> float:
    """Noise plus the weighted hidden interferers at user ``n`` (world ``c``) for AP ``k`` (mW)."""
    total = noise_mw
    for j in range(power_mw.shape[1]):
        if weights[c, k, j] > 0.0:
            total += weights[c, k, j] * power_mw[n, j]
    return total


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _pair_rate_mbps(power_mw: np.ndarray, n: int, k: int, weights: np.ndarray, c: int, hidden: np.ndarray,
                    noise_mw: float, thresholds: np.ndarray, ladder_mbps: np.ndarray) -> float:
    """PHY rate of user ``n`` (world ``c``) at AP ``k`` from its SINR (0 below MCS 0)."""
    interfered_mw = disturbance_mw(power_mw, n, k, weights, c, noise_mw) if hidden[c] else noise_mw
    return ladder_mbps[mcs_of(power_mw[n, k] / interfered_mw, thresholds) + 1]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _strongest_first(chosen: np.ndarray, strongest: np.ndarray, copy_index: np.ndarray) -> np.ndarray:
    """The ``chosen`` users, strongest first world by world (ties: lower row).

    A stable sort of each world's chosen users: the order of a stable sort of all its users, the others left
    out.
    """
    rows = np.flatnonzero(chosen)
    first = 0
    for i in range(1, rows.size + 1):
        if i == rows.size or copy_index[rows[i]] != copy_index[rows[first]]:
            world = rows[first:i]
            rows[first:i] = world[np.argsort(-strongest[world], kind="mergesort")]
            first = i
    return rows


@numba.njit(cache=True, nogil=True, error_model="numpy")
def admit(strongest: np.ndarray, power_mw: np.ndarray, in_range: np.ndarray, copy_index: np.ndarray,
           weights: np.ndarray, hidden: np.ndarray, noise_mw: float, thresholds: np.ndarray,
           ladder_mbps: np.ndarray, airtime: np.ndarray, efficiency: float, min_rate_mbps: float,
           airtime_fair: bool, rate_admission: bool, station_limit: int, previous: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray]:
    """Step 4: incumbents, then newcomers, at the pass-1 airtime and rates; ``airtime`` (B, K); limit 0: none.

    ``strongest``: (N,) each user's strongest received power among its APs in range (0: none in range).
    An AP is *closed* once no newcomer could pass its test (even at the top rate): skipping it changes
    nothing.
    """
    n_users, n_uavs = in_range.shape
    top_rate_mbps = ladder_mbps[-1]
    association = np.full(n_users, -1, np.int64)
    count = np.zeros(airtime.shape, np.int64)
    slowest = np.full(airtime.shape, np.inf)
    inverse_sum = np.zeros(airtime.shape)
    closed = np.zeros(airtime.shape, np.bool_)

    incumbent = np.zeros(n_users, np.bool_)
    for row in range(n_users):
        incumbent[row] = 0 <= previous[row] < n_uavs and in_range[row, previous[row]]
    # The incumbents first, whatever the station limit; with admission on rate, strongest first and each
    # only while its rate holds (the AP's test passes with it), else it is a newcomer again.
    order: np.ndarray = np.flatnonzero(incumbent)
    if rate_admission:
        order = _strongest_first(incumbent, strongest, copy_index)
    for n in order:
        k = previous[n]
        c = copy_index[n]
        rate = _pair_rate_mbps(power_mw, n, k, weights, c, hidden, noise_mw, thresholds, ladder_mbps)
        if rate_admission and _share_mbps(count[c, k], slowest[c, k], inverse_sum[c, k], airtime[c, k], rate,
                                          efficiency, airtime_fair) < min_rate_mbps:
            continue
        association[n] = k
        count[c, k] += 1
        slowest[c, k] = min(slowest[c, k], rate)
        inverse_sum[c, k] += 1.0 / rate
    rule = (efficiency, top_rate_mbps, min_rate_mbps, airtime_fair, rate_admission, station_limit)
    for c in range(airtime.shape[0]):
        for k in range(n_uavs):
            closed[c, k] = _closed(count[c, k], slowest[c, k], inverse_sum[c, k], airtime[c, k], rule)
    tried = np.zeros(n_uavs, np.bool_)
    for n in _strongest_first((association < 0) & (strongest > 0.0), strongest, copy_index):
        c = copy_index[n]
        tried[:] = False
        while True:  # the strongest AP in range not tried yet (ties: the lower index)
            k = -1
            for j in range(n_uavs):
                if not tried[j] and not closed[c, j] and in_range[n, j] \
                        and (k < 0 or power_mw[n, j] > power_mw[n, k]):
                    k = j
            if k < 0:
                break
            tried[k] = True
            rate = _pair_rate_mbps(power_mw, n, k, weights, c, hidden, noise_mw, thresholds, ladder_mbps)
            if rate_admission and _share_mbps(count[c, k], slowest[c, k], inverse_sum[c, k], airtime[c, k],
                                              rate, efficiency, airtime_fair) < min_rate_mbps:
                continue
            association[n] = k
            count[c, k] += 1
            slowest[c, k] = min(slowest[c, k], rate)
            inverse_sum[c, k] += 1.0 / rate
            closed[c, k] = _closed(count[c, k], slowest[c, k], inverse_sum[c, k], airtime[c, k], rule)
            break
    return association, count


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _share_mbps(stations: int, slowest_mbps: float, inverse_sum: float, airtime: float, rate_mbps: float,
                efficiency: float, airtime_fair: bool) -> float:
    """The least throughput of an AP's stations with one more at ``rate_mbps`` (the admission's test)."""
    if airtime_fair:
        return airtime * efficiency * min(slowest_mbps, rate_mbps) / (stations + 1)
    return airtime * efficiency / (inverse_sum + 1.0 / rate_mbps)


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _closed(stations: int, slowest_mbps: float, inverse_sum: float, airtime: float,
            rule: tuple[float, float, float, bool, bool, int]) -> bool:
    """No newcomer could join an AP with these stations, even at the top rate.

    ``rule``: MAC efficiency, top rate, minimum rate, airtime fairness, admission on rate, station limit.
    """
    efficiency, top_rate_mbps, min_rate_mbps, airtime_fair, rate_admission, station_limit = rule
    if station_limit > 0 and stations >= station_limit:
        return True
    best = _share_mbps(stations, slowest_mbps, inverse_sum, airtime, top_rate_mbps, efficiency, airtime_fair)
    return rate_admission and best < min_rate_mbps
