"""What a run reports of the 802.11 radio: channels, SINR and MCS of the users, airtime, co-channel sharing.

Under ``RadioConfig.propagation = "802.11"`` a run keeps, after every step, from the coverage the
environment computed (:class:`uav_swarm.world.coverage.Coverage`):

- each UAV's **channel** (the channel plan in force, :func:`uav_swarm.world.wifi.channels.plan_channels`);
- the users' **SINR and MCS**: the median SINR over all users (each at its AP, or its strongest AP when it
  has none) and the share of users in each MCS band of :data:`MCS_BANDS` (``not served``: no AP took
  the user, or no usable MCS at its AP);
- each UAV's **airtime** share;
- the **co-channel pairs sharing airtime**: two UAVs on one channel that hear each other above the
  carrier-sense threshold (:func:`uav_swarm.world.wifi.coverage.channel_conflicts`), so that their access
  points take turns on the medium;
- where each user stands against the **rate bar** (``min_user_rate_mbps``, 5 Mbps by default), the shares of
  :data:`SERVICE_CLASSES`: out of range of every AP, in range but refused (with admission on rate: no AP in
  range could take one more station with every station keeping the bar), served below the bar, served at
  the bar or above. QoS S1 counts the last two, QoS S2 the last one: their difference, and the refused users
  that an admission on rate leaves out of QoS S1 too, say why a strategy-2 run's QoS is lower than
  strategy 1's (:func:`admission_line`).

:func:`radio_summary` turns a :class:`RadioTrace` into ``summary.json``'s ``radio`` table, and
:func:`radio_line` names the radio that ran, for the printed table.

Examples:
    >>> mcs_band_shares(np.array([-1, 0, 5, 11, 11]))
    array([0.2, 0.2, 0.2, 0.4])
    >>> from uav_swarm.world.radio_config import RadioConfig
    >>> radio_line(RadioConfig())
    "radio: the paper's (Gaussian signal to 30 m, 200 Mbps per UAV shared equally)"
    >>> service_class_shares(np.array([False, True, True, True]), np.array([-1, -1, 0, 1]),
    ...                      np.array([0.0, 0.0, 2.0, 9.0]), 5.0).tolist()
    [0.25, 0.25, 0.25, 0.25]
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from uav_swarm.world.coverage import Coverage
from uav_swarm.world.radio_config import RadioConfig
from uav_swarm.world.wifi.coverage import channel_conflicts

__all__ = ["MCS_BANDS", "SERVICE_CLASSES", "SERVICE_COLOURS", "RadioTrace", "RadioLog", "mcs_band_shares",
           "median_sinr_db", "service_class_shares", "sharing_pairs", "radio_summary", "radio_line",
           "admission_line", "telemetry_fields", "Service", "uav_service", "service_label", "service_rgb"]

MCS_BANDS: tuple[tuple[str, int, int], ...] = (("not served", -1, -1), ("MCS 0-3", 0, 3), ("MCS 4-7", 4, 7),
                                                ("MCS 8-11", 8, 11))
"""``(name, lowest, highest)`` MCS index of each band a report counts users in (-1: not served)."""

SERVICE_CLASSES: tuple[str, ...] = ("out of range", "refused", "below the rate bar", "at the rate bar")
"""Where a user stands against the rate bar (module docstring), in :func:`service_class_shares` order."""

SERVICE_COLOURS: tuple[str, ...] = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b",
                                    "#e377c2", "#bcbd22", "#17becf", "#393b79")
"""The colour of UAV ``k`` and of the users it serves in the pictures of an 802.11 run (``k % 10``)."""

Service = tuple[int, int | None, np.ndarray | None]
"""A UAV's service under the 802.11 radio: its id, its channel and the ``(M, 2)`` users it serves (None:
unknown)."""


def uav_service(states: Sequence[Any], pedestrians_m: np.ndarray, covered: np.ndarray,
                association: np.ndarray | None) -> list[Service] | None:
    """Each UAV's channel and the users it serves, as a recording and ROS 2 draw them (``simulate``, ``fly``).

    Args:
        states: The UAVs drawn (telemetry ``UavState``; under the 802.11 radio each carries ``wifi_channel``).
        pedestrians_m: ``(N, 2)`` the users.
        covered: ``(N,)`` True for a user a UAV serves.
        association: ``(N,)`` each user's UAV id (-1: none), or None when not known (no users drawn then).

    Returns:
        One :data:`Service` per state, in their order; None under the paper's radio (no state has a channel).

    Examples:
        >>> from types import SimpleNamespace as State
        >>> users = np.array([[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]])
        >>> service = uav_service([State(uav_id=0, wifi_channel=36), State(uav_id=1, wifi_channel=40)],
        ...                       users, np.array([True, True, False]), np.array([1, 1, 0]))
        >>> [service_label(*uav) for uav in service]
        ['UAV 0, ch 36, 0 users', 'UAV 1, ch 40, 2 users']
    """
    if not any(s.wifi_channel is not None for s in states):
        return None
    users = np.asarray(pedestrians_m, np.float64).reshape(-1, 2)
    uav_of = None if association is None else np.where(np.asarray(covered, bool), association, -1)
    return [(s.uav_id, s.wifi_channel, None if uav_of is None else users[uav_of == s.uav_id]) for s in states]


def service_label(uav_id: int, channel: int | None, users_m: np.ndarray | None) -> str:
    """A UAV's label in a recording and in ROS 2: ``UAV 3, ch 40, 52 users`` (the parts known)."""
    on = "" if channel is None else f", ch {channel}"
    count = "" if users_m is None else f", {len(users_m)} users"
    return f"UAV {uav_id}{on}{count}"


