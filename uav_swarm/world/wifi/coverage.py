"""The 802.11 model over B worlds: association, airtime, SINR, MCS, rates, throughput and QoS.

Order of computation (each step uses only the ones before; docs/radio.md gives every formula):

1. **Powers.** Each user receives each UAV's AP with the air-to-ground loss of its own world's geometry
   (each UAV at its own altitude); the APs receive each other in free space
   (:mod:`uav_swarm.world.wifi.phy`).
2. **Carrier sense.** The carrier-sense graph joins co-channel APs that hear each other
   (:func:`~uav_swarm.world.wifi.airtime.carrier_sense_graph`).
3. **Pass 1, the admission's view.** An AP is *reachable* by a user when that user's SNR reaches MCS 0;
   every AP with a user in reach is taken as active. Airtime (ideal CSMA among them) less what collisions
   with its contenders take (Bianchi), SINR with the active hidden co-channel APs and PHY rate of every
   (user, AP) pair follow. A user is *in range* of an
   AP when that SINR reaches MCS 0.
4. **Association.** Incumbents (``previous``) stay while in range of their AP (with ``rate_admission``:
   strongest first, each while its rate holds, the AP's test below passing with it). The other users,
   strongest received power first (ties: lower row), try their APs in range from the strongest (ties: lower
   index); an AP admits a user when it has room under the station limit and, with ``rate_admission``, when
   every station of the AP, the user included, keeps ``min_user_rate_mbps`` at the pass-1 airtime and rates.
5. **Pass 2, what the stations get.** The active APs are now those with stations; airtime and SINR are
   computed again with them. Each station's MCS and rate come from its SINR at its AP; a station whose
   SINR falls below MCS 0 gets nothing and takes no share. The AP's airtime times its collision-free share,
   ``A``, is split among the others: airtime fairness gives ``A * eff * rate / n`` to each of ``n``,
   throughput fairness gives each ``A * eff / sum(1 / rate)``.

Examples:
    >>> import numpy as np
    >>> from uav_swarm.world.radio_config import RadioConfig
    >>> radio = RadioConfig(propagation="802.11")
    >>> users = np.array([[5.0, 0.0], [30.0, 0.0], [2000.0, 0.0]])
    >>> links = wifi_links(users, np.zeros(3, np.int64), np.zeros((1, 1, 2)), radio,
    ...                    altitudes_m=np.array([20.0]))
    >>> links.association.tolist(), links.mcs.tolist(), links.airtime.round(3).tolist()
    ([0, 0, -1], [11, 9, -1], [[0.968]])
    >>> links.throughput_mbps.round(1).tolist()  # airtime fairness: half the airtime each, at its own rate
    [64.5, 51.6, 0.0]
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numba
import numpy as np

from uav_swarm.world.radio_config import RadioConfig
from uav_swarm.world.wifi.airtime import (
    carrier_sense_graph,
    check_contenders,
    collision_success_shares,
    contention,
    hidden_interferers,
)
from uav_swarm.world.wifi.config import Ieee80211Config
from uav_swarm.world.wifi.phy import (
    ap_pair_power_dbm,
    dbm_to_mw,
    noise_dbm,
    rate_ladder_mbps,
    station_power_mw,
)
from uav_swarm.world.wifi.stations import admit, disturbance_mw, mcs_of
from uav_swarm.world.wifi.tables import WifiTables, load_wifi_tables

__all__ = ["WifiLinks", "wifi_links", "uav_channels", "uav_altitudes_m", "access_points_on",
           "channel_conflicts"]

_NO_SIGNAL = 1e-30
"""The linear SINR reported where a user hears no AP at all (every AP off): -300 dB."""


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
        airtime: (B, K) each AP's airtime share (pass 2, collided transmissions included; 0 for an AP
            without stations).
        collision_free: (B, K) the share of that airtime that carries data (Bianchi; 1 without contenders).
        channel: (B, K) each AP's channel number.
        throughput_per_user_mbps: (B, K) mean throughput of the AP's stations (0 without).
        covered_users: (B,) users covered in each world.
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
    collision_free: np.ndarray
    channel: np.ndarray
    throughput_per_user_mbps: np.ndarray
    covered_users: np.ndarray
    qos_s1: np.ndarray
    qos_s2: np.ndarray
    mean_throughput_mbps: np.ndarray


def uav_channels(channels: np.ndarray | None, n_worlds: int, n_uavs: int, config: RadioConfig) -> np.ndarray:
    """``(B, K)`` int channel plan: ``channels`` ((K,) or (B, K)), or every UAV on the first usable channel.

    Raises:
        ValueError: A shape that is neither, or a channel the config does not allow.
    """
    usable = _constants(config.ieee80211)[-1]
    if channels is None:
        return np.full((n_worlds, n_uavs), usable[0], np.int64)
    plan = np.asarray(channels, dtype=np.int64)
    if plan.shape not in ((n_uavs,), (n_worlds, n_uavs)):
        raise ValueError(f"channels must have shape ({n_uavs},) or ({n_worlds}, {n_uavs}), got {plan.shape}")
    if not (plan[..., None] == usable).any(axis=-1).all():
        wrong = sorted(set(plan.ravel().tolist()) - set(usable.tolist()))
        raise ValueError(f"channels {wrong} are not usable: allowed {usable.tolist()} "
                         "(RadioConfig.ieee80211)")
    return plan if plan.ndim == 2 else np.broadcast_to(plan, (n_worlds, n_uavs))


def access_points_on(enabled: np.ndarray, n_worlds: int, n_uavs: int) -> np.ndarray:
    """``(B, K)`` bool: which UAVs' access points are on, from ``enabled`` ((K,) or (B, K)).

    Raises:
        ValueError: A shape that is neither.
    """
    on = np.asarray(enabled, dtype=bool)
    if on.shape not in ((n_uavs,), (n_worlds, n_uavs)):
        raise ValueError(f"enabled must have shape ({n_uavs},) or ({n_worlds}, {n_uavs}), got {on.shape}")
    return np.broadcast_to(on, (n_worlds, n_uavs))


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
    return heights if heights.ndim == 2 else np.broadcast_to(heights, (n_worlds, n_uavs))


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


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _links(power_mw: np.ndarray, copy_index: np.ndarray, graph: np.ndarray, channels: np.ndarray,
           noise_mw: float, thresholds: np.ndarray, ladder_mbps: np.ndarray, rho: float, weighting: float,
           collisions: tuple[int, int, float], efficiency: float, min_rate_mbps: float, airtime_fair: bool,
           rate_admission: bool, station_limit: int, previous: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                      np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Steps 3-5 of the module docstring for all worlds (powers and carrier-sense graph given).

    ``collisions``: the tables' ``(cw_min, backoff_stages, collision_time_ratio)``. Returns per user:
    association, in range, SINR (linear), MCS, rate, throughput; per AP: stations, airtime, collision-free
    share, mean throughput of its stations; per world: users covered, users covered with the minimum rate,
    total throughput.
    """
    cw_min, stages, collision_ratio = collisions
    n_users, n_uavs = power_mw.shape
    n_worlds = graph.shape[0]
    # 3. Pass 1: the APs some user reaches with an SNR of MCS 0 are active. Without hidden interferers a
    # user is in range of the APs it reaches so (its SINR is its SNR); the other worlds' users are tested
    # again once the interferers are known.
    active = np.zeros((n_worlds, n_uavs), np.bool_)
    in_range = np.zeros((n_users, n_uavs), np.bool_)  # the pass-1 SINR reaches MCS 0
    strongest = np.zeros(n_users)  # the strongest received power among the APs in range
    reach_mw = thresholds[0] * noise_mw  # below it no AP is in range, whatever the interference
    for n in range(n_users):
        for k in range(n_uavs):
            if power_mw[n, k] >= reach_mw:
                active[copy_index[n], k] = in_range[n, k] = True
                strongest[n] = max(strongest[n], power_mw[n, k])
    airtime, contenders = contention(graph, active, rho)
    collision_free = collision_success_shares(contenders, cw_min, stages, collision_ratio)
    weights = hidden_interferers(graph, channels, active, airtime, weighting)
    hidden = weights.sum(axis=2).sum(axis=1) > 0.0  # (B,) worlds with hidden interferers
    for n in range(n_users):
        c = copy_index[n]
        if not hidden[c] or strongest[n] == 0.0:
            continue
        strongest[n] = 0.0
        for k in range(n_uavs):
            if in_range[n, k]:
                in_range[n, k] = power_mw[n, k] >= thresholds[0] * disturbance_mw(power_mw, n, k, weights, c,
                                                                                     noise_mw)
                if in_range[n, k]:
                    strongest[n] = max(strongest[n], power_mw[n, k])
    # 4. Association: incumbents, then the others strongest first (a stable sort: the lower row first on
    # ties), world by world (worlds do not interact; each world's rows stay together in memory).
    association, stations = admit(strongest, power_mw, in_range, copy_index, weights, hidden, noise_mw,
                                   thresholds, ladder_mbps, airtime * collision_free, efficiency,
                                   min_rate_mbps, airtime_fair, rate_admission, station_limit, previous)
    # 5. Pass 2: the APs with stations.
    served = stations > 0
    if np.any(served != active):
        airtime, contenders = contention(graph, served, rho)
        collision_free = collision_success_shares(contenders, cw_min, stages, collision_ratio)
        weights = hidden_interferers(graph, channels, served, airtime, weighting)
    sinr = np.zeros(n_users)
    mcs = np.full(n_users, -1, np.int64)
    sharing = np.zeros((n_worlds, n_uavs), np.int64)  # stations with a rate
    inverse_sum = np.zeros((n_worlds, n_uavs))
    for n in range(n_users):
        c = copy_index[n]
        k = association[n]
        if k < 0:  # the SINR at the strongest AP
            k = 0
            for j in range(1, n_uavs):
                if power_mw[n, j] > power_mw[n, k]:
                    k = j
        if n_uavs == 0:
            continue
        sinr[n] = power_mw[n, k] / disturbance_mw(power_mw, n, k, weights, c, noise_mw)
        if association[n] >= 0:
            mcs[n] = mcs_of(sinr[n], thresholds)
            if mcs[n] >= 0:
                sharing[c, k] += 1
                inverse_sum[c, k] += 1.0 / ladder_mbps[mcs[n] + 1]
    rate = np.zeros(n_users)
    throughput = np.zeros(n_users)
    per_ap = np.zeros((n_worlds, n_uavs))
    covered = np.zeros(n_worlds, np.int64)
    fast = np.zeros(n_worlds, np.int64)
    total_mbps = np.zeros(n_worlds)
    for n in range(n_users):
        if mcs[n] < 0:
            continue
        c, k = copy_index[n], association[n]
        rate[n] = ladder_mbps[mcs[n] + 1]
        useful = airtime[c, k] * collision_free[c, k]
        if airtime_fair:
            throughput[n] = useful * efficiency * rate[n] / sharing[c, k]
        else:
            throughput[n] = useful * efficiency / inverse_sum[c, k]
        per_ap[c, k] += throughput[n]
        total_mbps[c] += throughput[n]
        covered[c] += 1
        fast[c] += throughput[n] >= min_rate_mbps
    for c in range(n_worlds):
        for k in range(n_uavs):
            if not served[c, k]:
                airtime[c, k] = 0.0
                collision_free[c, k] = 1.0
            elif sharing[c, k]:
                per_ap[c, k] /= sharing[c, k]
    in_range_any = np.zeros(n_users, np.bool_)
    for n in range(n_users):
        in_range_any[n] = strongest[n] > 0.0
    return (association, in_range_any, sinr, mcs, rate, throughput, stations, airtime, collision_free, per_ap,
            covered, fast, total_mbps)


