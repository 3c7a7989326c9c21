"""The settings of the 802.11 radio model (``[task.radio.ieee80211]``), with their sources.

The model itself is :mod:`uav_swarm.world.wifi.coverage` (docs/radio.md); it runs when
``RadioConfig.propagation = "802.11"``. Defaults: 5 GHz channel 36 (5.18 GHz), 20 MHz, one spatial
stream, 20 dBm (the 5150-5250 MHz limit for a station-class device in most regions is 23 dBm EIRP),
0 dBi antennas, a 7 dB noise figure (a typical Wi-Fi receiver; the standard's sensitivities assume 10 dB),
Al-Hourani's urban environment, carrier sense at -82 dBm per 20 MHz (802.11's preamble detection level).

Usable channels: a list of channel numbers of the configured width and band; empty takes the band's
channels without radar detection (5 GHz: UNII-1 and UNII-3; 2.4 GHz: 1, 6, 11).

Examples:
    >>> Ieee80211Config().usable_channels
    (36, 40, 44, 48, 149, 153, 157, 161, 165)
    >>> Ieee80211Config(frequency_ghz=2.437).usable_channels
    (1, 6, 11)
    >>> Ieee80211Config(channel_width_mhz=40).cca_threshold_dbm
    -79.0
    >>> round(Ieee80211Config(guard_interval_us=3.2).guard_interval_rate_factor, 3)  # 13.6 / 16
    0.85
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from typed_config import Config, ConfigError, param

__all__ = ["Ieee80211Config", "ENVIRONMENTS", "CHANNELS_5GHZ", "CHANNELS_2GHZ", "GUARD_INTERVALS_US",
           "HE_SYMBOL_US"]

ENVIRONMENTS: dict[str, tuple[float, float, float, float]] = {
    "suburban": (4.88, 0.43, 0.1, 21.0),
    "urban": (9.61, 0.16, 1.0, 20.0),
    "dense urban": (12.08, 0.11, 1.6, 23.0),
    "high-rise urban": (27.23, 0.08, 2.3, 34.0),
}
"""Al-Hourani, Kandeepan, Lardner, IEEE WCL 3(6), 2014: ``(a, b, eta_LoS_dB, eta_NLoS_dB)`` by environment."""

CHANNELS_5GHZ: dict[int, tuple[int, ...]] = {
    20: (36, 40, 44, 48, 52, 56, 60, 64, 100, 104, 108, 112, 116, 120, 124, 128, 132, 136, 140, 144,
         149, 153, 157, 161, 165, 169, 173, 177),
    40: (38, 46, 54, 62, 102, 110, 118, 126, 134, 142, 151, 159, 167, 175),
    80: (42, 58, 106, 122, 138, 155, 171),
}
"""5 GHz channel numbers by width (centre channel of a bonded channel)."""

CHANNELS_2GHZ: tuple[int, ...] = tuple(range(1, 14))
"""2.4 GHz channel numbers (20 MHz only here)."""

GUARD_INTERVALS_US: tuple[float, ...] = (0.8, 1.6, 3.2)
"""802.11ax's guard intervals (us)."""
HE_SYMBOL_US = 12.8
"""An HE OFDM symbol without its guard interval (us): rates scale by 13.6 / (12.8 + guard interval)."""

_DEFAULT_CHANNELS = {20: (36, 40, 44, 48, 149, 153, 157, 161, 165), 40: (38, 46, 151, 159), 80: (42, 155)}


