"""The 802.11 model's physical layer: path loss, received power, noise, SINR -> MCS -> PHY rate.

All functions broadcast over any leading shape (worlds, users, UAVs). Formulas (docs/radio.md):

- free-space path loss, ``d`` the 3-D distance in metres (at least 1 m), ``f`` in Hz::

      FSPL(d) = 20 log10(d) + 20 log10(f) + 20 log10(4 pi / c)

- air to ground (Al-Hourani et al. 2014), ``theta`` the elevation angle of the UAV seen from the user in
  degrees (90 straight above), ``(a, b, eta_LoS, eta_NLoS)`` of the environment::

      P_LoS = 1 / (1 + a exp(-b (theta - a)))
      PL    = FSPL(d) + P_LoS eta_LoS + (1 - P_LoS) eta_NLoS

  fitted for platforms hundreds of metres up: at 10-50 m it is an extrapolation;
- UAV to UAV: free space;
- received power ``P = tx_power + G_tx + G_rx - PL`` (dBm), thermal noise
  ``N = -174 dBm/Hz + 10 log10(width in Hz) + noise figure``;
- MCS: the highest ``m`` with ``SINR >= min_sinr_db[m]`` (-1 below MCS 0: no usable rate); PHY rate
  ``rate_20mhz_1ss_mbps[m] * data tones(width) / 234 * streams``.

Examples:
    >>> round(float(free_space_loss_db(np.array(100.0), 5.18e9)), 2)
    86.73
    >>> mcs_index(np.array([-5.0, 40.0]), load_wifi_tables()).tolist()
    [-1, 11]
"""

from __future__ import annotations

import math

import numpy as np

from uav_swarm.world.wifi_config import Ieee80211Config
from uav_swarm.world.wifi_tables import WifiTables, load_wifi_tables

__all__ = ["SPEED_OF_LIGHT_M_S", "free_space_loss_db", "los_probability", "air_to_ground_loss_db",
           "station_power_dbm", "ap_power_dbm", "ap_pair_power_dbm", "noise_dbm", "mcs_index",
           "phy_rate_mbps", "dbm_to_mw"]

SPEED_OF_LIGHT_M_S = 299_792_458.0
MIN_DISTANCE_M = 1.0
"""Distances below 1 m count as 1 m (the far-field formulas mean nothing closer)."""


def free_space_loss_db(distance_m: np.ndarray, frequency_hz: float) -> np.ndarray:
    """Free-space path loss (dB) at ``distance_m`` (at least :data:`MIN_DISTANCE_M`)."""
    constant_db = 20.0 * math.log10(frequency_hz) + 20.0 * math.log10(4.0 * math.pi / SPEED_OF_LIGHT_M_S)
    return 20.0 * np.log10(np.maximum(distance_m, MIN_DISTANCE_M)) + constant_db


def los_probability(elevation_deg: np.ndarray, a: float, b: float) -> np.ndarray:
    """Al-Hourani's probability of line of sight at an elevation angle (degrees)."""
    return 1.0 / (1.0 + a * np.exp(-b * (elevation_deg - a)))


def air_to_ground_loss_db(horizontal_m: np.ndarray, height_m: np.ndarray, config: Ieee80211Config
                          ) -> np.ndarray:
    """Mean air-to-ground path loss (dB) of a UAV ``height_m`` above a user ``horizontal_m`` away."""
    a, b, eta_los_db, eta_nlos_db = config.environment_parameters
    elevation_deg = np.degrees(np.arctan2(height_m, horizontal_m))
    p_los = los_probability(elevation_deg, a, b)
    distance_m = np.hypot(horizontal_m, height_m)
    return free_space_loss_db(distance_m, config.frequency_ghz * 1e9) + p_los * eta_los_db \
        + (1.0 - p_los) * eta_nlos_db


def station_power_dbm(horizontal_m: np.ndarray, height_m: np.ndarray, config: Ieee80211Config) -> np.ndarray:
    """Power (dBm) a user receives from a UAV's AP."""
    gains_db = config.tx_power_dbm + config.ap_antenna_gain_dbi + config.station_antenna_gain_dbi
    return gains_db - air_to_ground_loss_db(horizontal_m, height_m, config)


def ap_power_dbm(distance_m: np.ndarray, config: Ieee80211Config) -> np.ndarray:
    """Power (dBm) one UAV's AP receives from another ``distance_m`` away (free space, both AP antennas)."""
    gains_db = config.tx_power_dbm + 2.0 * config.ap_antenna_gain_dbi
    return gains_db - free_space_loss_db(distance_m, config.frequency_ghz * 1e9)


def ap_pair_power_dbm(uavs_m: np.ndarray, altitudes_m: np.ndarray, config: Ieee80211Config) -> np.ndarray:
    """``(B, K, K)`` power (dBm) AP ``i`` receives from AP ``j`` of the same world (3-D distance, free space).

    Args:
        uavs_m: (B, K, 2) horizontal UAV positions, metres.
        altitudes_m: (B, K) each UAV's altitude, metres.
        config: The 802.11 settings.
    """
    positions = np.concatenate([uavs_m, altitudes_m[:, :, None]], axis=2)
    return ap_power_dbm(np.linalg.norm(positions[:, :, None] - positions[:, None], axis=3), config)


def noise_dbm(config: Ieee80211Config) -> float:
    """Thermal noise plus the receiver's noise figure over the channel width (dBm)."""
    return -174.0 + 10.0 * math.log10(config.channel_width_mhz * 1e6) + config.noise_figure_db


def dbm_to_mw(power_dbm: np.ndarray | float) -> np.ndarray:
    """Milliwatts of a power in dBm."""
    return np.power(10.0, np.asarray(power_dbm, dtype=np.float64) / 10.0)


def mcs_index(sinr_db: np.ndarray, tables: WifiTables) -> np.ndarray:
    """The highest MCS whose threshold the SINR reaches, -1 below MCS 0 (int64, the shape of ``sinr_db``)."""
    return np.searchsorted(tables.min_sinr_db, sinr_db, side="right").astype(np.int64) - 1


def phy_rate_mbps(mcs: np.ndarray, config: Ieee80211Config, tables: WifiTables | None = None) -> np.ndarray:
    """PHY rate (Mbps) of each MCS at the configured width and streams; 0 for -1 (no usable rate)."""
    tables = tables or load_wifi_tables(config.tables_file)
    scale = tables.width_factor(config.channel_width_mhz) * config.spatial_streams
    ladder = np.concatenate([[0.0], tables.rate_20mhz_1ss_mbps * scale])
    return ladder[np.asarray(mcs) + 1]
