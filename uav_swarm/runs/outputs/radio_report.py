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
  points take turns on the medium.

:func:`radio_summary` turns a :class:`RadioTrace` into ``summary.json``'s ``radio`` table, and
:func:`radio_line` names the radio that ran, for the printed table.

Examples:
    >>> mcs_band_shares(np.array([-1, 0, 5, 11, 11]))
    array([0.2, 0.2, 0.2, 0.4])
    >>> from uav_swarm.world.radio_config import RadioConfig
    >>> radio_line(RadioConfig())
    "radio: the paper's (Gaussian signal to 30 m, 200 Mbps per UAV shared equally)"
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from uav_swarm.world.coverage import Coverage
from uav_swarm.world.radio_config import RadioConfig
from uav_swarm.world.wifi.coverage import channel_conflicts

__all__ = ["MCS_BANDS", "SERVICE_COLOURS", "RadioTrace", "RadioLog", "mcs_band_shares", "median_sinr_db",
           "sharing_pairs",
           "radio_summary", "radio_line", "telemetry_fields"]

MCS_BANDS: tuple[tuple[str, int, int], ...] = (("not served", -1, -1), ("MCS 0-3", 0, 3), ("MCS 4-7", 4, 7),
                                                ("MCS 8-11", 8, 11))
"""``(name, lowest, highest)`` MCS index of each band a report counts users in (-1: not served)."""

SERVICE_COLOURS: tuple[str, ...] = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b",
                                    "#e377c2", "#bcbd22", "#17becf", "#393b79")
"""The colour of UAV ``k`` and of the users it serves in the pictures of an 802.11 run (``k % 10``)."""


def mcs_band_shares(mcs: np.ndarray) -> np.ndarray:
    """(len(MCS_BANDS),) share of the users in each band of :data:`MCS_BANDS` (zeros without users)."""
    mcs = np.asarray(mcs)
    if mcs.size == 0:
        return np.zeros(len(MCS_BANDS))
    return np.array([np.count_nonzero((mcs >= low) & (mcs <= high)) / mcs.size for _, low, high in MCS_BANDS])


def median_sinr_db(sinr_db: np.ndarray) -> float:
    """The median SINR of the users (dB), NaN without users."""
    return float(np.median(sinr_db)) if len(sinr_db) else float("nan")


def sharing_pairs(uavs_m: np.ndarray, channels: np.ndarray, radio: RadioConfig, altitudes_m: np.ndarray
                  ) -> np.ndarray:
    """(K, K) bool, upper triangle: UAVs ``i < j`` on one channel that hear each other (sharing airtime)."""
    _, conflict = channel_conflicts(np.asarray(uavs_m, np.float64)[None], radio, altitudes_m)
    same = channels[:, None] == channels[None, :]
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
    """

    channels: np.ndarray
    median_sinr_db: np.ndarray
    mcs_shares: np.ndarray
    airtime: np.ndarray
    sharing: np.ndarray


@dataclass
class RadioLog:
    """Collects a :class:`RadioTrace` step by step.

    Args:
        radio: The 802.11 radio of the run.
        altitudes_m: (K,) each UAV's altitude.
    """

    radio: RadioConfig
    altitudes_m: np.ndarray
    _rows: list[tuple[np.ndarray, float, np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=list)

    def observe(self, coverage: Coverage, uavs_m: np.ndarray) -> None:
        """One step's coverage (802.11: with SINR, MCS, airtime and channels) and the UAVs' positions."""
        if coverage.sinr_db is None or coverage.mcs is None or coverage.airtime is None \
                or coverage.channel is None:
            raise ValueError(f"the coverage of {coverage.model!r} has no 802.11 figures")
        channels = np.array(coverage.channel, np.int64)
        self._rows.append((channels, median_sinr_db(coverage.sinr_db), mcs_band_shares(coverage.mcs),
                           np.array(coverage.airtime, np.float64),
                           sharing_pairs(uavs_m, channels, self.radio, self.altitudes_m)))

    @property
    def latest_pairs(self) -> int | None:
        """Co-channel pairs sharing airtime at the last observed step (None before the first)."""
        return int(self._rows[-1][4].sum()) if self._rows else None

    def trace(self) -> RadioTrace:
        """Everything observed so far."""
        k = len(self.altitudes_m)
        if not self._rows:
            return RadioTrace(np.zeros((0, k), np.int64), np.zeros(0), np.zeros((0, len(MCS_BANDS))),
                              np.zeros((0, k)), np.zeros((0, k, k), bool))
        channels, sinr, shares, airtime, sharing = zip(*self._rows, strict=True)
        return RadioTrace(np.stack(channels), np.array(sinr), np.stack(shares), np.stack(airtime),
                          np.stack(sharing))


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
        "final": {"channels": trace.channels[last].tolist(),
                  "median_sinr_db": float(trace.median_sinr_db[last]),
                  "mcs_shares": trace.mcs_shares[last].tolist(), "airtime": trace.airtime[last].tolist(),
                  "co_channel_pairs": int(per_step[last])} if steps else None,
    }


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
