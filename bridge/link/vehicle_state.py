"""Typed per-vehicle state built from the vehicle's MAVLink stream.

HEARTBEAT, GLOBAL_POSITION_INT, GPS_RAW_INT, EKF_STATUS_REPORT, SYS_STATUS, BATTERY_STATUS,
MISSION_CURRENT and MISSION_ITEM_REACHED from each vehicle's autopilot (component 1) update an
immutable :class:`VehicleState` snapshot, with the position also given back in local
East-North-Up metres around the configured home.

**No position without a fix.** ArduPilot sends GLOBAL_POSITION_INT before it has a position:
latitude 0, longitude 0 (thousands of kilometres from any real home). A position is kept only
while the vehicle has a fix: not that placeholder, GPS_RAW_INT's ``fix_type`` at least
``GPS_FIX_TYPE_3D_FIX`` when reported, and the EKF's absolute horizontal position valid when
EKF_STATUS_REPORT is reported. Otherwise the position and velocity fields are ``None`` and
:attr:`VehicleState.has_fix` is False.
"""

from __future__ import annotations

import dataclasses
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mavlink

from bridge.geo import Home, geodetic_to_enu

__all__ = ["VehicleState", "VehicleStateTracker"]

log = logging.getLogger(__name__)

_UINT16_UNKNOWN = 65535
_EKF_POSITION_OK = 16  # EKF_STATUS_REPORT flag EKF_POS_HORIZ_ABS (ArduPilot dialect)
_EKF_UNINITIALIZED = 1024  # EKF_STATUS_REPORT flag EKF_UNINITIALIZED
_POSITION_FIELDS = ("lat_deg", "lon_deg", "alt_m", "x_m", "y_m", "z_m", "vx_m_s", "vy_m_s", "vz_m_s")


@dataclass(frozen=True)
class VehicleState:
    """What we last heard from one vehicle. ``None`` means "not reported yet".

    Attributes:
        system_id: MAVLink system id.
        autopilot: ``MAV_AUTOPILOT_*`` from HEARTBEAT.
        vehicle_type: ``MAV_TYPE_*`` from HEARTBEAT.
        armed: Motors armed (``MAV_MODE_FLAG_SAFETY_ARMED``).
        mode: Flight mode name as pymavlink decodes it for this autopilot (e.g. ``"AUTO"``).
        system_status: ``MAV_STATE_*``.
        fix_type: GPS_RAW_INT's ``GPS_FIX_TYPE_*`` (None: not reported).
        ekf_position_ok: The EKF's absolute horizontal position is valid (EKF_STATUS_REPORT; None:
            not reported).
        lat_deg: WGS84 latitude, degrees (None without a fix, see the module docstring).
        lon_deg: WGS84 longitude, degrees.
        alt_m: Altitude above mean sea level, metres.
        relative_alt_m: Altitude above the vehicle's own home, metres.
        x_m: East of the configured home, metres.
        y_m: North of the configured home, metres.
        z_m: Up from the configured home, metres.
        vx_m_s: Velocity East, m/s.
        vy_m_s: Velocity North, m/s.
        vz_m_s: Velocity Up, m/s.
        heading_deg: Heading, degrees from North clockwise.
        battery_remaining_pct: Remaining battery, percent.
        battery_voltage_v: Battery voltage, volts.
        mission_seq_current: The mission item being flown (MISSION_CURRENT.seq).
        mission_total: Items in the vehicle's mission, when MISSION_CURRENT reports it.
        last_reached_seq: The last mission item reached (MISSION_ITEM_REACHED.seq).
        heartbeat_time_s: Unix time of the last HEARTBEAT, seconds.
        position_time_s: Unix time of the last GLOBAL_POSITION_INT, seconds.
        updated_time_s: Unix time of the last update of any field, seconds.
    """

    system_id: int
    autopilot: int | None = None
    vehicle_type: int | None = None
    armed: bool | None = None
    mode: str | None = None
    system_status: int | None = None
    fix_type: int | None = None
    ekf_position_ok: bool | None = None
    lat_deg: float | None = None
    lon_deg: float | None = None
    alt_m: float | None = None
    relative_alt_m: float | None = None
    x_m: float | None = None
    y_m: float | None = None
    z_m: float | None = None
    vx_m_s: float | None = None
    vy_m_s: float | None = None
    vz_m_s: float | None = None
    heading_deg: float | None = None
    battery_remaining_pct: float | None = None
    battery_voltage_v: float | None = None
    mission_seq_current: int | None = None
    mission_total: int | None = None
    last_reached_seq: int | None = None
    heartbeat_time_s: float | None = None
    position_time_s: float | None = None
    updated_time_s: float | None = None

    @property
    def has_fix(self) -> bool:
        """True when the vehicle reports a usable position (see the module docstring)."""
        return self.lat_deg is not None and self.lon_deg is not None

    def to_dict(self) -> dict[str, Any]:
        """Plain dict of the fields (for JSON)."""
        return dataclasses.asdict(self)


def _fix_lost(state: VehicleState) -> bool:
    """True when what the vehicle last said denies a fix: GPS below 3-D, or the EKF's position invalid."""
    return ((state.fix_type is not None and state.fix_type < mavlink.GPS_FIX_TYPE_3D_FIX)
            or state.ekf_position_ok is False)


def _heartbeat(msg: mavlink.MAVLink_message) -> dict[str, Any]:
    return {
        "autopilot": msg.autopilot,
        "vehicle_type": msg.type,
        "armed": bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED),
        "mode": mavutil.mode_string_v10(msg),
        "system_status": msg.system_status,
    }