def service_rgb(uav_id: int) -> tuple[float, float, float]:
    """UAV ``uav_id``'s colour (:data:`SERVICE_COLOURS`) as red, green and blue in [0, 1]."""
    code = SERVICE_COLOURS[uav_id % len(SERVICE_COLOURS)].lstrip("#")
    red, green, blue = (int(code[i:i + 2], 16) / 255.0 for i in (0, 2, 4))
    return red, green, blue


def mcs_band_shares(mcs: np.ndarray) -> np.ndarray:
    """(len(MCS_BANDS),) share of the users in each band of :data:`MCS_BANDS` (zeros without users)."""
    mcs = np.asarray(mcs)
    if mcs.size == 0:
        return np.zeros(len(MCS_BANDS))
    return np.array([np.count_nonzero((mcs >= low) & (mcs <= high)) / mcs.size for _, low, high in MCS_BANDS])


def service_class_shares(in_range: np.ndarray, association: np.ndarray, throughput_mbps: np.ndarray,
                         rate_bar_mbps: float) -> np.ndarray:
    """(len(SERVICE_CLASSES),) share of the users in each class of :data:`SERVICE_CLASSES` (zeros, no users).

    Args:
        in_range: (N,) some AP's SINR reaches MCS 0 for the user.
        association: (N,) the user's AP, -1 when none took it.
        throughput_mbps: (N,) the user's throughput.
        rate_bar_mbps: The rate strategy 2 counts (``min_user_rate_mbps``).
    """
    n_users = len(association)
    if n_users == 0:
        return np.zeros(len(SERVICE_CLASSES))
    served = np.asarray(association) >= 0
    at_bar = served & (np.asarray(throughput_mbps) >= rate_bar_mbps)
    counts = (np.count_nonzero(~served & ~np.asarray(in_range, bool)),
              np.count_nonzero(~served & np.asarray(in_range, bool)), np.count_nonzero(served & ~at_bar),
              np.count_nonzero(at_bar))
    return np.array(counts, dtype=np.float64) / n_users


def median_sinr_db(sinr_db: np.ndarray) -> float:
    """The median SINR of the users (dB), NaN without users."""
    return float(np.median(sinr_db)) if len(sinr_db) else float("nan")


def sharing_pairs(uavs_m: np.ndarray, channels: np.ndarray, radio: RadioConfig, altitudes_m: np.ndarray,
                  enabled: np.ndarray | None = None) -> np.ndarray:
    """(K, K) bool, upper triangle: UAVs ``i < j`` on one channel that hear each other (sharing airtime).

    ``enabled``: (K,) bool, the UAVs whose access point is on (an AP that is off shares with none).
    """
    _, conflict = channel_conflicts(np.asarray(uavs_m, np.float64)[None], radio, altitudes_m)
    same = channels[:, None] == channels[None, :]
    if enabled is not None:
        on = np.asarray(enabled, dtype=bool)
        same = same & on[:, None] & on[None, :]
    return np.triu(conflict[0] & same, k=1)


@dataclass
class RadioTrace:
    """The 802.11 figures of a run, one row per step (module docstring).

    Attributes:
        channels: (T, K) each UAV's channel.
        median_sinr_db: (T,) the users' median SINR.
        mcs_shares: (T, len(MCS_BANDS)) share of the users in each MCS band.
        airtime: (T, K) each UAV's airtime share.
        sharing: (T, K, K) bool, upper triangle: the co-channel pairs sharing airtime.
        service: (T, len(SERVICE_CLASSES)) share of the users in each class against the rate bar.
        stations: (T, K) each UAV's stations.
    """

    channels: np.ndarray
    median_sinr_db: np.ndarray
    mcs_shares: np.ndarray
    airtime: np.ndarray
    sharing: np.ndarray
    service: np.ndarray
    stations: np.ndarray


