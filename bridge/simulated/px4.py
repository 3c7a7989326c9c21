"""A simulated PX4 quadrotor: it answers as PX4 v1.16 does (its SIH quadrotor seen over MAVLink).

Written from PX4's sources (Commander, Navigator, the MAVLink receiver and mission manager at
v1.16.0) and from what real PX4 SITL did, independently of the bridge's own table:

- **HEARTBEAT**: ``MAV_AUTOPILOT_PX4``; ``custom_mode`` is PX4's union: main mode in bits 16-23,
  sub mode in bits 24-31 (AUTO.LOITER = main 4, sub 3). It boots in POSCTL (main 3).
- **Modes** (``MAV_CMD_DO_SET_MODE``, param2 the main mode, param3 the sub mode): POSCTL and
  AUTO.{TAKEOFF, LOITER, MISSION, RTL, LAND}; another sub mode of AUTO is denied.
- **Arming**: refused (``MAV_RESULT_TEMPORARILY_REJECTED``, STATUSTEXT "Preflight Fail: ...") for
  ``prearm_s`` after start.
- **Take-off** (``MAV_CMD_NAV_TAKEOFF``): param7 is the altitude above mean sea level; the vehicle
  switches to AUTO.TAKEOFF, climbs, and holds in AUTO.LOITER once there.
- **Reposition** (``MAV_CMD_DO_REPOSITION``, COMMAND_INT): needs param2's change-mode bit (else
  ``MAV_RESULT_UNSUPPORTED``), switches to AUTO.LOITER, and reads z as an altitude **above mean
  sea level whatever the frame says** (``MAV_FRAME_GLOBAL_RELATIVE_ALT_INT`` included). Sent below
  its home it descends to the ground: STATUSTEXT "Landing detected", then disarmed ("Disarmed by
  landing"). It moves only while armed.
- **Missions**: item 0 is the first real item (no home placeholder); AUTO.MISSION flies from the
  current item, item 0 included (a take-off item climbs where it stands). MISSION_CLEAR_ALL is
  accepted in any mode, flying or not. Mission transfers follow :class:`SimVehicle`'s ``"px4"``
  personality.
- **Streams** GLOBAL_POSITION_INT, MISSION_CURRENT and HOME_POSITION without being asked (its
  offboard and GCS links do), and answers ``MAV_CMD_REQUEST_MESSAGE`` for HOME_POSITION.
- **Flight** on :class:`~bridge.simulated.ardupilot.ArduCopter`'s point mass, with PX4's own limits
  (its parameters, at PX4's defaults): the cruise speed ``MPC_XY_CRUISE`` (or a reposition's ground
  speed, param1, when positive; or a mission's ``MAV_CMD_DO_CHANGE_SPEED``), never above
  ``MPC_XY_VEL_MAX``; ``MPC_ACC_HOR`` for acceleration and braking; ``MPC_TKO_SPEED`` climbing in
  AUTO.TAKEOFF, ``MPC_Z_V_AUTO_UP`` and ``MPC_Z_V_AUTO_DN`` otherwise; the smaller of
  ``MPC_ACC_UP_MAX`` and ``MPC_ACC_DOWN_MAX`` vertically. ``MPC_JERK_AUTO`` is served at its default;
  the point mass has no jerk limit.
- **The end**: AUTO.RTL climbs where it is to ``RTL_RETURN_ALT`` (metres above home; its altitude when
  higher; with ``RTL_CONE_ANG`` > 0, its default 45, lowered near home to ``distance / tan(angle)``, not
  below ``RTL_DESCEND_ALT``), flies home at it and lands; AUTO.LAND lands where it is; on the ground
  "Landing detected" and disarmed.
- **Data link loss** (Commander's GCS link check): once a ground station's heartbeat (``MAV_TYPE_GCS``, any
  system id) was heard, an armed vehicle that hears none for ``COM_DL_LOSS_T`` seconds after the heartbeat's
  own timeout (2.5 s, ``telemetry_status``'s ``HEARTBEAT_TIMEOUT_US``: the last heartbeat counts as heard that
  long), and ``COM_FAIL_ACT_T`` more (PX4 holds then; here it stays in the mode it was in), takes
  ``NAV_DLL_ACT``: 0 nothing (PX4's default), 1 hold (AUTO.LOITER), 2 AUTO.RTL, 3 AUTO.LAND. Parameters travel
  bytewise (PX4's ``PARAM_ENCODE_BYTEWISE``).
"""

