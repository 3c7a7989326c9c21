"""The 802.11 model's physical layer: path loss, received power, noise, SINR -> MCS -> PHY rate.

Formulas (docs/radio.md):

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
  ``rate_20mhz_1ss_mbps[m] * data tones(width) / 234 * streams * 13.6 / (12.8 + guard interval in us)``.

The received power of every (user, UAV) pair (N x K x B at every step) is one compiled pass, in milliwatts:
``10^((EIRP - FSPL(1 m) - excess) / 10) / d^2``, the same formula, its first factor (a function of the
elevation angle alone) read from a fine table (within 2e-5 dB of the formula). SINR and MCS are computed
where they are used, in :mod:`uav_swarm.world.wifi.coverage`.

Examples:
    >>> config = Ieee80211Config()
    >>> two = ap_pair_power_dbm(np.array([[[0.0, 0.0], [100.0, 0.0]]]), np.array([[10.0, 10.0]]), config)
    >>> round(float(two[0, 0, 1]), 2)  # 20 dBm - FSPL(100 m) = 20 - 86.73
    -66.73
    >>> power_mw = station_power_mw(np.array([[0.0, 0.0]]), np.zeros(1, np.int64), np.array([[[30.0, 0.0]]]),
    ...                             np.array([[20.0]]), config)  # 30 m away, 20 m up
    >>> round(float(10 * np.log10(power_mw[0, 0])), 2), round(noise_dbm(config), 2)
    (-62.09, -93.99)
    >>> rate_ladder_mbps(config)[[0, 1, 12]].tolist()  # no MCS, MCS 0, MCS 11
    [0.0, 8.6, 143.4]
    >>> round(float(rate_ladder_mbps(Ieee80211Config(guard_interval_us=3.2))[12]), 2)  # MCS 11 at 3.2 us
    121.89
"""

from __future__ import annotations

import functools
import math

import numba
import numpy as np

from uav_swarm.world.wifi.config import Ieee80211Config
from uav_swarm.world.wifi.tables import WifiTables, load_wifi_tables

__all__ = ["SPEED_OF_LIGHT_M_S", "TABLE_ERROR_DB", "station_power_mw", "elevation_gain_table",
           "ap_pair_power_dbm", "noise_dbm", "dbm_to_mw", "rate_ladder_mbps"]

SPEED_OF_LIGHT_M_S = 299_792_458.0
MIN_DISTANCE_M = 1.0
"""Distances below 1 m count as 1 m (the far-field formulas mean nothing closer)."""
TABLE_SIZE = 8192
"""Intervals of :func:`elevation_gain_table` (64 KiB of float64: the table stays in the cache)."""
TABLE_ERROR_DB = 2e-5
"""The most the tabulated received power differs from the formula, in dB, in every environment (tested)."""


def _fspl_1m_db(frequency_hz: float) -> float:
    """Free-space path loss at 1 m (dB)."""
    return 20.0 * math.log10(frequency_hz) + 20.0 * math.log10(4.0 * math.pi / SPEED_OF_LIGHT_M_S)


def station_power_mw(users_m: np.ndarray, copy_index: np.ndarray, uavs_m: np.ndarray, heights_m: np.ndarray,
                     config: Ieee80211Config) -> np.ndarray:
    """``(N, K)`` power (mW) each user receives from each UAV's AP of its own world (air to ground).

    Computed as ``G(q) / max(d^2, 1)``, the formula above in milliwatts: ``G`` is
    ``10^((EIRP - FSPL(1 m) - excess) / 10)``, a function of the elevation angle alone, read from
    :func:`elevation_gain_table` with linear interpolation in ``q = r / (r + h)`` (``r`` the horizontal
    distance, ``h`` the UAV's height; ``tan(theta) = (1 - q) / q``), within :data:`TABLE_ERROR_DB` of the
    formula. The users of all worlds go through one compiled pass (a pair's power does not depend on the
    others: one world alone gets the same numbers as in a batch). A UAV below the users (``h < 0``) gets
    the formula itself.

    Args:
        users_m: (N, 2) user positions, metres, stacked world by world.
        copy_index: (N,) each user's world (non-decreasing).
        uavs_m: (B, K, 2) UAV positions, metres.
        heights_m: (B, K) each UAV's height above the users, metres.
        config: The 802.11 settings.
    """
    return _station_power_kernel(
        np.ascontiguousarray(users_m, dtype=np.float64), np.ascontiguousarray(copy_index, dtype=np.int64),
        np.ascontiguousarray(uavs_m, dtype=np.float64), np.ascontiguousarray(heights_m, dtype=np.float64),
        elevation_gain_table(config), *_folded_constants(config))


def _folded_constants(config: Ieee80211Config) -> tuple[float, float, float, float]:
    """The formula's constants folded (four floats).

    ``-b 180 / pi``, ``ln a + a b``, ``ln10 / 10 (eta_NLoS - eta_LoS)`` and
    ``ln10 / 10 (EIRP - FSPL(1 m) - eta_NLoS)``.
    """
    a, b, eta_los_db, eta_nlos_db = config.environment_parameters
    eirp_dbm = config.tx_power_dbm + config.ap_antenna_gain_dbi + config.station_antenna_gain_dbi
    to_neper = math.log(10.0) / 10.0
    return (-b * 180.0 / math.pi, math.log(a) + a * b, (eta_nlos_db - eta_los_db) * to_neper,
            (eirp_dbm - _fspl_1m_db(config.frequency_ghz * 1e9) - eta_nlos_db) * to_neper)


