"""A test vehicle that boots as ArduCopter SITL does: no fix, then a fix, then a home; nothing unasked.

Written from ArduCopter's observable behaviour right after boot (independently of the bridge):

- **No position for ``fix_after_s``**: GLOBAL_POSITION_INT carries latitude 0, longitude 0 (its
  placeholder), GPS_RAW_INT ``GPS_FIX_TYPE_NO_FIX``; then a 3-D fix. The EKF's absolute position
  (EKF_STATUS_REPORT ``EKF_POS_HORIZ_ABS``) and the home come only at ``home_after_s``, later
  still; HOME_POSITION is not sent before.
- **Pre-arm checks**: until then arming is refused (``MAV_RESULT_FAILED``) and so is a switch to
  GUIDED or AUTO, each with STATUSTEXT "PreArm: Need Position Estimate", also repeated every second.
- **Nothing streamed on a new link until asked**: only HEARTBEAT (and STATUSTEXT); each of
  GLOBAL_POSITION_INT, GPS_RAW_INT, EKF_STATUS_REPORT, MISSION_CURRENT and HOME_POSITION comes
  once asked, at the interval of ``MAV_CMD_SET_MESSAGE_INTERVAL`` or once per
  ``MAV_CMD_REQUEST_MESSAGE`` (which is ACCEPTED, as ArduPilot does, even when there is no home to send).
- **Missions as AP_Mission** (``SimVehicle``'s ``"ardupilot"`` personality): MISSION_CLEAR_ALL while
  flying in AUTO is refused with ``MAV_MISSION_ERROR``.

A restart is a new :class:`BootingCopter` on the same endpoint: it boots again.
"""

from __future__ import annotations

import time

from bridge.missions.items import DEG_E7
from bridge.simulated.ardupilot import AUTO, GUIDED, ArduCopter
from bridge.simulated.peer import m

__all__ = ["BootingCopter", "PREARM_TEXT"]

PREARM_TEXT = "PreArm: Need Position Estimate"
_STREAMABLE = (m.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, m.MAVLINK_MSG_ID_GPS_RAW_INT,
               m.MAVLINK_MSG_ID_EKF_STATUS_REPORT, m.MAVLINK_MSG_ID_MISSION_CURRENT,
               m.MAVLINK_MSG_ID_HOME_POSITION)
_EKF_READY = m.EKF_ATTITUDE | m.EKF_VELOCITY_HORIZ | m.EKF_POS_HORIZ_REL | m.EKF_POS_HORIZ_ABS
_HEARTBEAT_S = 0.2
_PREARM_TEXT_S = 1.0