from __future__ import annotations

import math
import time
from typing import Any

from bridge.geo import Home, geodetic_to_enu
from bridge.missions.items import DEG_E7
from bridge.simulated.ardupilot import ArduCopter
from bridge.simulated.dynamics import AutopilotLimits
from bridge.simulated.peer import m

__all__ = ["Px4Copter", "POSCTL", "TAKEOFF", "LOITER", "MISSION", "RTL", "LAND", "px4_mode", "PX4_PARAMS",
           "FAILSAFE_ON"]

POSCTL, TAKEOFF, LOITER, MISSION, RTL, LAND = (3, 0), (4, 2), (4, 3), (4, 4), (4, 5), (4, 6)
_MODES = (POSCTL, TAKEOFF, LOITER, MISSION, RTL, LAND)
_HOME_PERIOD_S = 1.0
_ARRIVED_M = 0.5
_POSITIONED = (m.MAV_CMD_NAV_WAYPOINT, m.MAV_CMD_NAV_LOITER_UNLIM, m.MAV_CMD_NAV_LOITER_TIME)
_INT32, _REAL32 = m.MAV_PARAM_TYPE_INT32, m.MAV_PARAM_TYPE_REAL32
PX4_PARAMS = {
    "NAV_DLL_ACT": (0.0, _INT32), "COM_DL_LOSS_T": (10.0, _INT32), "RTL_RETURN_ALT": (60.0, _REAL32),
    "GF_ACTION": (2.0, _INT32), "MIS_TAKEOFF_ALT": (2.5, _REAL32), "RTL_CONE_ANG": (45.0, _INT32),
    "RTL_TYPE": (0.0, _INT32), "RTL_DESCEND_ALT": (30.0, _REAL32), "COM_FAIL_ACT_T": (5.0, _REAL32),
    "MPC_XY_CRUISE": (5.0, _REAL32), "MPC_XY_VEL_MAX": (12.0, _REAL32), "MPC_ACC_HOR": (3.0, _REAL32),
    "MPC_JERK_AUTO": (4.0, _REAL32), "MPC_TKO_SPEED": (1.5, _REAL32), "MPC_Z_V_AUTO_UP": (3.0, _REAL32),
    "MPC_Z_V_AUTO_DN": (1.5, _REAL32), "MPC_ACC_UP_MAX": (4.0, _REAL32), "MPC_ACC_DOWN_MAX": (3.0, _REAL32)}
"""PX4 v1.16's defaults of the parameters ``fly`` and its guard read (value, ``MAV_PARAM_TYPE``)."""
_DLL_MODES = {1: LOITER, 2: RTL, 3: LAND}
FAILSAFE_ON = {"NAV_DLL_ACT": 2.0}
"""PX4's data link loss action set to Return (``params`` of a vehicle an operator prepared)."""
_HEARTBEAT_TIMEOUT_S = 2.5  # a heartbeat counts as heard this long (PX4's mavlink receiver)
_SLOWEST = 0.1  # m/s or m/s^2: PX4 keeps its speeds and accelerations above a positive floor


def px4_mode(custom_mode: int) -> tuple[int, int]:
    """``(main, sub)`` of a PX4 HEARTBEAT ``custom_mode``."""
    return (custom_mode >> 16) & 0xFF, (custom_mode >> 24) & 0xFF


def _custom_mode(mode: tuple[int, int]) -> int:
    return mode[0] << 16 | mode[1] << 24