def _position(msg: mavlink.MAVLink_message, home: Home) -> dict[str, Any]:
    if (msg.lat, msg.lon) == (0, 0):  # ArduPilot's "no position yet"
        return {**dict.fromkeys(_POSITION_FIELDS), "relative_alt_m": msg.relative_alt / 1000.0}
    lat_deg, lon_deg, alt_m = msg.lat / 1e7, msg.lon / 1e7, msg.alt / 1000.0
    x_m, y_m, z_m = geodetic_to_enu(home, lat_deg, lon_deg, alt_m)
    return {
        "lat_deg": lat_deg,
        "lon_deg": lon_deg,
        "alt_m": alt_m,
        "relative_alt_m": msg.relative_alt / 1000.0,
        "x_m": x_m,
        "y_m": y_m,
        "z_m": z_m,
        # GLOBAL_POSITION_INT: vx North, vy East, vz Down, cm/s.
        "vx_m_s": msg.vy / 100.0,
        "vy_m_s": msg.vx / 100.0,
        "vz_m_s": -msg.vz / 100.0,
        "heading_deg": None if msg.hdg == _UINT16_UNKNOWN else msg.hdg / 100.0,
    }


def _sys_status(msg: mavlink.MAVLink_message) -> dict[str, Any]:
    return {
        "battery_remaining_pct": None if msg.battery_remaining < 0 else float(msg.battery_remaining),
        "battery_voltage_v": None if msg.voltage_battery == _UINT16_UNKNOWN else msg.voltage_battery / 1000.0,
    }


def _battery_status(msg: mavlink.MAVLink_message) -> dict[str, Any]:
    cells_mv = [v for v in msg.voltages if v != _UINT16_UNKNOWN]
    return {
        "battery_remaining_pct": None if msg.battery_remaining < 0 else float(msg.battery_remaining),
        "battery_voltage_v": sum(cells_mv) / 1000.0 if cells_mv else None,
    }


def _ekf_status(msg: mavlink.MAVLink_message) -> dict[str, Any]:
    flags = msg.flags
    return {"ekf_position_ok": bool(flags & _EKF_POSITION_OK) and not flags & _EKF_UNINITIALIZED}


def _mission_current(msg: mavlink.MAVLink_message) -> dict[str, Any]:
    total = getattr(msg, "total", _UINT16_UNKNOWN)
    return {"mission_seq_current": msg.seq, "mission_total": None if total == _UINT16_UNKNOWN else total}


class VehicleStateTracker:
    """Folds vehicles' MAVLink messages into :class:`VehicleState` snapshots (thread-safe).

    Args:
        home: The origin of the ENU positions.
        component_id: Only messages from this component update the state (the autopilot).
    """

    MESSAGE_TYPES = frozenset(
        {
            "HEARTBEAT",
            "GLOBAL_POSITION_INT",
            "GPS_RAW_INT",
            "EKF_STATUS_REPORT",
            "SYS_STATUS",
            "BATTERY_STATUS",
            "MISSION_CURRENT",
            "MISSION_ITEM_REACHED",
        }
    )
    """The message types :meth:`update` uses (for :meth:`~bridge.link.mavlink.MavlinkLink.add_listener`)."""

    def __init__(self, home: Home, component_id: int = mavlink.MAV_COMP_ID_AUTOPILOT1) -> None:
        self._home = home
        self._component_id = component_id
        self._lock = threading.Lock()
        self._states: dict[int, VehicleState] = {}
        self._listeners: list[Callable[[VehicleState], None]] = []

    def add_listener(self, callback: Callable[[VehicleState], None]) -> None:
        """Call ``callback(state)`` after every update (from the link's reader thread: keep it short)."""
        with self._lock:
            self._listeners.append(callback)

    def update(self, msg: mavlink.MAVLink_message) -> None:
        """Fold one received message into its sender's state (other message types are ignored)."""
        if msg.get_srcComponent() != self._component_id:
            return
        kind = msg.get_type()
        now_s = time.time()
        changes: dict[str, Any]
        if kind == "HEARTBEAT":
            if msg.type == mavlink.MAV_TYPE_GCS:
                return
            changes = {**_heartbeat(msg), "heartbeat_time_s": now_s}
        elif kind == "GLOBAL_POSITION_INT":
            changes = {**_position(msg, self._home), "position_time_s": now_s}
        elif kind == "GPS_RAW_INT":
            changes = {"fix_type": msg.fix_type}
        elif kind == "EKF_STATUS_REPORT":
            changes = _ekf_status(msg)
        elif kind == "SYS_STATUS":
            changes = _sys_status(msg)
        elif kind == "BATTERY_STATUS":
            changes = _battery_status(msg)
        elif kind == "MISSION_CURRENT":
            changes = _mission_current(msg)
        elif kind == "MISSION_ITEM_REACHED":
            changes = {"last_reached_seq": msg.seq}
        else:
            return
        system_id = msg.get_srcSystem()
        with self._lock:
            old = self._states.get(system_id, VehicleState(system_id=system_id))
            state = dataclasses.replace(old, **changes, updated_time_s=now_s)
            if state.has_fix and _fix_lost(state):
                unknown: dict[str, Any] = dict.fromkeys(_POSITION_FIELDS)
                state = dataclasses.replace(state, **unknown)
            self._states[system_id] = state
            listeners = list(self._listeners)
        for callback in listeners:
            try:
                callback(state)
            except Exception:
                log.exception("vehicle state listener failed for vehicle %d", system_id)

    def state(self, system_id: int) -> VehicleState | None:
        """The latest snapshot of one vehicle, or ``None`` if nothing was heard from it."""
        with self._lock:
            return self._states.get(system_id)

    def states(self) -> dict[int, VehicleState]:
        """The latest snapshots of every vehicle heard, by system id."""
        with self._lock:
            return dict(self._states)
