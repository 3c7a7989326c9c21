"""The 802.11 model's tables: MCS ladder, SINR thresholds, width factors, MAC efficiency, contention.

The numbers live in a TOML data file (``uav_swarm/world/data/wifi_80211ax.toml``, shipped with the package,
with the source of every value in its comments) so that a calibration can refit them without touching code.
Schema (``schema = 2``; ``schema = 1``, without the collision keys, is refused with what to add)::

    [mcs]        rate_20mhz_1ss_mbps = [12 floats, increasing]   PHY rate of MCS 0..11, 1 stream, 20 MHz,
                                                                  0.8 us guard interval
                 min_sinr_db          = [12 floats, increasing]   lowest SINR at which each MCS is used
    [width]      channel_width_mhz    = [ints]                    e.g. 20, 40, 80, 160
                 data_subcarriers     = [ints, same length]       rate factor = tones / tones at 20 MHz
    [mac]        efficiency           = float in (0, 1]           payload share of the PHY rate
    [contention] access_intensity     = float > 0                 ideal CSMA's rho (transmit / backoff time)
                 interference_airtime_weighting = float in [0, 1]
                                                    0: hidden APs always on; 1: on for their airtime share
                 cw_min               = int in [1, 1023]          minimum contention window (slots - 1)
                 backoff_stages       = int in [0, 10]            doublings up to the maximum window
                 collision_time_ratio = float in [0, 10]          a collision's busy time over a success's
                                                                  (0: collisions cost nothing)

Examples:
    >>> tables = load_wifi_tables()
    >>> float(tables.rate_20mhz_1ss_mbps[11]), float(tables.min_sinr_db[0]), tables.width_factor(40)
    (143.4, 12.0, 2.0)
"""

from __future__ import annotations

import functools
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from typed_config import ConfigError

__all__ = ["WifiTables", "SHIPPED_TABLES", "load_wifi_tables"]

SHIPPED_TABLES = Path(__file__).parents[1] / "data" / "wifi_80211ax.toml"
"""The tables shipped with the package."""


@dataclass(frozen=True)
class WifiTables:
    """The numbers of the 802.11 model (read-only arrays; see the module docstring for the schema).

    Attributes:
        rate_20mhz_1ss_mbps: (M,) PHY rate of each MCS, one spatial stream, 20 MHz.
        min_sinr_db: (M,) lowest SINR (dB) at which each MCS is used, increasing.
        channel_width_mhz: (W,) channel widths the tables know.
        data_subcarriers: (W,) data tones of each width.
        mac_efficiency: Payload share of the PHY rate.
        access_intensity: Ideal CSMA's rho.
        interference_airtime_weighting: 0: hidden APs interfere always; 1: for their airtime share only.
        cw_min: Minimum contention window (Bianchi's ``W - 1``).
        backoff_stages: Doublings of the window up to its maximum (Bianchi's ``m``).
        collision_time_ratio: A collision's busy time over a successful transmission's.
        source: The file read.
    """

    rate_20mhz_1ss_mbps: np.ndarray
    min_sinr_db: np.ndarray
    channel_width_mhz: np.ndarray
    data_subcarriers: np.ndarray
    mac_efficiency: float
    access_intensity: float
    interference_airtime_weighting: float
    cw_min: int
    backoff_stages: int
    collision_time_ratio: float
    source: str

    def width_factor(self, width_mhz: int) -> float:
        """PHY rate at ``width_mhz`` over the rate at 20 MHz (data tones over data tones).

        Raises:
            ValueError: A width the tables do not list.
        """
        rows = np.flatnonzero(self.channel_width_mhz == width_mhz)
        base = np.flatnonzero(self.channel_width_mhz == 20)
        if rows.size == 0 or base.size == 0:
            raise ValueError(f"{self.source}: [width] lists no {width_mhz} MHz (or no 20 MHz) channel width")
        return float(self.data_subcarriers[rows[0]] / self.data_subcarriers[base[0]])


