"""The geofence: an East-North area and an altitude band around home.

Waypoints outside the fence are refused with :class:`bridge.errors.GeofenceError`
before any message is sent.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from bridge.errors import GeofenceError
from typed_config import Config, ConfigError, param

__all__ = ["GeofenceConfig", "check_geofence"]


@dataclass(frozen=True)
class GeofenceConfig(Config):
    """An axis-aligned East-North box (metres from home) and an altitude band (metres above home)."""

    x_min_m: float = param(-500.0, doc="western edge, metres East of home")
    x_max_m: float = param(500.0, doc="eastern edge, metres East of home")
    y_min_m: float = param(-500.0, doc="southern edge, metres North of home")
    y_max_m: float = param(500.0, doc="northern edge, metres North of home")
    alt_min_m: float = param(2.0, ge=0.0, doc="lowest allowed waypoint altitude above home, metres")
    alt_max_m: float = param(120.0, gt=0.0, le=10000.0, doc="highest allowed altitude above home, metres")

    def check(self) -> None:
        """Each interval must be non-empty."""
        for low, high in (("x_min_m", "x_max_m"), ("y_min_m", "y_max_m"), ("alt_min_m", "alt_max_m")):
            if getattr(self, low) >= getattr(self, high):
                raise ConfigError(
                    f"GeofenceConfig.{low} = {getattr(self, low)} must be < {high} = {getattr(self, high)}"
                )


def check_geofence(
    points_m: Sequence[tuple[float, float, float]],
    fence: GeofenceConfig,
    labels: Sequence[str] | None = None,
) -> None:
    """Refuse any point outside the fence.

    Args:
        points_m: ``(x_m, y_m, z_m)`` points, East/North/Up metres from home (``z_m`` above home).
        fence: The allowed area and altitude band.
        labels: How the user knows each point (``"target"``, ``"waypoint 2"``); default
            ``"waypoint <index>"``.

    Raises:
        GeofenceError: Naming the first offending point, its value and the allowed range.
    """
    for index, (x_m, y_m, z_m) in enumerate(points_m):
        label = labels[index] if labels is not None else f"waypoint {index}"
        for name, value, low, high in (
            ("x_m", x_m, fence.x_min_m, fence.x_max_m),
            ("y_m", y_m, fence.y_min_m, fence.y_max_m),
            ("z_m", z_m, fence.alt_min_m, fence.alt_max_m),
        ):
            if not low <= value <= high:
                raise GeofenceError(
                    f"{label}: {name} = {value:.2f} is outside the geofence: "
                    f"allowed {low} <= {name} <= {high}"
                )