@dataclass(frozen=True)
class Ieee80211Config(Config):
    """Radio, channel and MAC settings of the 802.11 model (``RadioConfig.propagation = "802.11"``)."""

    frequency_ghz: float = param(
        5.18, ge=2.4, le=5.9, doc="carrier frequency for path loss (GHz): 2.4-2.5 or 5.15-5.9; 5.18: ch 36")
    channel_width_mhz: int = param(20, doc="channel width (MHz): 20, 40 or 80 (2.4 GHz: 20)")
    spatial_streams: int = param(1, ge=1, le=8, doc="spatial streams of every link (rate scales linearly)")
    tx_power_dbm: float = param(20.0, ge=-10.0, le=36.0, doc="AP transmit power (dBm)")
    ap_antenna_gain_dbi: float = param(0.0, ge=-10.0, le=20.0, doc="AP antenna gain (dBi)")
    station_antenna_gain_dbi: float = param(0.0, ge=-10.0, le=20.0, doc="user device antenna gain (dBi)")
    noise_figure_db: float = param(7.0, ge=0.0, le=20.0, doc="receiver noise figure (dB)")
    environment: Literal["suburban", "urban", "dense urban", "high-rise urban"] = param(
        "urban", doc="Al-Hourani air-to-ground environment (fitted far higher up: extrapolated at 10-50 m)")
    cca_threshold_20mhz_dbm: float = param(
        -82.0, ge=-100.0, le=-40.0, doc="carrier-sense threshold at 20 MHz (dBm); +3 dB per doubled width")
    fairness: Literal["airtime", "throughput"] = param(
        "airtime", doc="how an AP splits its airtime: equal airtime per station (modern APs) or equal "
        "throughput (first-in first-out queues: the 802.11 performance anomaly)")
    rate_admission: bool | None = param(
        None, doc="admit a station only while every station of the AP keeps min_user_rate_mbps; not given: "
        "the task's strategy decides (strategy 1: off, every user in range joins; strategy 2: on), and the "
        "model used alone admits on rate")
    guard_interval_us: float = param(
        0.8, doc="802.11ax guard interval (us): 0.8 (as the tables are fitted), 1.6 or 3.2 (ns-3's default); "
        "rates scale by 13.6 / (12.8 + guard interval)")
    channels: tuple[int, ...] = param((), doc="usable channel numbers (width and band of this config); "
                                      "empty: the band's channels without radar detection")
    mac_efficiency: float | None = param(None, gt=0.0, le=1.0,
                                         doc="payload share of the PHY rate; None: the tables' value")
    tables_file: str = param("", doc="TOML tables (MCS, SINR thresholds, efficiency, contention); "
                             "empty: the shipped tables")

    def check(self) -> None:
        """The band, width and channels must agree."""
        two_four = self.frequency_ghz <= 2.5
        if not two_four and self.frequency_ghz < 5.15:
            raise ConfigError(f"Ieee80211Config.frequency_ghz = {self.frequency_ghz} is out of range: "
                              "allowed 2.4 <= frequency_ghz <= 2.5 or 5.15 <= frequency_ghz <= 5.9")
        widths = (20,) if two_four else tuple(CHANNELS_5GHZ)
        if self.channel_width_mhz not in widths:
            raise ConfigError(f"Ieee80211Config.channel_width_mhz = {self.channel_width_mhz} is not allowed "
                              f"in this band: choose one of {list(widths)}")
        if self.guard_interval_us not in GUARD_INTERVALS_US:
            raise ConfigError(f"Ieee80211Config.guard_interval_us = {self.guard_interval_us} is not allowed: "
                              f"choose one of {list(GUARD_INTERVALS_US)}")
        allowed = CHANNELS_2GHZ if two_four else CHANNELS_5GHZ[self.channel_width_mhz]
        wrong = [c for c in self.channels if c not in allowed]
        if wrong or len(set(self.channels)) != len(self.channels):
            raise ConfigError(f"Ieee80211Config.channels = {list(self.channels)}: each channel once, from "
                              f"{list(allowed)} ({self.channel_width_mhz} MHz, "
                              f"{'2.4' if two_four else '5'} GHz)")

    @property
    def admits_on_rate(self) -> bool:
        """Whether admission on rate runs: ``rate_admission``, on when not given (no strategy decided it)."""
        return self.rate_admission is not False

    @property
    def usable_channels(self) -> tuple[int, ...]:
        """The channels a plan may use: ``channels`` or the band's default."""
        if self.channels:
            return self.channels
        return (1, 6, 11) if self.frequency_ghz <= 2.5 else _DEFAULT_CHANNELS[self.channel_width_mhz]

    @property
    def guard_interval_rate_factor(self) -> float:
        """PHY rate at this guard interval over the rate at 0.8 us (the tables'): ``13.6 / (12.8 + GI)``."""
        return (HE_SYMBOL_US + GUARD_INTERVALS_US[0]) / (HE_SYMBOL_US + self.guard_interval_us)

    @property
    def cca_threshold_dbm(self) -> float:
        """Carrier-sense threshold at the configured width (dBm): ``cca_20 + 3 log2(width / 20)``."""
        return self.cca_threshold_20mhz_dbm + 3 * int(math.log2(self.channel_width_mhz // 20))

    @property
    def environment_parameters(self) -> tuple[float, float, float, float]:
        """``(a, b, eta_LoS_dB, eta_NLoS_dB)`` of the environment (Al-Hourani 2014)."""
        return ENVIRONMENTS[self.environment]