def _array(data: dict[str, Any], table: str, key: str, path: str, dtype: type) -> np.ndarray:
    try:
        values: np.ndarray = np.asarray(data[table][key], dtype=dtype)
    except (KeyError, TypeError, ValueError):
        raise ConfigError(f"{path}: [{table}] {key} is missing or not a list of numbers") from None
    if values.ndim != 1 or values.size == 0:
        raise ConfigError(f"{path}: [{table}] {key} must be a non-empty list of numbers")
    values.setflags(write=False)
    return values


def _number(data: dict[str, Any], table: str, key: str, path: str, low: float, high: float,
            low_open: bool) -> float:
    value = data.get(table, {}).get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f"{path}: [{table}] {key} is missing or not a number")
    if not ((low < value) if low_open else (low <= value)) or not value <= high:
        bound = "<" if low_open else "<="
        raise ConfigError(f"{path}: [{table}] {key} = {value} is out of range: allowed {low} {bound} {key} "
                          f"<= {high}")
    return float(value)


def _integer(data: dict[str, Any], table: str, key: str, path: str, low: int, high: int) -> int:
    value = data.get(table, {}).get(key)
    if isinstance(value, bool) or not isinstance(value, int):
        raise ConfigError(f"{path}: [{table}] {key} is missing or not an integer")
    if not low <= value <= high:
        raise ConfigError(f"{path}: [{table}] {key} = {value} is out of range: allowed {low} <= {key} "
                          f"<= {high}")
    return value


@functools.lru_cache(maxsize=8)
def load_wifi_tables(path: str | Path | None = None) -> WifiTables:
    """Read and check the tables (cached per path).

    Args:
        path: A TOML file of the schema above; None (or "") reads the shipped tables.

    Raises:
        ConfigError: The file is missing, not TOML, or breaks the schema (the message names file and key).
    """
    file = Path(path) if path else SHIPPED_TABLES
    where = str(file)
    try:
        data = tomllib.loads(file.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"Wi-Fi tables file not found: {where}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{where}: invalid TOML: {exc}") from None
    if data.get("schema") == 1:
        raise ConfigError(f"{where}: schema = 1 has no collision model: set schema = 2 and add [contention] "
                          "cw_min, backoff_stages and collision_time_ratio (docs/radio.md, the tables file)")
    if data.get("schema") != 2:
        raise ConfigError(f"{where}: schema = {data.get('schema')!r}; allowed: schema = 2")
    rates = _array(data, "mcs", "rate_20mhz_1ss_mbps", where, float)
    sinr = _array(data, "mcs", "min_sinr_db", where, float)
    widths = _array(data, "width", "channel_width_mhz", where, np.int64)
    tones = _array(data, "width", "data_subcarriers", where, np.int64)
    if rates.size != sinr.size or widths.size != tones.size:
        raise ConfigError(f"{where}: [mcs] rate_20mhz_1ss_mbps and min_sinr_db, and [width] "
                          "channel_width_mhz and data_subcarriers, must have equal lengths")
    if np.any(np.diff(rates) <= 0) or np.any(np.diff(sinr) < 0) or np.any(rates <= 0) or np.any(tones <= 0):
        raise ConfigError(f"{where}: [mcs] rates must be positive and increasing, min_sinr_db "
                          "non-decreasing, [width] data_subcarriers positive")
    return WifiTables(
        rate_20mhz_1ss_mbps=rates, min_sinr_db=sinr, channel_width_mhz=widths, data_subcarriers=tones,
        mac_efficiency=_number(data, "mac", "efficiency", where, 0.0, 1.0, True),
        access_intensity=_number(data, "contention", "access_intensity", where, 0.0, 1e6, True),
        interference_airtime_weighting=_number(data, "contention", "interference_airtime_weighting", where,
                                               0.0, 1.0, False),
        cw_min=_integer(data, "contention", "cw_min", where, 1, 1023),
        backoff_stages=_integer(data, "contention", "backoff_stages", where, 0, 10),
        collision_time_ratio=_number(data, "contention", "collision_time_ratio", where, 0.0, 10.0, False),
        source=where)
