"""The 802.11 model over B worlds: association, airtime, SINR, MCS, rates, throughput and QoS.

Order of computation (each step uses only the ones before; docs/radio.md gives every formula):

1. **Powers.** Each user receives each UAV's AP with the air-to-ground loss of its own world's geometry
   (each UAV at its own altitude); the APs receive each other in free space
   (:mod:`uav_swarm.world.wifi_phy`).
2. **Carrier sense.** The carrier-sense graph joins co-channel APs that hear each other
   (:func:`~uav_swarm.world.wifi_airtime.carrier_sense_graph`).
3. **Pass 1, the admission's view.** An AP is *reachable* by a user when that user's SNR reaches MCS 0;
   every AP with a user in reach is taken as active. Airtime (ideal CSMA among them), SINR with the
   active hidden co-channel APs and PHY rate of every (user, AP) pair follow. A user is *in range* of an
   AP when that SINR reaches MCS 0.
4. **Association.** Incumbents (``previous``) stay while in range of their AP. The other users, strongest
   received power first (ties: lower row), try their APs in range from the strongest (ties: lower index);
   an AP admits a user when it has room under the station limit and, with ``rate_admission``, when every
   station of the AP, the user included, keeps ``min_user_rate_mbps`` at the pass-1 airtime and rates.
5. **Pass 2, what the stations get.** The active APs are now those with stations; airtime and SINR are
   computed again with them. Each station's MCS and rate come from its SINR at its AP; a station whose
   SINR falls below MCS 0 gets nothing and takes no share. The AP's airtime ``A`` is split among the
   others: airtime fairness gives ``A * eff * rate / n`` to each of ``n``, throughput fairness gives each
   ``A * eff / sum(1 / rate)``.

Examples:
    >>> import numpy as np
    >>> from uav_swarm.world.radio_config import RadioConfig
    >>> radio = RadioConfig(propagation="802.11")
    >>> users = np.array([[5.0, 0.0], [30.0, 0.0], [2000.0, 0.0]])
    >>> links = wifi_links(users, np.zeros(3, np.int64), np.zeros((1, 1, 2)), radio,
    ...                    altitudes_m=np.array([20.0]))
    >>> links.association.tolist(), links.mcs.tolist(), links.airtime.round(3).tolist()
    ([0, 0, -1], [11, 9, -1], [[0.998]])
    >>> links.throughput_mbps.round(1).tolist()  # airtime fairness: half the airtime each, at its own rate
    [62.6, 50.1, 0.0]
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from uav_swarm.world.radio_config import RadioConfig
from uav_swarm.world.wifi_airtime import carrier_sense_graph, csma_airtime, hidden_interferers
from uav_swarm.world.wifi_phy import (
    ap_pair_power_dbm,
    dbm_to_mw,
    mcs_index,
    noise_dbm,
    phy_rate_mbps,
    station_power_dbm,
)
from uav_swarm.world.wifi_tables import load_wifi_tables

__all__ = ["WifiLinks", "wifi_links", "uav_channels", "uav_altitudes_m", "channel_conflicts"]


@dataclass(frozen=True)
class WifiLinks:
    """What the 802.11 model computed for B worlds (per-user arrays stacked world by world).

    Attributes:
        association: (N,) each user's UAV within its world, -1 without one.
        covered: (N,) associated with an MCS (MCS 0 or better) at its AP.
        in_range: (N,) some AP's pass-1 SINR reaches MCS 0.
        sinr_db: (N,) SINR at the user's AP (its strongest AP when not associated), dB.
        mcs: (N,) MCS index at its AP, -1 without a usable rate.
        rate_mbps: (N,) PHY rate at its AP (0 without).
        throughput_mbps: (N,) the user's throughput.
        offsets: (B + 1,) world ``c``'s users are ``offsets[c]:offsets[c + 1]``.
        n_users: (B,) users of each world.
        users_per_uav: (B, K) stations of each AP.
        airtime: (B, K) each AP's airtime share (pass 2; 0 for an AP without stations).
        channel: (B, K) each AP's channel number.
        throughput_per_user_mbps: (B, K) mean throughput of the AP's stations (0 without).
        qos_s1: (B,) share of the world's users covered.
        qos_s2: (B,) share covered with at least ``min_user_rate_mbps``.
        mean_throughput_mbps: (B,) mean throughput over the world's users.
    """

    association: np.ndarray
    covered: np.ndarray
    in_range: np.ndarray
    sinr_db: np.ndarray
    mcs: np.ndarray
    rate_mbps: np.ndarray
    throughput_mbps: np.ndarray
    offsets: np.ndarray
    n_users: np.ndarray
    users_per_uav: np.ndarray
    airtime: np.ndarray
    channel: np.ndarray
    throughput_per_user_mbps: np.ndarray
    qos_s1: np.ndarray
    qos_s2: np.ndarray
    mean_throughput_mbps: np.ndarray


def uav_channels(channels: np.ndarray | None, n_worlds: int, n_uavs: int, config: RadioConfig) -> np.ndarray:
    """``(B, K)`` int channel plan: ``channels`` ((K,) or (B, K)), or every UAV on the first usable channel.

    Raises:
        ValueError: A shape that is neither, or a channel the config does not allow.
    """
    usable = config.ieee80211.usable_channels
    if channels is None:
        return np.full((n_worlds, n_uavs), usable[0], np.int64)
    plan = np.asarray(channels, dtype=np.int64)
    if plan.shape not in ((n_uavs,), (n_worlds, n_uavs)):
        raise ValueError(f"channels must have shape ({n_uavs},) or ({n_worlds}, {n_uavs}), got {plan.shape}")
    wrong = sorted(set(np.unique(plan).tolist()) - set(usable))
    if wrong:
        raise ValueError(f"channels {wrong} are not usable: allowed {list(usable)} (RadioConfig.ieee80211)")
    return np.broadcast_to(plan, (n_worlds, n_uavs))


def uav_altitudes_m(altitudes_m: np.ndarray | None, n_worlds: int, n_uavs: int, config: RadioConfig
                    ) -> np.ndarray:
    """``(B, K)`` height of each UAV above the users: ``altitudes_m`` ((K,) or (B, K)), else the config's.

    Raises:
        ValueError: A shape that is neither, or no altitude at all (None and ``config.altitude_m = 0``).
    """
    if altitudes_m is None:
        if config.altitude_m <= 0.0:
            raise ValueError("the 802.11 model needs the UAVs' altitudes: pass altitudes_m (each UAV's "
                             "height above the users) or set RadioConfig.altitude_m")
        return np.full((n_worlds, n_uavs), config.altitude_m)
    heights = np.asarray(altitudes_m, dtype=np.float64)
    if heights.shape not in ((n_uavs,), (n_worlds, n_uavs)):
        raise ValueError(f"altitudes_m must have shape ({n_uavs},) or ({n_worlds}, {n_uavs}), "
                         f"got {heights.shape}")
    return np.broadcast_to(heights, (n_worlds, n_uavs))


def channel_conflicts(uavs_m: np.ndarray, config: RadioConfig, altitudes_m: np.ndarray | None = None
                      ) -> tuple[np.ndarray, np.ndarray]:
    """What a channel plan must separate: which APs would hear each other on one channel, and how loud.

    Args:
        uavs_m: (B, K, 2) UAV positions, metres.
        config: The radio model (``config.ieee80211``).
        altitudes_m: (K,) or (B, K) each UAV's altitude; None: ``config.altitude_m``.

    Returns:
        ``(power_dbm, conflict)``: (B, K, K) power AP ``i`` receives from AP ``j``, and (B, K, K) bool,
        ``i != j`` and that power reaches the carrier-sense threshold (on one channel they share airtime).
    """
    uavs_m = np.asarray(uavs_m, dtype=np.float64)
    n_worlds, n_uavs = uavs_m.shape[0], uavs_m.shape[1]
    power_dbm = ap_pair_power_dbm(uavs_m, uav_altitudes_m(altitudes_m, n_worlds, n_uavs, config),
                                  config.ieee80211)
    same = np.zeros((n_worlds, n_uavs), np.int64)
    return power_dbm, carrier_sense_graph(power_dbm, same, config.ieee80211.cca_threshold_dbm)


def _sinr_db(rx_mw: np.ndarray, copy_index: np.ndarray, weights: np.ndarray, noise_mw: float) -> np.ndarray:
    """(N, K) SINR of every (user, AP) pair with the weighted hidden interferers of ``weights`` (B, K, J)."""
    interference = np.full(rx_mw.shape, noise_mw)
    if weights.any():
        for j in range(rx_mw.shape[1]):
            interference += rx_mw[:, j, None] * weights[copy_index, :, j]
    return 10.0 * np.log10(rx_mw / interference)


@numba.njit(cache=True, nogil=True)
def _admit(user_order: np.ndarray, ap_order: np.ndarray, in_range: np.ndarray, rate_mbps: np.ndarray,
           copy_index: np.ndarray, airtime: np.ndarray, efficiency: float, min_rate_mbps: float,
           airtime_fair: bool, rate_admission: bool, station_limit: int, previous: np.ndarray) -> np.ndarray:
    """Step 4 of the module docstring; ``airtime`` is (B * K,), ``station_limit`` 0 for none."""
    n_users, n_uavs = in_range.shape
    association = np.full(n_users, -1, np.int64)
    count = np.zeros(airtime.size, np.int64)
    slowest = np.full(airtime.size, np.inf)
    inverse_sum = np.zeros(airtime.size)
    for n in range(n_users):
        k = previous[n]
        if 0 <= k < n_uavs and in_range[n, k]:
            slot = copy_index[n] * n_uavs + k
            association[n] = k
            count[slot] += 1
            slowest[slot] = min(slowest[slot], rate_mbps[n, k])
            inverse_sum[slot] += 1.0 / rate_mbps[n, k]
    for n in user_order:
        if association[n] >= 0:
            continue
        for j in range(n_uavs):
            k = ap_order[n, j]
            if not in_range[n, k]:
                continue
            slot = copy_index[n] * n_uavs + k
            if station_limit > 0 and count[slot] >= station_limit:
                continue
            rate = rate_mbps[n, k]
            if rate_admission:
                if airtime_fair:
                    share = airtime[slot] * efficiency * min(slowest[slot], rate) / (count[slot] + 1)
                else:
                    share = airtime[slot] * efficiency / (inverse_sum[slot] + 1.0 / rate)
                if share < min_rate_mbps:
                    continue
            association[n] = k
            count[slot] += 1
            slowest[slot] = min(slowest[slot], rate)
            inverse_sum[slot] += 1.0 / rate
            break
    return association


def wifi_links(users_m: np.ndarray, copy_index: np.ndarray, uavs_m: np.ndarray, config: RadioConfig,
               altitudes_m: np.ndarray | None = None, channels: np.ndarray | None = None,
               previous: np.ndarray | None = None) -> WifiLinks:
    """The 802.11 model (module docstring) for the users of B worlds.

    Args:
        users_m: (N, 2) user positions of all worlds, stacked world by world, metres.
        copy_index: (N,) int, each user's world (non-decreasing).
        uavs_m: (B, K, 2) UAV positions, metres.
        config: The radio model (``config.ieee80211`` and ``min_user_rate_mbps``, ``station_limit``).
        altitudes_m: (K,) or (B, K) height of each UAV above the users; None: ``config.altitude_m``.
        channels: (K,) or (B, K) channel number of each UAV; None: all on the first usable channel.
        previous: (N,) each user's UAV at the last update (incumbents), -1 for none; None: no incumbents.

    Raises:
        ValueError: A shape or a channel the model does not take (the message names it).
    """
    wifi = config.ieee80211
    tables = load_wifi_tables(wifi.tables_file)
    efficiency = wifi.mac_efficiency if wifi.mac_efficiency is not None else tables.mac_efficiency
    users_m = np.asarray(users_m, dtype=np.float64).reshape(-1, 2)
    copy_index = np.asarray(copy_index, dtype=np.int64)
    uavs_m = np.asarray(uavs_m, dtype=np.float64)
    n_worlds, n_uavs = uavs_m.shape[0], uavs_m.shape[1]
    n_all = len(users_m)
    heights = uav_altitudes_m(altitudes_m, n_worlds, n_uavs, config)
    plan = uav_channels(channels, n_worlds, n_uavs, config)
    offsets = np.searchsorted(copy_index, np.arange(n_worlds + 1))
    n_users = np.diff(offsets)
    # 1. Powers: (N, K) user from AP, (B, K, K) AP from AP.
    rx_dbm = station_power_dbm(np.hypot(uavs_m[copy_index, :, 0] - users_m[:, 0:1],
                                        uavs_m[copy_index, :, 1] - users_m[:, 1:2]),
                               heights[copy_index], wifi)
    rx_mw = dbm_to_mw(rx_dbm)
    ap_dbm = ap_pair_power_dbm(uavs_m, heights, wifi)
    # 2. Carrier sense.
    graph = carrier_sense_graph(ap_dbm, plan, wifi.cca_threshold_dbm)
    noise = noise_dbm(wifi)
    noise_mw = float(dbm_to_mw(noise))
    weighting = tables.interference_airtime_weighting

    def radio_state(active: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        airtime = csma_airtime(graph, active, tables.access_intensity)
        weights = hidden_interferers(graph, plan, active, airtime, weighting)
        return airtime, _sinr_db(rx_mw, copy_index, weights, noise_mw)

    # 3. Pass 1: every AP with a user whose SNR reaches MCS 0 is active.
    reach = (rx_dbm - noise) >= tables.min_sinr_db[0]
    slots = (copy_index[:, None] * n_uavs + np.arange(n_uavs)).ravel()
    active = (np.bincount(slots[reach.ravel()], minlength=n_worlds * n_uavs) > 0).reshape(n_worlds, n_uavs)
    airtime, sinr = radio_state(active)
    rate_pairs = phy_rate_mbps(mcs_index(sinr, tables), wifi, tables)  # (N, K)
    in_range_pairs = rate_pairs > 0.0
    # 4. Association.
    best_rx = np.where(in_range_pairs, rx_dbm, -np.inf).max(axis=1, initial=-np.inf)
    user_order = np.lexsort((np.arange(n_all), -best_rx))
    ap_order = np.argsort(-rx_dbm, axis=1, kind="stable")
    limit = config.max_stations or 0
    before = np.full(n_all, -1, np.int64) if previous is None else np.asarray(previous, np.int64)
    if before.shape != (n_all,):
        raise ValueError(f"previous must have shape ({n_all},), got {before.shape}")
    association = _admit(user_order, ap_order, in_range_pairs, rate_pairs, copy_index, airtime.ravel(),
                         efficiency, config.min_user_rate_mbps, wifi.fairness == "airtime",
                         wifi.rate_admission, limit, before)
    # 5. Pass 2 with the APs that serve someone.
    linked = association >= 0
    serving = np.where(linked, association, rx_dbm.argmax(axis=1) if n_uavs else 0)
    slot = copy_index * n_uavs + serving
    stations = np.bincount(slot[linked], minlength=n_worlds * n_uavs)
    served = stations.reshape(n_worlds, n_uavs) > 0
    if not np.array_equal(served, active):
        airtime, sinr = radio_state(served)
    rows = np.arange(n_all)
    sinr_db = sinr[rows, serving] if n_uavs else np.full(n_all, -np.inf)
    mcs = np.where(linked, mcs_index(sinr_db, tables), -1)
    rate = phy_rate_mbps(mcs, wifi, tables)
    covered = mcs >= 0
    share_of = np.bincount(slot[covered], minlength=n_worlds * n_uavs)
    inverse = np.bincount(slot[covered], weights=1.0 / rate[covered], minlength=n_worlds * n_uavs)
    ap_airtime = airtime.ravel()[slot]
    if wifi.fairness == "airtime":
        throughput = ap_airtime * efficiency * rate / np.maximum(share_of[slot], 1)
    else:
        throughput = ap_airtime * efficiency / np.where(covered, inverse[slot], 1.0)
    throughput = np.where(covered, throughput, 0.0)
    fast = covered & (throughput >= config.min_user_rate_mbps)
    denominator = np.maximum(n_users, 1)
    per_ap = np.bincount(slot[covered], weights=throughput[covered], minlength=n_worlds * n_uavs)
    return WifiLinks(
        association=association, covered=covered, in_range=np.asarray(in_range_pairs.any(axis=1)),
        sinr_db=sinr_db, mcs=mcs, rate_mbps=rate, throughput_mbps=throughput, offsets=offsets,
        n_users=n_users,
        users_per_uav=stations.reshape(n_worlds, n_uavs), airtime=np.where(served, airtime, 0.0),
        channel=np.array(plan),
        throughput_per_user_mbps=(per_ap / np.maximum(share_of, 1)).reshape(n_worlds, n_uavs),
        qos_s1=np.bincount(copy_index[covered], minlength=n_worlds) / denominator,
        qos_s2=np.bincount(copy_index[fast], minlength=n_worlds) / denominator,
        mean_throughput_mbps=np.bincount(copy_index, weights=throughput, minlength=n_worlds) / denominator)