@functools.lru_cache(maxsize=16)
def _constants(wifi: Ieee80211Config) -> tuple[WifiTables, float, np.ndarray, np.ndarray, float, np.ndarray]:
    """The tables, noise (mW), linear SINR thresholds, rate ladder, MAC efficiency and usable channels."""
    tables = load_wifi_tables(wifi.tables_file)
    efficiency = wifi.mac_efficiency if wifi.mac_efficiency is not None else tables.mac_efficiency
    return (tables, float(dbm_to_mw(noise_dbm(wifi))), dbm_to_mw(tables.min_sinr_db),
            rate_ladder_mbps(wifi, tables), efficiency, np.array(wifi.usable_channels, np.int64))


def wifi_links(users_m: np.ndarray, copy_index: np.ndarray, uavs_m: np.ndarray, config: RadioConfig,
               altitudes_m: np.ndarray | None = None, channels: np.ndarray | None = None,
               previous: np.ndarray | None = None, enabled: np.ndarray | None = None) -> WifiLinks:
    """The 802.11 model (module docstring) for the users of B worlds.

    Args:
        users_m: (N, 2) user positions of all worlds, stacked world by world, metres.
        copy_index: (N,) int, each user's world (non-decreasing).
        uavs_m: (B, K, 2) UAV positions, metres.
        config: The radio model (``config.ieee80211`` and ``min_user_rate_mbps``, ``station_limit``).
        altitudes_m: (K,) or (B, K) height of each UAV above the users; None: ``config.altitude_m``.
        channels: (K,) or (B, K) channel number of each UAV; None: all on the first usable channel.
        previous: (N,) each user's UAV at the last update (incumbents), -1 for none; None: no incumbents.
        enabled: (K,) or (B, K) bool, the UAVs whose access point is on; an AP that is off transmits nothing
            (no user hears it, no AP senses it). None: every AP on.

    Raises:
        ValueError: A shape or a channel the model does not take (the message names it).
    """
    wifi = config.ieee80211
    tables, noise_mw, thresholds, ladder, efficiency, _ = _constants(wifi)
    users_m = np.ascontiguousarray(users_m, dtype=np.float64).reshape(-1, 2)
    copy_index = np.ascontiguousarray(copy_index, dtype=np.int64)
    uavs_m = np.ascontiguousarray(uavs_m, dtype=np.float64)
    n_worlds, n_uavs = uavs_m.shape[0], uavs_m.shape[1]
    n_all = len(users_m)
    before = np.full(n_all, -1, np.int64) if previous is None else np.asarray(previous, np.int64)
    if before.shape != (n_all,):
        raise ValueError(f"previous must have shape ({n_all},), got {before.shape}")
    check_contenders(n_uavs)
    heights = np.ascontiguousarray(uav_altitudes_m(altitudes_m, n_worlds, n_uavs, config))
    plan = np.ascontiguousarray(uav_channels(channels, n_worlds, n_uavs, config))
    offsets = np.searchsorted(copy_index, np.arange(n_worlds + 1)) if n_worlds > 1 else np.array([0, n_all])
    n_users = np.diff(offsets)
    # 1-2. Powers, (N, K) user from AP in mW; the carrier-sense graph.
    power_mw = station_power_mw(users_m, copy_index, uavs_m, heights, wifi)
    ap_power_dbm = ap_pair_power_dbm(uavs_m, heights, wifi)
    if enabled is not None:
        on = access_points_on(enabled, n_worlds, n_uavs)
        power_mw = np.where(on[copy_index], power_mw, 0.0)
        ap_power_dbm = np.where(on[:, :, None] & on[:, None, :], ap_power_dbm, -np.inf)
    graph = carrier_sense_graph(ap_power_dbm, plan, wifi.cca_threshold_dbm)
    # 3-5. Passes and association.
    (association, in_range, sinr, mcs, rate, throughput, stations, airtime, collision_free, per_ap, covered,
     fast, total) = _links(
        power_mw, copy_index, graph, plan, noise_mw, thresholds, ladder, tables.access_intensity,
        tables.interference_airtime_weighting,
        (tables.cw_min, tables.backoff_stages, tables.collision_time_ratio), efficiency,
        config.min_user_rate_mbps, wifi.fairness == "airtime", wifi.admits_on_rate, config.max_stations or 0,
        before)
    denominator = np.maximum(n_users, 1)
    return WifiLinks(
        association=association, covered=mcs >= 0, in_range=in_range,
        sinr_db=10.0 * np.log10(np.maximum(sinr, _NO_SIGNAL)), mcs=mcs,
        rate_mbps=rate, throughput_mbps=throughput, offsets=offsets, n_users=n_users, users_per_uav=stations,
        airtime=airtime, collision_free=collision_free, channel=plan, throughput_per_user_mbps=per_ap,
        covered_users=covered, qos_s1=covered / denominator, qos_s2=fast / denominator,
        mean_throughput_mbps=total / denominator)
