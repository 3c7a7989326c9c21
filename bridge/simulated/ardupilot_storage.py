"""How ArduPilot Copter stores a mission item and returns it on download (AP_Mission), for SimVehicle.

Written from ArduPilot's behaviour, independently of the bridge's own comparison rules
(``bridge.missions.compare``), so that the tests check one against the other.
"""

from __future__ import annotations

import math

from bridge.link.mavlink import use_mavlink2
from bridge.missions.items import MissionItem

m = use_mavlink2().mavlink

__all__ = ["stored_by_ardupilot"]

# ArduPilot's AP_Mission::stored_in_location, for the commands these tests use
_WITH_LOCATION = {
    m.MAV_CMD_NAV_WAYPOINT,
    m.MAV_CMD_NAV_LOITER_UNLIM,
    m.MAV_CMD_NAV_LOITER_TURNS,
    m.MAV_CMD_NAV_LOITER_TIME,
    m.MAV_CMD_NAV_LAND,
    m.MAV_CMD_NAV_TAKEOFF,
    m.MAV_CMD_NAV_SPLINE_WAYPOINT,
    m.MAV_CMD_DO_SET_ROI,
}
_DE_INT = {
    m.MAV_FRAME_GLOBAL_INT: m.MAV_FRAME_GLOBAL,
    m.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT: m.MAV_FRAME_GLOBAL_RELATIVE_ALT,
    m.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT: m.MAV_FRAME_GLOBAL_TERRAIN_ALT,
}


def stored_by_ardupilot(item: MissionItem, home: tuple[int, int, float]) -> MissionItem:
    """``item`` as AP_Mission keeps it: item 0 is the vehicle's ``home`` (degE7, degE7, metres)."""
    if item.seq == 0:  # always the vehicle's own home
        lat, lon, alt_m = home
        return MissionItem(seq=0, frame=m.MAV_FRAME_GLOBAL, command=m.MAV_CMD_NAV_WAYPOINT, x=lat, y=lon,
                           z=alt_m)
    params = [0.0 if math.isnan(p) else p for p in (item.param1, item.param2, item.param3, item.param4)]
    if item.command == m.MAV_CMD_NAV_WAYPOINT:
        params[1] = params[3] = 0.0  # Copter keeps only the delay
    if item.command == m.MAV_CMD_NAV_LOITER_TIME:
        params[2] = -1.0 if params[2] < 0 else 1.0  # only the direction
    located = item.command in _WITH_LOCATION
    return MissionItem(
        seq=item.seq,
        frame=_DE_INT.get(item.frame, item.frame) if located else m.MAV_FRAME_GLOBAL,
        command=item.command,
        param1=params[0],
        param2=params[1],
        param3=params[2],
        param4=params[3],
        x=item.x if located else 0,
        y=item.y if located else 0,
        z=round(item.z * 100) / 100 if located else 0.0,
    )
