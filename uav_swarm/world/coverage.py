"""What a radio model tells about N users and K UAVs: :class:`Coverage` (both propagation models).

Examples:
    >>> import numpy as np
    >>> from uav_swarm.world.radio_config import RadioConfig
    >>> from uav_swarm.world.wifi.coverage import wifi_links
    >>> radio = RadioConfig(propagation="802.11")
    >>> links = wifi_links(np.array([[5.0, 0.0]]), np.zeros(1, np.int64), np.zeros((1, 1, 2)), radio,
    ...                    altitudes_m=np.array([20.0]))
    >>> coverage_of_links(links, 0, radio).mcs.tolist()
    [11]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from uav_swarm.world.radio_config import RadioConfig
from uav_swarm.world.wifi.coverage import WifiLinks

__all__ = ["Coverage", "coverage_of_links"]


@dataclass(frozen=True)
class Coverage:
    """Association, coverage and throughput of N users served by K UAVs.

    Attributes:
        association: (N,) int, index of each user's UAV, -1 without network.
        covered: (N,) bool, the user has network (is associated; 802.11: with MCS 0 or better).
        users_per_uav: (K,) int, users associated with each UAV.
        throughput_mbps: (N,) float, ``capacity / users_per_uav[association]`` (802.11: the station's
            throughput), 0 without network.
        qos_s1: Share of users with network (strategy 1), 0.0 without users.
        qos_s2: Share of users with network and at least ``min_user_rate_mbps`` (strategy 2).
        mean_throughput_mbps: Mean throughput over all users (users without network count as 0).
        in_range: (N,) bool, strongest signal >= ``signal_at_range`` (equals ``covered`` in the paper's model;
            under admission control a user in range of full UAVs only is refused).
        model: Which association ran (:attr:`RadioConfig.association_name`).
        sinr_db: 802.11 only (None in the paper's model): (N,) SINR at the user's AP (its strongest AP if
            none), dB.
        mcs: 802.11 only: (N,) MCS index at the user's AP, -1 without a usable rate.
        rate_mbps: 802.11 only: (N,) PHY rate at the user's AP.
        airtime: 802.11 only: (K,) each AP's airtime share.
        channel: 802.11 only: (K,) each UAV's channel number.
    """

    association: np.ndarray
    covered: np.ndarray
    users_per_uav: np.ndarray
    throughput_mbps: np.ndarray
    qos_s1: float
    qos_s2: float
    mean_throughput_mbps: float
    in_range: np.ndarray
    model: str
    sinr_db: np.ndarray | None = None
    mcs: np.ndarray | None = None
    rate_mbps: np.ndarray | None = None
    airtime: np.ndarray | None = None
    channel: np.ndarray | None = None


def coverage_of_links(links: WifiLinks, world: int, config: RadioConfig) -> Coverage:
    """World ``world``'s :class:`Coverage` from the 802.11 model's output.

    Args:
        links: What :func:`~uav_swarm.world.wifi.coverage.wifi_links` computed.
        world: The world's index.
        config: The radio model (it names the association).

    ``covered`` is "associated with MCS 0 or better", ``throughput_mbps`` each station's 802.11 throughput.
    """
    rows = slice(links.offsets[world], links.offsets[world + 1])
    n_users = int(links.n_users[world])
    return Coverage(
        association=links.association[rows], covered=links.covered[rows],
        users_per_uav=links.users_per_uav[world], throughput_mbps=links.throughput_mbps[rows],
        qos_s1=float(links.qos_s1[world]) if n_users else 0.0,
        qos_s2=float(links.qos_s2[world]) if n_users else 0.0,
        mean_throughput_mbps=float(links.mean_throughput_mbps[world]) if n_users else 0.0,
        in_range=links.in_range[rows], model=config.association_name, sinr_db=links.sinr_db[rows],
        mcs=links.mcs[rows], rate_mbps=links.rate_mbps[rows], airtime=links.airtime[world],
        channel=links.channel[world])