class BootingCopter(ArduCopter):
    """A :class:`ArduCopter` that boots as ArduCopter (see the module docstring).

    Args:
        url: Its end of the link.
        system_id: Its MAVLink system id.
        fix_after_s: Its GPS 3-D fix, this long after start.
        home_after_s: Its EKF position and home (arming allowed), this long after start.
        answer_mission_current: Send MISSION_CURRENT when asked (False: never, streamed or requested).
        climbed_mark_m: :attr:`climbed_s` is the time it first rose above this height.
        **options: :class:`ArduCopter`'s.
    """

    def __init__(self, url: str, system_id: int, *, fix_after_s: float = 2.0, home_after_s: float = 4.0,
                 answer_mission_current: bool = True, climbed_mark_m: float = 8.9, **options) -> None:
        self.boot_s = time.monotonic()
        self.fix_after_s, self.home_after_s = fix_after_s, home_after_s
        self.answer_mission_current = answer_mission_current
        self.climbed_mark_m = climbed_mark_m
        self.climbed_s: float | None = None
        self.intervals_s: dict[int, float] = {}
        self.clears_received = 0
        self.counts_before_home = 0
        self.zero_positions_sent = 0
        self._due_s: dict[int, float] = {}
        self._next_heartbeat_s = 0.0
        self._next_prearm_s = 0.0
        super().__init__(url, system_id, position_period_s=0.05, stream_until_asked=True,
                         personality="ardupilot", **options)

    # -- boot ----------------------------------------------------------------------------------
    def has_fix(self) -> bool:
        """Its GPS has a 3-D fix."""
        return time.monotonic() - self.boot_s >= self.fix_after_s

    def home_set(self) -> bool:
        """Its EKF has a position and its home is set (pre-arm checks pass)."""
        return time.monotonic() - self.boot_s >= self.home_after_s

    def _prearm_text(self) -> None:
        self._conn.mav.statustext_send(severity=m.MAV_SEVERITY_CRITICAL, text=PREARM_TEXT.encode())

    # -- sending -------------------------------------------------------------------------------
    def _send(self, message_id: int) -> None:
        mav, fix = self._conn.mav, self.has_fix()
        lat_e7, lon_e7, alt_m = self._geodetic_e7()
        if message_id == m.MAVLINK_MSG_ID_GLOBAL_POSITION_INT:
            if not fix:
                self.zero_positions_sent += 1
            vx, vy, vz = self.velocity
            mav.global_position_int_send(
                time_boot_ms=int((time.monotonic() - self.boot_s) * 1000), lat=lat_e7 if fix else 0,
                lon=lon_e7 if fix else 0, alt=round(alt_m * 1000) if fix else 0,
                relative_alt=round(self.enu[2] * 1000), vx=round(vy * 100), vy=round(vx * 100),
                vz=round(-vz * 100), hdg=0)
        elif message_id == m.MAVLINK_MSG_ID_GPS_RAW_INT:
            mav.gps_raw_int_send(
                time_usec=int((time.monotonic() - self.boot_s) * 1e6),
                fix_type=m.GPS_FIX_TYPE_3D_FIX if fix else m.GPS_FIX_TYPE_NO_FIX, lat=lat_e7 if fix else 0,
                lon=lon_e7 if fix else 0, alt=round(alt_m * 1000) if fix else 0, eph=65535, epv=65535,
                vel=65535, cog=65535, satellites_visible=10 if fix else 0)
        elif message_id == m.MAVLINK_MSG_ID_EKF_STATUS_REPORT:
            flags = _EKF_READY if self.home_set() else m.EKF_ATTITUDE
            mav.ekf_status_report_send(flags=flags, velocity_variance=0.0, pos_horiz_variance=0.0,
                                       pos_vert_variance=0.0, compass_variance=0.0, terrain_alt_variance=0.0)
        elif message_id == m.MAVLINK_MSG_ID_MISSION_CURRENT and self.answer_mission_current:
            mav.mission_current_send(seq=self.current_seq, total=len(self.mission))
        elif message_id == m.MAVLINK_MSG_ID_HOME_POSITION and self.home_set():
            lat, lon, home_alt_m = self.home
            mav.home_position_send(latitude=lat, longitude=lon, altitude=round(home_alt_m * 1000), x=0.0,
                                   y=0.0, z=0.0, q=[1.0, 0.0, 0.0, 0.0], approach_x=0.0, approach_y=0.0,
                                   approach_z=0.0)

    def _geodetic_e7(self) -> tuple[int, int, float]:
        from bridge.geo import enu_to_geodetic

        lat_deg, lon_deg, alt_m = enu_to_geodetic(self.geo_home, *self.enu)
        return round(lat_deg * DEG_E7), round(lon_deg * DEG_E7), alt_m

    def _telemetry(self) -> None:
        self._step()
        if self.climbed_s is None and self.armed and self.enu[2] >= self.climbed_mark_m:
            self.climbed_s = time.time()
        now_s = time.monotonic()
        if now_s >= self._next_heartbeat_s:
            self._next_heartbeat_s = now_s + _HEARTBEAT_S
            armed = m.MAV_MODE_FLAG_SAFETY_ARMED if self.armed else 0
            status = m.MAV_STATE_ACTIVE if self.armed else m.MAV_STATE_STANDBY
            self._conn.mav.heartbeat_send(type=m.MAV_TYPE_QUADROTOR, autopilot=self.autopilot,
                                          base_mode=m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | armed,
                                          custom_mode=self.custom_mode, system_status=status)
        if not self.home_set() and now_s >= self._next_prearm_s:
            self._next_prearm_s = now_s + _PREARM_TEXT_S
            self._prearm_text()
        for message_id, period_s in list(self.intervals_s.items()):
            if now_s >= self._due_s.get(message_id, 0.0):
                self._due_s[message_id] = now_s + period_s
                self._send(message_id)

    # -- commands ------------------------------------------------------------------------------
    def _on_command_long(self, msg) -> None:
        self.commands.append(msg.command)
        if msg.command == m.MAV_CMD_REQUEST_MESSAGE:
            message_id = int(msg.param1)
            if message_id not in _STREAMABLE:
                self._answer(msg, m.MAV_RESULT_FAILED)
                return
            self._answer(msg, m.MAV_RESULT_ACCEPTED)  # also with no home yet: nothing is then sent
            self._send(message_id)
            return
        self._answer(msg, self._command(msg))

    def _command(self, msg) -> int:
        if msg.command == m.MAV_CMD_SET_MESSAGE_INTERVAL:
            message_id = int(msg.param1)
            if message_id not in _STREAMABLE:
                return m.MAV_RESULT_DENIED
            if msg.param2 < 0:
                self.intervals_s.pop(message_id, None)
            else:
                self.intervals_s[message_id] = msg.param2 / 1e6 if msg.param2 > 0 else 1.0
            return m.MAV_RESULT_ACCEPTED
        ready = self.home_set()
        wants_position = msg.command == m.MAV_CMD_DO_SET_MODE and int(msg.param2) in (GUIDED, AUTO)
        arming = msg.command == m.MAV_CMD_COMPONENT_ARM_DISARM and msg.param1 == 1.0
        if not ready and (wants_position or arming):
            self._prearm_text()
            return m.MAV_RESULT_FAILED
        return super()._command(msg)

    def _on_mission_count(self, msg) -> None:
        self.counts_before_home += not self.home_set()
        super()._on_mission_count(msg)

    def _on_mission_clear_all(self, msg) -> None:
        self.clears_received += 1
        super()._on_mission_clear_all(msg)
