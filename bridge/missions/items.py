"""A UAV's plan as MAVLink mission items (``MISSION_ITEM_INT``).

Mission shape, for waypoints ``w_0 .. w_k`` in local East-North-Up metres:

====  ==========================================  ==================================
seq   command                                      frame
====  ==========================================  ==================================
0     ArduPilot only: home placeholder             ``MAV_FRAME_GLOBAL_INT`` (AMSL)
      (``MAV_CMD_NAV_WAYPOINT`` at home)
.     ``MAV_CMD_NAV_TAKEOFF`` to ``takeoff_alt_m``  ``MAV_FRAME_GLOBAL_RELATIVE_ALT_INT``
.     optional ``MAV_CMD_DO_CHANGE_SPEED``         ``MAV_FRAME_MISSION``
      (``speed_m_s`` > 0: ground speed)
.     ``MAV_CMD_NAV_WAYPOINT`` per waypoint        ``MAV_FRAME_GLOBAL_RELATIVE_ALT_INT``
.     ``MAV_CMD_NAV_LOITER_UNLIM`` or
      ``MAV_CMD_NAV_LOITER_TIME`` at the last one  ``MAV_FRAME_GLOBAL_RELATIVE_ALT_INT``
.     optional ``MAV_CMD_NAV_RETURN_TO_LAUNCH``    ``MAV_FRAME_MISSION``
====  ==========================================  ==================================

Coordinates are degE7 integers, altitudes metres above home (AMSL for the
placeholder): a waypoint's ``z_m`` is used as its height above home as is (the
Earth-curvature gap between ENU Up and height, under 1 cm within 350 m, is ignored).
Item 0 is the only one marked current. Parameters and altitudes are stored as
float32 values, exactly what travels in the MAVLink message.

Altitudes (one model, :func:`takeoff_altitude`): 2-D waypoints fly at ``cruise_alt_m``;
the take-off climbs to ``takeoff_alt_m``, or to the first waypoint's altitude when that
is lower, so a mission never descends after take-off unless the user's own points do.
The user numbers points as ``waypoint 1 .. k`` (intermediate, in order) and ``target``
(the last); refusals use those names.

Whether item 0 is the home placeholder is the autopilot's convention
(:attr:`bridge.autopilots.Conventions.home_item`: ArduPilot's, not PX4's, whose item 0 is the
take-off). Verification of a mission read back is :mod:`bridge.missions.compare`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pymavlink.dialects.v20 import common as mavlink

from bridge.autopilots import conventions_for
from bridge.geo import Home, enu_to_geodetic
from bridge.geofence import GeofenceConfig, check_geofence
from typed_config import Config, ConfigError, param

__all__ = [
    "MissionConfig",
    "MissionItem",
    "Mission",
    "build_mission",
    "home_placeholder",
    "mark_current",
    "waypoints_enu",
    "point_labels",
    "takeoff_altitude",
    "DEG_E7",
]

DEG_E7 = 10_000_000
"""Scale of MISSION_ITEM_INT latitude/longitude integers (degrees * 1e7)."""


def _f32(value: float) -> float:
    return float(np.float32(value))


@dataclass(frozen=True, eq=False)
class MissionItem:
    """One ``MISSION_ITEM_INT``, field for field (params and ``z`` rounded to float32).

    Equality treats NaN parameters as equal (MAVLink uses NaN for "unset", e.g. yaw).

    Attributes:
        seq: Sequence number, 0-based.
        frame: ``MAV_FRAME_*``.
        command: ``MAV_CMD_*``.
        current: 1 for the item the mission starts at, else 0.
        autocontinue: 1 to continue to the next item when this one completes.
        param1: Command parameter 1.
        param2: Command parameter 2.
        param3: Command parameter 3.
        param4: Command parameter 4.
        x: Latitude, degE7 (global frames).
        y: Longitude, degE7 (global frames).
        z: Altitude, metres (meaning set by ``frame``).
        mission_type: ``MAV_MISSION_TYPE_*`` (missions only here).
    """

    seq: int
    frame: int
    command: int
    current: int = 0
    autocontinue: int = 1
    param1: float = 0.0
    param2: float = 0.0
    param3: float = 0.0
    param4: float = 0.0
    x: int = 0
    y: int = 0
    z: float = 0.0
    mission_type: int = field(default=mavlink.MAV_MISSION_TYPE_MISSION)

    def __post_init__(self) -> None:
        for name in ("seq", "frame", "command", "current", "autocontinue", "x", "y", "mission_type"):
            object.__setattr__(self, name, int(getattr(self, name)))
        for name in ("param1", "param2", "param3", "param4", "z"):
            object.__setattr__(self, name, _f32(getattr(self, name)))

    def _key(self) -> tuple[object, ...]:
        values = (getattr(self, name) for name in self.__dataclass_fields__)
        return tuple("nan" if isinstance(v, float) and v != v else v for v in values)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, MissionItem) and self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())

    def message_fields(self) -> dict[str, Any]:
        """Keyword arguments for ``mission_item_int_send`` (without target ids)."""
        return {name: getattr(self, name) for name in self.__dataclass_fields__}


@dataclass(frozen=True)
class Mission:
    """A vehicle's mission: its items, the home they were built around, the autopilot convention.

    Attributes:
        home: The geodetic origin (ENU frame, ArduPilot placeholder, ``.plan`` planned home).
        items: The mission items, ``seq`` 0..n-1.
        autopilot: ``MAV_AUTOPILOT_*`` whose conventions the items follow.
    """

    home: Home
    items: tuple[MissionItem, ...]
    autopilot: int = mavlink.MAV_AUTOPILOT_GENERIC

    def __post_init__(self) -> None:
        for index, item in enumerate(self.items):
            if item.seq != index:
                raise ValueError(f"Mission.items[{index}].seq = {item.seq}: items must be numbered 0..n-1")

    @property
    def has_home_placeholder(self) -> bool:
        """True when item 0 is the home placeholder (ArduPilot's convention)."""
        return conventions_for(self.autopilot).home_item and len(self.items) > 0


@dataclass(frozen=True)
class MissionConfig(Config):
    """How a plan becomes a mission: take-off, cruise altitude, loiter and return."""

    takeoff_alt_m: float = param(20.0, gt=0.0, le=1000.0, doc="take-off altitude above home, metres")
    cruise_alt_m: float = param(30.0, gt=0.0, le=1000.0, doc="altitude above home of 2-D waypoints, metres")
    acceptance_radius_m: float = param(2.0, ge=0.0, le=100.0, doc="waypoint acceptance radius, metres")
    loiter_time_s: float = param(0.0, ge=0.0, le=86400.0, doc="loiter at the target: 0 = unlimited, else s")
    loiter_radius_m: float = param(0.0, ge=0.0, le=1000.0, doc="loiter radius (fixed wing), 0 = default")
    return_to_launch: bool = param(False, doc="append MAV_CMD_NAV_RETURN_TO_LAUNCH after a timed loiter")
    speed_m_s: float = param(0.0, ge=0.0, le=100.0,
                             doc="ground speed of the legs (MAV_CMD_DO_CHANGE_SPEED after take-off); "
                                 "0 = the vehicle's own mission speed")

    def check(self) -> None:
        """An unlimited loiter never ends, so a return-to-launch after it could never run."""
        if self.return_to_launch and self.loiter_time_s == 0.0:
            raise ConfigError(
                "MissionConfig.return_to_launch = true needs a timed loiter: set loiter_time_s > 0 "
                "(0 means loiter forever)"
            )


def point_labels(count: int) -> list[str]:
    """The user's names of a plan's points: ``waypoint 1 .. count-1``, then ``target``."""
    return [f"waypoint {i}" for i in range(1, count)] + ["target"] if count else []


def takeoff_altitude(points: Sequence[tuple[float, float, float]], config: MissionConfig) -> float:
    """The take-off altitude: ``config.takeoff_alt_m``, or the first point's altitude when that is lower.

    So a mission never descends after take-off unless the user's own points do.
    """
    return min(config.takeoff_alt_m, points[0][2]) if points else config.takeoff_alt_m


def waypoints_enu(
    points_m: Sequence[Sequence[float]], cruise_alt_m: float
) -> list[tuple[float, float, float]]:
    """Normalise ``(x_m, y_m)`` or ``(x_m, y_m, z_m)`` points to 3-D, 2-D ones at ``cruise_alt_m``.

    Raises:
        ValueError: A point with other than 2 or 3 coordinates, or no point at all.
    """
    out = []
    labels = point_labels(len(points_m))
    for index, point in enumerate(points_m):
        values = [float(v) for v in point]
        if len(values) not in (2, 3):
            raise ValueError(
                f"{labels[index]} = {tuple(point)}: a waypoint must be (x_m, y_m) or (x_m, y_m, z_m)"
            )
        out.append((values[0], values[1], values[2] if len(values) == 3 else cruise_alt_m))
    if not out:
        raise ValueError("a plan needs at least one waypoint (the target)")
    return out


def _global_item(
    seq: int, command: int, home: Home, point_m: tuple[float, float, float], **params: Any
) -> MissionItem:
    lat_deg, lon_deg, _ = enu_to_geodetic(home, *point_m)
    return MissionItem(
        seq=seq,
        frame=mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
        command=command,
        x=round(lat_deg * DEG_E7),
        y=round(lon_deg * DEG_E7),
        z=point_m[2],
        **params,
    )


def home_placeholder(home: Home) -> MissionItem:
    """ArduPilot's seq-0 home item: a waypoint at home, altitude above mean sea level."""
    return MissionItem(
        seq=0,
        frame=mavlink.MAV_FRAME_GLOBAL_INT,
        command=mavlink.MAV_CMD_NAV_WAYPOINT,
        x=round(home.lat_deg * DEG_E7),
        y=round(home.lon_deg * DEG_E7),
        z=home.alt_m,
    )


def mark_current(items: Sequence[MissionItem]) -> tuple[MissionItem, ...]:
    """The items with item 0 current and every other item not."""
    return tuple(MissionItem(**{**item.message_fields(), "current": int(item.seq == 0)}) for item in items)


def build_mission(
    points_m: Sequence[Sequence[float]],
    home: Home,
    config: MissionConfig,
    fence: GeofenceConfig,
    autopilot: int = mavlink.MAV_AUTOPILOT_GENERIC,
) -> Mission:
    """Turn a plan (ENU waypoints, the last one the target) into a mission.

    Args:
        points_m: Waypoints ``(x_m, y_m)`` or ``(x_m, y_m, z_m)``, East/North/Up metres from home;
            the last is where the UAV loiters. 2-D points fly at ``config.cruise_alt_m``; the
            take-off altitude is :func:`takeoff_altitude`.
        home: Geodetic origin of the ENU frame.
        config: Take-off, loiter and return settings.
        fence: The allowed area and altitude band; checked before anything is built.
        autopilot: ``MAV_AUTOPILOT_*`` of the vehicle (ArduPilot gets a home placeholder at seq 0,
            PX4's take-off is item 0).

    Returns:
        The mission; item 0 is the only current one.

    Raises:
        GeofenceError: A waypoint (or the take-off altitude) is outside the fence.
        ValueError: Malformed waypoints.
    """
    points = waypoints_enu(points_m, config.cruise_alt_m)
    takeoff_alt_m = takeoff_altitude(points, config)
    check_geofence([*points, (0.0, 0.0, takeoff_alt_m)], fence, [*point_labels(len(points)), "take-off"])
    items: list[MissionItem] = []
    if conventions_for(autopilot).home_item:
        items.append(home_placeholder(home))
    items.append(
        _global_item(
            len(items),
            mavlink.MAV_CMD_NAV_TAKEOFF,
            home,
            (0.0, 0.0, takeoff_alt_m),
            param4=float("nan"),
        )
    )
    if config.speed_m_s > 0.0:  # param1 1: ground speed; param3 -1: throttle unchanged
        items.append(MissionItem(seq=len(items), frame=mavlink.MAV_FRAME_MISSION,
                                 command=mavlink.MAV_CMD_DO_CHANGE_SPEED, param1=1.0,
                                 param2=config.speed_m_s, param3=-1.0))
    for point in points:
        items.append(
            _global_item(
                len(items),
                mavlink.MAV_CMD_NAV_WAYPOINT,
                home,
                point,
                param2=config.acceptance_radius_m,
                param4=float("nan"),
            )
        )
    if config.loiter_time_s > 0.0:
        items.append(
            _global_item(
                len(items),
                mavlink.MAV_CMD_NAV_LOITER_TIME,
                home,
                points[-1],
                param1=config.loiter_time_s,
                param3=config.loiter_radius_m,
            )
        )
    else:
        items.append(
            _global_item(
                len(items),
                mavlink.MAV_CMD_NAV_LOITER_UNLIM,
                home,
                points[-1],
                param3=config.loiter_radius_m,
                param4=float("nan"),
            )
        )
    if config.return_to_launch:
        items.append(
            MissionItem(
                seq=len(items), frame=mavlink.MAV_FRAME_MISSION, command=mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH
            )
        )
    return Mission(home=home, items=mark_current(items), autopilot=autopilot)