@dataclass
class RadioLog:
    """Collects a :class:`RadioTrace` step by step.

    Args:
        radio: The 802.11 radio of the run.
        altitudes_m: (K,) each UAV's altitude.
    """

    radio: RadioConfig
    altitudes_m: np.ndarray
    _rows: list[tuple[np.ndarray, float, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = field(
        default_factory=list)

    def observe(self, coverage: Coverage, uavs_m: np.ndarray, enabled: np.ndarray | None = None) -> None:
        """One step's coverage (802.11: with SINR, MCS, airtime and channels) and the UAVs' positions.

        ``enabled``: (K,) bool, the UAVs whose access point is on; None: all.
        """
        if coverage.sinr_db is None or coverage.mcs is None or coverage.airtime is None \
                or coverage.channel is None:
            raise ValueError(f"the coverage of {coverage.model!r} has no 802.11 figures")
        channels = np.array(coverage.channel, np.int64)
        service = service_class_shares(coverage.in_range, coverage.association, coverage.throughput_mbps,
                                       self.radio.min_user_rate_mbps)
        self._rows.append((channels, median_sinr_db(coverage.sinr_db), mcs_band_shares(coverage.mcs),
                           np.array(coverage.airtime, np.float64),
                           sharing_pairs(uavs_m, channels, self.radio, self.altitudes_m, enabled), service,
                           np.array(coverage.users_per_uav, np.int64)))

    @property
    def latest_pairs(self) -> int | None:
        """Co-channel pairs sharing airtime at the last observed step (None before the first)."""
        return int(self._rows[-1][4].sum()) if self._rows else None

    def trace(self) -> RadioTrace:
        """Everything observed so far."""
        k = len(self.altitudes_m)
        if not self._rows:
            return RadioTrace(np.zeros((0, k), np.int64), np.zeros(0), np.zeros((0, len(MCS_BANDS))),
                              np.zeros((0, k)), np.zeros((0, k, k), bool),
                              np.zeros((0, len(SERVICE_CLASSES))), np.zeros((0, k), np.int64))
        channels, sinr, shares, airtime, sharing, service, stations = zip(*self._rows, strict=True)
        return RadioTrace(np.stack(channels), np.array(sinr), np.stack(shares), np.stack(airtime),
                          np.stack(sharing), np.stack(service), np.stack(stations))


def radio_summary(trace: RadioTrace, dt_s: float, radio: RadioConfig) -> dict[str, Any]:
    """``summary.json``'s ``radio`` table of one run (means over its steps, and its last step).

    ``co_channel_pairs`` lists every pair of UAVs that shared airtime on one channel at some step, with
    the seconds they did and their channel(s); ``channel_changes`` counts UAV channel changes between steps.
    """
    wifi = radio.ieee80211
    steps = len(trace.channels)
    pairs = []
    for i, j in zip(*np.nonzero(trace.sharing.any(axis=0)), strict=True):
        when = trace.sharing[:, i, j]
        pairs.append({"uavs": [int(i), int(j)], "seconds": float(when.sum() * dt_s),
                      "channels": sorted({int(c) for c in trace.channels[when, i]})})
    per_step = trace.sharing.sum(axis=(1, 2))
    changes = int(np.count_nonzero(np.diff(trace.channels, axis=0))) if steps else 0
    sinr = trace.median_sinr_db[np.isfinite(trace.median_sinr_db)]
    last = steps - 1
    return {
        "model": radio.association_name, "environment": wifi.environment, "frequency_ghz": wifi.frequency_ghz,
        "channel_width_mhz": wifi.channel_width_mhz, "usable_channels": list(wifi.usable_channels),
        "channels_final": trace.channels[last].tolist() if steps else [],
        "channels_used": sorted({int(c) for c in np.unique(trace.channels)}),
        "channel_changes": changes,
        "median_sinr_db": float(sinr.mean()) if sinr.size else None,
        "mcs_shares": {name: float(trace.mcs_shares[:, b].mean()) if steps else 0.0
                       for b, (name, _, _) in enumerate(MCS_BANDS)},
        "mean_airtime_per_uav": trace.airtime.mean(axis=0).tolist() if steps else [],
        "co_channel_pairs_mean": float(per_step.mean()) if steps else 0.0,
        "co_channel_sharing_s": float(np.count_nonzero(per_step) * dt_s),
        "co_channel_pairs": pairs,
        "rate_bar": _rate_bar(trace, radio),
        "final": {"channels": trace.channels[last].tolist(),
                  "median_sinr_db": float(trace.median_sinr_db[last]),
                  "mcs_shares": trace.mcs_shares[last].tolist(), "airtime": trace.airtime[last].tolist(),
                  "co_channel_pairs": int(per_step[last])} if steps else None,
    }


def _rate_bar(trace: RadioTrace, radio: RadioConfig) -> dict[str, Any]:
    """Where the users stood against the rate bar, and what the APs that served carried (means over steps)."""
    active = trace.stations > 0
    return {
        "rate_bar_mbps": radio.min_user_rate_mbps, "admission_on_rate": radio.ieee80211.admits_on_rate,
        "shares": {name: float(trace.service[:, c].mean()) if len(trace.service) else 0.0
                   for c, name in enumerate(SERVICE_CLASSES)},
        "stations_per_serving_ap": float(trace.stations[active].mean()) if active.any() else 0.0,
        "airtime_of_serving_ap": float(trace.airtime[active].mean()) if active.any() else 0.0,
    }


def admission_line(kind: str, wifi: dict[str, Any]) -> str:
    """One planner's users against the rate bar, and why QoS S2 is what it is (the printed table's).

    Examples:
        >>> wifi = {"rate_bar": {"rate_bar_mbps": 5.0, "admission_on_rate": True, "shares": {
        ...     "out of range": 0.2, "refused": 0.45, "below the rate bar": 0.15, "at the rate bar": 0.2},
        ...     "stations_per_serving_ap": 8.1, "airtime_of_serving_ap": 0.91}}
        >>> print(admission_line("learned", wifi))  # doctest: +NORMALIZE_WHITESPACE
        learned against the 5 Mbps bar: 20% at it or above (QoS S2), 15% served below it, 45% in range but
        refused on rate, 20% out of range; a serving AP carried 8.1 stations in 91% of the airtime: each AP
        admits a user only while all its stations keep 5 Mbps in its share of the airtime, so strategy 2
        refuses users that strategy 1 would serve at a lower rate
    """
    bar = wifi["rate_bar"]
    shares, rate = bar["shares"], bar["rate_bar_mbps"]
    line = (f"{kind} against the {rate:g} Mbps bar: {shares['at the rate bar']:.0%} at it or above (QoS S2), "
            f"{shares['below the rate bar']:.0%} served below it, {shares['refused']:.0%} in range but "
            f"refused{' on rate' if bar['admission_on_rate'] else ''}, {shares['out of range']:.0%} out of "
            f"range; a serving AP carried {bar['stations_per_serving_ap']:.1f} stations in "
            f"{bar['airtime_of_serving_ap']:.0%} of the airtime")
    if bar["admission_on_rate"]:
        return (line + f": each AP admits a user only while all its stations keep {rate:g} Mbps in its share "
                "of the airtime, so strategy 2 refuses users that strategy 1 would serve at a lower rate")
    return line + f": without admission on rate every user in range is served, however far below {rate:g} " \
        "Mbps"


def telemetry_fields(coverage: Coverage, co_channel_pairs: int | None
                     ) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """The 802.11 fields of each UAV's telemetry state and of the QoS (:mod:`bridge.telemetry.schema`).

    Returns:
        ``(per_uav, qos)``: one dict per UAV (``wifi_channel``, ``airtime_share``, ``n_stations``) and the
        QoS's (``median_sinr_db``, ``co_channel_pairs``); empty dicts under the paper's radio.
    """
    if coverage.channel is None or coverage.airtime is None or coverage.sinr_db is None:
        return [{} for _ in coverage.users_per_uav], {}
    rows = zip(coverage.channel, np.clip(coverage.airtime, 0.0, 1.0), coverage.users_per_uav, strict=True)
    per_uav = [{"wifi_channel": int(channel), "airtime_share": float(airtime), "n_stations": int(stations)}
               for channel, airtime, stations in rows]
    sinr = median_sinr_db(coverage.sinr_db)
    return per_uav, {"median_sinr_db": sinr if np.isfinite(sinr) else None,
                     "co_channel_pairs": co_channel_pairs}


def radio_line(radio: RadioConfig) -> str:
    """Which radio ran, in one line (the printed table's)."""
    if radio.propagation == "paper":
        return (f"radio: the paper's (Gaussian signal to {radio.range_m:g} m, {radio.capacity_mbps:g} "
                "Mbps per UAV shared equally)")
    wifi = radio.ieee80211
    channels = ", ".join(str(c) for c in wifi.usable_channels)
    return (f"radio: 802.11, {wifi.environment} air-to-ground, {wifi.frequency_ghz:g} GHz, "
            f"{wifi.channel_width_mhz} MHz, {wifi.tx_power_dbm:g} dBm, channels {channels}")
