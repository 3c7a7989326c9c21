"""East-North-Up metres <-> WGS84 geodetic coordinates around a home position.

All geodesy is delegated to :mod:`pymap3d` (WGS84 ellipsoid); nothing here is
hand-written trigonometry.

Examples:
    >>> home = Home(lat_deg=47.3977418, lon_deg=8.5455938, alt_m=488.0)
    >>> lat_deg, lon_deg, alt_m = enu_to_geodetic(home, 100.0, 0.0, 10.0)
    >>> [round(v, 3) for v in geodetic_to_enu(home, lat_deg, lon_deg, alt_m)]
    [100.0, 0.0, 10.0]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pymap3d
import pymap3d.vincenty

from typed_config import Config, param

__all__ = ["Home", "enu_to_geodetic", "enu_to_geodetic_many", "geodetic_to_enu", "ground_distance_m"]


@dataclass(frozen=True)
class Home(Config):
    """The geodetic origin of the local East-North-Up frame (the take-off point)."""

    lat_deg: float = param(47.3977418, ge=-90.0, le=90.0, doc="home latitude, WGS84 degrees")
    lon_deg: float = param(8.5455938, ge=-180.0, le=180.0, doc="home longitude, WGS84 degrees")
    alt_m: float = param(488.0, ge=-500.0, le=9000.0, doc="home altitude above mean sea level, metres")


def enu_to_geodetic(home: Home, x_m: float, y_m: float, z_m: float) -> tuple[float, float, float]:
    """Convert a local East-North-Up point to WGS84 latitude, longitude and altitude.

    Args:
        home: The origin of the local frame.
        x_m: East offset from home, metres.
        y_m: North offset from home, metres.
        z_m: Up offset from home, metres.

    Returns:
        ``(lat_deg, lon_deg, alt_m)`` with ``alt_m`` above mean sea level (home's datum).
    """
    lat_deg, lon_deg, alt_m = pymap3d.enu2geodetic(
        x_m, y_m, z_m, home.lat_deg, home.lon_deg, home.alt_m, deg=True
    )
    return float(lat_deg), float(lon_deg), float(alt_m)


def enu_to_geodetic_many(home: Home, points_m: np.ndarray) -> np.ndarray:
    """:func:`enu_to_geodetic` of ``(N, 3)`` East-North-Up points in one call: ``(N, 3)`` lat, lon, alt.

    Examples:
        >>> home = Home()
        >>> many = enu_to_geodetic_many(home, np.array([[100.0, 0.0, 10.0], [0.0, -50.0, 0.0]]))
        >>> bool(np.all(many[0] == enu_to_geodetic(home, 100.0, 0.0, 10.0)))
        True
    """
    points = np.asarray(points_m, np.float64).reshape(-1, 3)
    lat_deg, lon_deg, alt_m = pymap3d.enu2geodetic(points[:, 0], points[:, 1], points[:, 2], home.lat_deg,
                                                   home.lon_deg, home.alt_m, deg=True)
    return np.column_stack([lat_deg, lon_deg, alt_m]).reshape(-1, 3)


def geodetic_to_enu(home: Home, lat_deg: float, lon_deg: float, alt_m: float) -> tuple[float, float, float]:
    """Convert a WGS84 point to local East-North-Up metres around ``home``.

    Args:
        home: The origin of the local frame.
        lat_deg: Latitude, degrees.
        lon_deg: Longitude, degrees.
        alt_m: Altitude above mean sea level (home's datum), metres.

    Returns:
        ``(x_m, y_m, z_m)``: East, North and Up offsets from home, metres.
    """
    x_m, y_m, z_m = pymap3d.geodetic2enu(
        lat_deg, lon_deg, alt_m, home.lat_deg, home.lon_deg, home.alt_m, deg=True
    )
    return float(x_m), float(y_m), float(z_m)


def ground_distance_m(a: Home, b: Home) -> float:
    """The distance along the WGS84 ellipsoid between two positions' latitude/longitude, metres."""
    if (a.lat_deg, a.lon_deg) == (b.lat_deg, b.lon_deg):
        return 0.0
    distance_m, _ = pymap3d.vincenty.vdist(a.lat_deg, a.lon_deg, b.lat_deg, b.lon_deg)
    return float(distance_m)