class Px4Copter(ArduCopter):
    """A PX4 quadrotor at ``home`` (see the module docstring); :class:`ArduCopter`'s point mass.

    Args:
        url: Its end of the link (PX4's offboard link sends to UDP 14540 + instance: ``udpout:``).
        system_id: Its MAVLink system id.
        home: Where it stands at start (its home).
        **options: :class:`ArduCopter`'s (``realism``, ``rng``, ``prearm_s``, ``position_period_s``,
            ``params``).
    """

    def __init__(self, url: str, system_id: int, *, home: Home | None = None, **options: Any) -> None:
        self.mode = POSCTL
        self.texts: list[str] = []
        self.landed_in: list[tuple[int, int]] = []
        self._cruise_m_s: float | None = None
        self._next_home_s = 0.0
        options.setdefault("stream_until_asked", False)
        super().__init__(url, system_id, home=home, autopilot=m.MAV_AUTOPILOT_PX4,
                         custom_mode=_custom_mode(POSCTL), personality="px4", **options)

    def _default_params(self) -> dict[str, tuple[float, int]]:
        return dict(PX4_PARAMS)

    def limits(self) -> AutopilotLimits:
        """How it flies now: its ``MPC_*`` parameters and the speed it was last asked for."""
        p = {name: max(_SLOWEST, self.param(name)) for name in PX4_PARAMS if name.startswith("MPC_")}
        cruise_m_s = self._cruise_m_s if self._cruise_m_s is not None else p["MPC_XY_CRUISE"]
        climb_m_s = p["MPC_TKO_SPEED"] if self.mode == TAKEOFF else p["MPC_Z_V_AUTO_UP"]
        return AutopilotLimits(max_speed_m_s=min(cruise_m_s, p["MPC_XY_VEL_MAX"]),
                               max_accel_m_s2=p["MPC_ACC_HOR"], climb_m_s=climb_m_s,
                               descent_m_s=p["MPC_Z_V_AUTO_DN"],
                               vertical_accel_m_s2=min(p["MPC_ACC_UP_MAX"], p["MPC_ACC_DOWN_MAX"]))

    def _watches(self, gcs_system_id: int) -> bool:
        return True  # any ground station's heartbeat keeps PX4's data link

    def _check_failsafe(self) -> None:
        action, silent_s = int(self.param("NAV_DLL_ACT")), self._silent_s()
        hold_s = self.param("COM_FAIL_ACT_T") if "COM_FAIL_ACT_T" in self.params else 0.0  # older PX4: none
        waits_s = _HEARTBEAT_TIMEOUT_S + self.param("COM_DL_LOSS_T") + hold_s
        if (action not in _DLL_MODES or not self.armed or self.mode in (RTL, LAND) or silent_s is None
                or silent_s < waits_s or self._setpoint()[2] <= 0.0 or self.failsafes):
            return
        self.failsafes.append(time.monotonic())
        self._say("Connection to ground station lost", m.MAV_SEVERITY_CRITICAL)
        self.set_mode(_DLL_MODES[action])

    def _rtl_alt_m(self) -> float:
        return self.param("RTL_RETURN_ALT")

    def _return_alt_for(self, distance_m: float, z_m: float) -> float:
        """PX4's return altitude: ``RTL_RETURN_ALT``, lowered by its cone near home.

        Within ``RTL_CONE_ANG`` of home it is ``distance / tan(angle)``, not below ``RTL_DESCEND_ALT``; never
        below where it is.
        """
        target = self._rtl_alt_m()
        angle_deg = self.param("RTL_CONE_ANG")
        if 0 < angle_deg < 90:
            cone_m = distance_m / math.tan(math.radians(angle_deg))
            target = min(target, max(cone_m, self.param("RTL_DESCEND_ALT")))
        return max(target, z_m)

    def _returning(self) -> bool:
        return self.mode == RTL

    # -- modes ---------------------------------------------------------------------------------
    def set_mode(self, mode: tuple[int, int]) -> None:
        """Switch to ``(main, sub)``, as a mode change on the vehicle does."""
        self.mode = mode
        self._switch(_custom_mode(mode))

    def _say(self, text: str, severity: int = m.MAV_SEVERITY_INFO) -> None:
        self.texts.append(text)
        self._conn.mav.statustext_send(severity=severity, text=text.encode())

    # -- flight --------------------------------------------------------------------------------
    def _mission_target(self) -> tuple[float, float, float] | None:
        while 0 <= self.current_seq < len(self.mission):
            item = self.mission[self.current_seq]
            if item.command == m.MAV_CMD_NAV_TAKEOFF:
                x, y, _ = self._setpoint()
                target = (x, y, item.z)
            elif item.command in _POSITIONED:
                target = self._item_enu(item)
            else:
                if item.command == m.MAV_CMD_DO_CHANGE_SPEED and item.param2 > 0:
                    self._cruise_m_s = item.param2
                self.current_seq += 1
                continue
            passing = item.command in (m.MAV_CMD_NAV_TAKEOFF, m.MAV_CMD_NAV_WAYPOINT)
            if passing and math.dist(target, self._setpoint()) < _ARRIVED_M:
                self.reached_seq = self.current_seq
                self.current_seq += 1
                continue
            return target
        return None

    def _flight_goal(self) -> tuple[float, float, float] | None:
        if not self.armed:
            return None
        if self.mode in (TAKEOFF, LOITER):
            return self.target
        if self.mode == MISSION:
            return self._mission_target()
        if self.mode == RTL:
            return self._rtl_goal()
        if self.mode == LAND:
            x, y, _ = self._setpoint()
            return (x, y, 0.0)
        return None

    def _after_step(self, goal: tuple[float, float, float] | None) -> None:
        x, y, z = self._setpoint()
        if self.mode == TAKEOFF and self.target is not None and abs(self.target[2] - z) < 0.3:
            self.set_mode(LOITER)  # take-off done: PX4 holds there
        if not self.armed or goal is None or goal[2] != 0.0 or z > 0.01:
            return
        if self.mode != RTL or math.hypot(goal[0] - x, goal[1] - y) < _ARRIVED_M:
            self._touch_down()
            self.landed_in.append(self.mode)
            self._say("Landing detected")
            self._say("Disarmed by landing")

    def _telemetry(self) -> None:
        super()._telemetry()
        now_s = time.monotonic()
        if now_s >= self._next_home_s:
            self._next_home_s = now_s + _HOME_PERIOD_S
            lat, lon, alt_m = self.home
            self._conn.mav.home_position_send(
                latitude=lat, longitude=lon, altitude=round(alt_m * 1000), x=0.0, y=0.0, z=0.0,
                q=[1.0, 0.0, 0.0, 0.0], approach_x=0.0, approach_y=0.0, approach_z=0.0)

    # -- commands ------------------------------------------------------------------------------
    def _command(self, msg) -> int:
        if msg.command == m.MAV_CMD_DO_SET_MODE:
            mode = (int(msg.param2), int(msg.param3) if int(msg.param2) == 4 else 0)
            if not int(msg.param1) & m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED or mode not in _MODES:
                return m.MAV_RESULT_DENIED
            self.set_mode(mode)
            return m.MAV_RESULT_ACCEPTED
        if msg.command == m.MAV_CMD_COMPONENT_ARM_DISARM:
            if msg.param1 == 1.0 and time.monotonic() < self._ready_at_s:
                self._say("Preflight Fail: ekf2 missing data", m.MAV_SEVERITY_CRITICAL)
                return m.MAV_RESULT_TEMPORARILY_REJECTED
            self.armed = msg.param1 == 1.0
            return m.MAV_RESULT_ACCEPTED
        if msg.command == m.MAV_CMD_NAV_TAKEOFF:
            finite = math.isfinite(msg.param7)
            height_m = msg.param7 - self.geo_home.alt_m if finite else self.param("MIS_TAKEOFF_ALT")
            x, y, _ = self._setpoint()
            self.target = (x, y, height_m)
            self.set_mode(TAKEOFF)
            return m.MAV_RESULT_ACCEPTED
        if msg.command in (m.MAV_CMD_NAV_RETURN_TO_LAUNCH, m.MAV_CMD_NAV_LAND):
            self.set_mode(RTL if msg.command == m.MAV_CMD_NAV_RETURN_TO_LAUNCH else LAND)
            return m.MAV_RESULT_ACCEPTED
        return super()._command(msg)

    def _on_command_int(self, msg) -> None:
        self.commands.append(msg.command)
        if msg.command != m.MAV_CMD_DO_REPOSITION:
            self._answer(msg, m.MAV_RESULT_UNSUPPORTED)
            return
        if int(msg.param2) != m.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE:
            self._answer(msg, m.MAV_RESULT_UNSUPPORTED)  # Commander: only the change-mode bit
            return
        self.reposition_frames.append(msg.frame)
        if self.armed:  # Navigator takes the setpoint only armed; the mode changes anyway
            x, y, _ = geodetic_to_enu(self.geo_home, msg.x / DEG_E7, msg.y / DEG_E7, self.geo_home.alt_m)
            self.target = (x, y, msg.z - self.geo_home.alt_m)  # z above sea level, whatever the frame
            self.reposition_target = (msg.x, msg.y, msg.z)
            asked = math.isfinite(msg.param1) and msg.param1 > 0  # the ground speed, else the default
            self._cruise_m_s = msg.param1 if asked else None
        self.set_mode(LOITER)
        self._answer(msg, m.MAV_RESULT_ACCEPTED)

    def _on_mission_clear_all(self, msg) -> None:
        self.mission, self.current_seq = [], 0  # PX4 clears whatever it flies
        self._ack(msg, m.MAV_MISSION_ACCEPTED)