@functools.lru_cache(maxsize=16)
def elevation_gain_table(config: Ieee80211Config) -> np.ndarray:
    """``(TABLE_SIZE + 1,)`` the power at 1 m (mW) at ``q = i / TABLE_SIZE`` (``q = r / (r + h)``).

    ``q = 0`` is straight above (90 degrees), ``q = 1`` the horizon; the elevation is
    ``atan2(1 - q, q)``. Read-only, cached per config.
    """
    per_radian, offset, los_gain, at_1m = _folded_constants(config)
    q = np.linspace(0.0, 1.0, TABLE_SIZE + 1)
    table = np.array([_gain_at_1m(theta, per_radian, offset, los_gain, at_1m)
                      for theta in np.arctan2(1.0 - q, q)])
    table.setflags(write=False)
    return table


@numba.njit(cache=True, nogil=True)
def _gain_at_1m(elevation: float, per_radian: float, offset: float, los_gain: float, at_1m: float) -> float:
    """The formula with its constants folded, at 1 m (``elevation`` in rad).

    ``P_LoS = 1 / (1 + exp(ln a + a b - b theta))`` and
    ``exp(ln10 / 10 (EIRP - FSPL(1 m) - eta_NLoS + (eta_NLoS - eta_LoS) P_LoS))``.
    """
    los = 1.0 / (math.exp(elevation * per_radian + offset) + 1.0)
    return math.exp(los * los_gain + at_1m)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _station_power_kernel(users_m: np.ndarray, copy_index: np.ndarray, uavs_m: np.ndarray,
                          heights_m: np.ndarray, table: np.ndarray, per_radian: float, offset: float,
                          los_gain: float, at_1m: float) -> np.ndarray:
    """(N, K) powers: the table's gain at ``q = r / (r + h)`` over ``max(d^2, 1)``."""
    n_users, n_uavs = users_m.shape[0], uavs_m.shape[1]
    power_mw = np.empty((n_users, n_uavs))
    steps = table.size - 1
    for n in range(n_users):
        c = copy_index[n]
        for k in range(n_uavs):
            dx = uavs_m[c, k, 0] - users_m[n, 0]
            dy = uavs_m[c, k, 1] - users_m[n, 1]
            horizontal_sq = dx * dx + dy * dy
            height = heights_m[c, k]
            distance_sq = max(horizontal_sq + height * height, MIN_DISTANCE_M * MIN_DISTANCE_M)
            horizontal = math.sqrt(horizontal_sq)
            if height < 0.0:  # below the users: the formula itself (the table spans 0 to 90 degrees)
                gain = _gain_at_1m(math.atan2(height, horizontal), per_radian, offset, los_gain, at_1m)
            else:
                span = horizontal + height
                x = horizontal / span * steps if span > 0.0 else float(steps)  # atan2(0, 0) = 0: the horizon
                i = min(int(x), steps - 1)
                gain = table[i] + (x - i) * (table[i + 1] - table[i])
            power_mw[n, k] = gain / distance_sq
    return power_mw


def ap_pair_power_dbm(uavs_m: np.ndarray, altitudes_m: np.ndarray, config: Ieee80211Config) -> np.ndarray:
    """``(B, K, K)`` power (dBm) AP ``i`` receives from AP ``j`` of the same world (3-D distance, free space).

    Args:
        uavs_m: (B, K, 2) horizontal UAV positions, metres.
        altitudes_m: (B, K) each UAV's altitude, metres.
        config: The 802.11 settings.
    """
    eirp_dbm = config.tx_power_dbm + 2.0 * config.ap_antenna_gain_dbi
    return _ap_pair_kernel(np.ascontiguousarray(uavs_m, dtype=np.float64),
                           np.ascontiguousarray(altitudes_m, dtype=np.float64),
                           eirp_dbm - _fspl_1m_db(config.frequency_ghz * 1e9))


@numba.njit(cache=True, nogil=True)
def _ap_pair_kernel(uavs_m: np.ndarray, altitudes_m: np.ndarray, at_1m_dbm: float) -> np.ndarray:
    """``EIRP - FSPL(1 m) - 20 log10(max(d_ij, 1))`` for every pair of APs of each world (K x K is small)."""
    n_worlds, n_uavs = altitudes_m.shape
    power_dbm = np.empty((n_worlds, n_uavs, n_uavs))
    for c in range(n_worlds):
        for i in range(n_uavs):
            for j in range(n_uavs):
                dx = uavs_m[c, i, 0] - uavs_m[c, j, 0]
                dy = uavs_m[c, i, 1] - uavs_m[c, j, 1]
                dz = altitudes_m[c, i] - altitudes_m[c, j]
                distance_m = max(math.sqrt(dx * dx + dy * dy + dz * dz), MIN_DISTANCE_M)
                power_dbm[c, i, j] = at_1m_dbm - 20.0 * math.log10(distance_m)
    return power_dbm


def noise_dbm(config: Ieee80211Config) -> float:
    """Thermal noise plus the receiver's noise figure over the channel width (dBm)."""
    return -174.0 + 10.0 * math.log10(config.channel_width_mhz * 1e6) + config.noise_figure_db


def dbm_to_mw(power_dbm: np.ndarray | float) -> np.ndarray:
    """Milliwatts of a power in dBm."""
    return np.power(10.0, np.asarray(power_dbm, dtype=np.float64) / 10.0)


def rate_ladder_mbps(config: Ieee80211Config, tables: WifiTables | None = None) -> np.ndarray:
    """``(M + 1,)`` 0 (no usable rate), then the PHY rate of MCS 0..M-1 (width, streams, guard interval)."""
    tables = tables or load_wifi_tables(config.tables_file)
    scale = tables.width_factor(config.channel_width_mhz) * config.spatial_streams \
        * config.guard_interval_rate_factor
    return np.concatenate([[0.0], tables.rate_20mhz_1ss_mbps * scale])
