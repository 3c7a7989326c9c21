"""A test vehicle that flies: :class:`SimVehicle` with simple kinematics and the flight commands.

It answers as ArduPilot Copter does the commands ``uav-swarm fly`` sends: ``MAV_CMD_DO_SET_MODE``
(custom modes GUIDED 4, AUTO 3, RTL 6, LAND 9), ``MAV_CMD_COMPONENT_ARM_DISARM`` (refused with
``MAV_RESULT_FAILED`` during ``prearm_s`` after start, as pre-arm checks do), ``MAV_CMD_NAV_TAKEOFF``
(only armed and in GUIDED), ``MAV_CMD_NAV_RETURN_TO_LAUNCH``, ``MAV_CMD_NAV_LAND``,
``MAV_CMD_SET_MESSAGE_INTERVAL`` for GLOBAL_POSITION_INT, and ``MAV_CMD_DO_REPOSITION`` (only
airborne; z above home in ``MAV_FRAME_GLOBAL_RELATIVE_ALT_INT``, above sea level in
``MAV_FRAME_GLOBAL_INT``, as ArduPilot reads the frame). Like ArduPilot on a new link it sends only
HEARTBEAT until GLOBAL_POSITION_INT is asked for (``stream_until_asked``). It flies toward its
target at ``speed_m_s`` horizontally and ``climb_m_s`` vertically, through its mission in AUTO, down
in LAND, and disarms on the ground.

RTL is ArduCopter's: climb to ``RTL_ALT`` (centimetres above home; its current altitude when higher,
or when ``RTL_ALT`` is 0), fly home at that altitude, descend and land. Its ground station failsafe
is ArduCopter's too: with ``FS_GCS_ENABLE`` set, once a heartbeat of its ground station
(``SYSID_MYGCS``, a ``MAV_TYPE_GCS`` heartbeat) was heard, an armed vehicle that hears none for
``FS_GCS_TIMEOUT`` seconds switches to RTL (LAND for 5); ``FS_GCS_ENABLE = 0`` (ArduPilot's default)
leaves it where it is. Its parameters (:class:`SimVehicle`'s server) start at ArduPilot's defaults,
``params`` overriding them. ``track`` keeps each position it flew: ``(time.monotonic(), x, y, z)``.
"""

from __future__ import annotations

import math
import time

from sim_vehicle import SimVehicle, m

from bridge.geo import Home, enu_to_geodetic, geodetic_to_enu
from bridge.missions.items import DEG_E7

__all__ = ["FlyingVehicle", "GUIDED", "AUTO", "RTL", "LAND", "FAILSAFE_ON", "launch_home"]

STABILIZE, AUTO, GUIDED, RTL, LAND = 0, 3, 4, 6, 9
_INT8, _INT16, _INT32, _REAL32 = (m.MAV_PARAM_TYPE_INT8, m.MAV_PARAM_TYPE_INT16, m.MAV_PARAM_TYPE_INT32,
                                  m.MAV_PARAM_TYPE_REAL32)
ARDUPILOT_PARAMS = {"FS_GCS_ENABLE": (0.0, _INT8), "FS_GCS_TIMEOUT": (5.0, _REAL32),
                    "SYSID_MYGCS": (255.0, _INT16), "RTL_ALT": (1500.0, _INT32), "FENCE_ENABLE": (0.0, _INT8)}
"""ArduCopter 4.6's defaults of the parameters ``fly`` reads (value, ``MAV_PARAM_TYPE``)."""
FAILSAFE_ON = {"FS_GCS_ENABLE": 1.0}
"""ArduCopter's ground station failsafe set to RTL (``params`` of a vehicle an operator prepared)."""
_POSITIONED = (m.MAV_CMD_NAV_WAYPOINT, m.MAV_CMD_NAV_LOITER_UNLIM, m.MAV_CMD_NAV_LOITER_TIME)


def launch_home(index: int, spacing_m: float = 10.0, origin: Home | None = None) -> Home:
    """Where vehicle ``index`` of a test fleet stands: ``spacing_m`` apart going East, as a real launch."""
    origin = origin or Home()
    lat_deg, lon_deg, _ = enu_to_geodetic(origin, index * spacing_m, 0.0, 0.0)
    return Home(lat_deg=lat_deg, lon_deg=lon_deg, alt_m=origin.alt_m)


class FlyingVehicle(SimVehicle):
    """A Copter-like vehicle at ``home`` (East-North-Up kinematics around it).

    Args:
        url: Its end of the link (``udpout:``, ``udpin:`` or ``tcpin:``).
        system_id: Its MAVLink system id.
        home: Where it stands at start (its home).
        speed_m_s: Horizontal speed.
        climb_m_s: Vertical speed.
        prearm_s: Arming is refused this long after start.
        position_period_s: Period of its telemetry until asked otherwise.
        stream_until_asked: Send no GLOBAL_POSITION_INT before ``MAV_CMD_SET_MESSAGE_INTERVAL`` asks.
        personality: :class:`SimVehicle`'s mission server personality (``"ardupilot"``: as AP_Mission).
        autopilot: The ``MAV_AUTOPILOT_*`` of its HEARTBEAT.
        custom_mode: Its mode at start (on the ground, disarmed).
        params: Parameter values that differ from its autopilot's defaults.
    """

    def __init__(self, url: str, system_id: int, *, home: Home | None = None, speed_m_s: float = 12.0,
                 climb_m_s: float = 8.0, prearm_s: float = 0.0, position_period_s: float = 0.2,
                 stream_until_asked: bool = True, personality: str = "generic",
                 autopilot: int = m.MAV_AUTOPILOT_ARDUPILOTMEGA, custom_mode: int = STABILIZE,
                 params: dict[str, float] | None = None) -> None:
        self.url = url
        self.geo_home = home = home or Home()
        self.speed_m_s, self.climb_m_s = speed_m_s, climb_m_s
        self.armed = False
        self.streaming = not stream_until_asked
        self.enu = [0.0, 0.0, 0.0]
        self.velocity = [0.0, 0.0, 0.0]
        self.target: tuple[float, float, float] | None = None
        self.commands: list[int] = []
        self.modes: list[int] = []
        self.reposition_frames: list[int] = []
        self.track: list[tuple[float, float, float, float]] = []
        self.failsafes: list[float] = []
        self._gcs_heard_s: float | None = None
        self._return_alt_m: float | None = None
        self._ready_at_s = time.monotonic() + prearm_s
        self._last_step_s = time.monotonic()
        defaults = self._default_params()
        unknown = set(params or {}) - set(defaults)
        if unknown:
            raise ValueError(f"params: {sorted(unknown)} are not among {sorted(defaults)}")
        table = {name: (float((params or {}).get(name, value)), kind)
                 for name, (value, kind) in defaults.items()}
        super().__init__(url, system_id, autopilot=autopilot, armed=False, custom_mode=custom_mode,
                         lat_deg=home.lat_deg, lon_deg=home.lon_deg, alt_m=home.alt_m,
                         telemetry_period_s=position_period_s, personality=personality, params=table)

    def _default_params(self) -> dict[str, tuple[float, int]]:
        return dict(ARDUPILOT_PARAMS)

    # -- ground station failsafe ---------------------------------------------------------------
    def _on_heartbeat(self, msg) -> None:
        if msg.type == m.MAV_TYPE_GCS and self._watches(msg.get_srcSystem()):
            self._gcs_heard_s = time.monotonic()

    def _watches(self, gcs_system_id: int) -> bool:
        """ArduPilot: only its ground station's heartbeat (``SYSID_MYGCS``) keeps the link."""
        return gcs_system_id == int(self.param("SYSID_MYGCS"))

    def _failsafe_action(self) -> int | None:
        """The mode its failsafe switches to now, or None (off, not armed, never heard, or not yet)."""
        action = int(self.param("FS_GCS_ENABLE"))
        silent_s = None if self._gcs_heard_s is None else time.monotonic() - self._gcs_heard_s
        if (action == 0 or not self.armed or self.custom_mode in (RTL, LAND) or silent_s is None
                or silent_s < self.param("FS_GCS_TIMEOUT") or self.enu[2] <= 0.0):
            return None
        return LAND if action == 5 else RTL

    def _check_failsafe(self) -> None:
        mode = self._failsafe_action()
        if mode is not None:
            self.failsafes.append(time.monotonic())
            self.custom_mode = mode
            self.modes.append(mode)
            self._conn.mav.statustext_send(severity=m.MAV_SEVERITY_WARNING, text=b"GCS Failsafe")

    def _rtl_alt_m(self) -> float:
        return self.param("RTL_ALT") / 100.0

    def _rtl_goal(self) -> tuple[float, float, float]:
        """RTL: climb to the return altitude where it is, fly home at it, then descend."""
        if self._return_alt_m is None:
            self._return_alt_m = max(self._rtl_alt_m(), self.enu[2])
        if math.hypot(*self.enu[:2]) <= 0.5:
            return (0.0, 0.0, 0.0)
        if self.enu[2] < self._return_alt_m - 0.05:
            return (self.enu[0], self.enu[1], self._return_alt_m)
        return (0.0, 0.0, self._return_alt_m)

    # -- kinematics ----------------------------------------------------------------------------
    def _mission_target(self) -> tuple[float, float, float] | None:
        while 0 < self.current_seq < len(self.mission):
            item = self.mission[self.current_seq]
            if item.command in _POSITIONED:
                home = self.geo_home
                x, y, _ = geodetic_to_enu(home, item.x / DEG_E7, item.y / DEG_E7, home.alt_m)
                target = (x, y, item.z)
                if item.command == m.MAV_CMD_NAV_WAYPOINT and math.dist(target, self.enu) < 0.5:
                    self.reached_seq = self.current_seq
                    self.current_seq += 1  # on to the next item
                    continue
                return target
            self.current_seq += 1
        return None

    def _step(self) -> None:
        now_s = time.monotonic()
        dt_s, self._last_step_s = now_s - self._last_step_s, now_s
        self._check_failsafe()
        if self.custom_mode != RTL:
            self._return_alt_m = None
        goal: tuple[float, float, float] | None = None
        if self.armed and self.custom_mode == GUIDED:
            goal = self.target
        elif self.armed and self.custom_mode == AUTO:
            goal = self._mission_target()
        elif self.armed and self.custom_mode == RTL:
            goal = self._rtl_goal()
        elif self.armed and self.custom_mode == LAND:
            goal = (self.enu[0], self.enu[1], 0.0)
        if goal is None:
            self.velocity = [0.0, 0.0, 0.0]
            return
        dx, dy, dz = (g - p for g, p in zip(goal, self.enu, strict=True))
        horizontal = math.hypot(dx, dy)
        scale = min(1.0, self.speed_m_s * dt_s / horizontal) if horizontal > 0 else 0.0
        climb = max(-self.climb_m_s * dt_s, min(self.climb_m_s * dt_s, dz))
        step = (dx * scale, dy * scale, climb)
        self.enu = [p + d for p, d in zip(self.enu, step, strict=True)]
        self.velocity = [d / dt_s if dt_s > 0 else 0.0 for d in step]
        if self.custom_mode in (RTL, LAND) and self.enu[2] <= 0.01 and math.hypot(dx, dy) < 0.5:
            self.enu[2], self.armed = 0.0, False  # landed: disarm

    def _telemetry(self) -> None:
        self._step()
        self.track.append((time.monotonic(), *self.enu))
        lat_deg, lon_deg, alt_m = enu_to_geodetic(self.geo_home, *self.enu)
        mav = self._conn.mav
        base_mode = m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (m.MAV_MODE_FLAG_SAFETY_ARMED if self.armed else 0)
        mav.heartbeat_send(type=m.MAV_TYPE_QUADROTOR, autopilot=self.autopilot, base_mode=base_mode,
                           custom_mode=self.custom_mode, system_status=m.MAV_STATE_ACTIVE)
        if not self.streaming:
            return
        vx, vy, vz = self.velocity
        mav.global_position_int_send(
            time_boot_ms=int(time.monotonic() * 1000) % 2**32, lat=round(lat_deg * DEG_E7),
            lon=round(lon_deg * DEG_E7), alt=round(alt_m * 1000), relative_alt=round(self.enu[2] * 1000),
            vx=round(vy * 100), vy=round(vx * 100), vz=round(-vz * 100), hdg=0)
        mav.mission_current_send(seq=self.current_seq, total=len(self.mission))

    # -- commands ------------------------------------------------------------------------------
    def _answer(self, msg, result: int) -> None:
        self._conn.mav.command_ack_send(command=msg.command, result=result, **self._targets(msg))

    def _on_command_long(self, msg) -> None:
        self.commands.append(msg.command)
        if msg.command == m.MAV_CMD_REQUEST_MESSAGE:  # HOME_POSITION: the base vehicle answers
            super()._on_command_long(msg)
            return
        self._answer(msg, self._command(msg))

    def _command(self, msg) -> int:
        airborne = self.armed and self.enu[2] > 0.5
        if msg.command == m.MAV_CMD_SET_MESSAGE_INTERVAL:
            if int(msg.param1) != m.MAVLINK_MSG_ID_GLOBAL_POSITION_INT or msg.param2 <= 0:
                return m.MAV_RESULT_DENIED
            self.telemetry_period_s, self.streaming = msg.param2 / 1e6, True
            return m.MAV_RESULT_ACCEPTED
        if msg.command == m.MAV_CMD_DO_SET_MODE:
            if int(msg.param2) not in (STABILIZE, AUTO, GUIDED, RTL, LAND):
                return m.MAV_RESULT_DENIED
            self.custom_mode = int(msg.param2)
            self.modes.append(self.custom_mode)
            return m.MAV_RESULT_ACCEPTED
        if msg.command == m.MAV_CMD_COMPONENT_ARM_DISARM:
            if msg.param1 == 1.0 and time.monotonic() < self._ready_at_s:
                return m.MAV_RESULT_FAILED  # pre-arm checks still failing
            self.armed = msg.param1 == 1.0
            return m.MAV_RESULT_ACCEPTED
        if msg.command == m.MAV_CMD_NAV_TAKEOFF:
            if not self.armed or self.custom_mode != GUIDED or msg.param7 <= 0:
                return m.MAV_RESULT_FAILED
            self.target = (self.enu[0], self.enu[1], msg.param7)
            return m.MAV_RESULT_ACCEPTED
        if msg.command in (m.MAV_CMD_NAV_RETURN_TO_LAUNCH, m.MAV_CMD_NAV_LAND):
            if not self.armed:
                return m.MAV_RESULT_FAILED
            self.custom_mode = RTL if msg.command == m.MAV_CMD_NAV_RETURN_TO_LAUNCH else LAND
            self.modes.append(self.custom_mode)
            return m.MAV_RESULT_ACCEPTED
        return m.MAV_RESULT_UNSUPPORTED if not airborne else m.MAV_RESULT_DENIED

    def _on_command_int(self, msg) -> None:
        self.commands.append(msg.command)
        if msg.command != m.MAV_CMD_DO_REPOSITION:
            self._answer(msg, m.MAV_RESULT_UNSUPPORTED)
            return
        if not (self.armed and self.enu[2] > 0.5):
            self._answer(msg, m.MAV_RESULT_FAILED)  # ArduPilot: not flying
            return
        x, y, _ = geodetic_to_enu(self.geo_home, msg.x / DEG_E7, msg.y / DEG_E7, self.geo_home.alt_m)
        self.reposition_frames.append(msg.frame)  # ArduPilot honours the frame: GLOBAL_INT is above sea level
        height_m = msg.z - self.geo_home.alt_m if msg.frame == m.MAV_FRAME_GLOBAL_INT else msg.z
        self.target = (x, y, height_m)
        self.reposition_target = (msg.x, msg.y, msg.z)
        self.custom_mode = GUIDED
        self._answer(msg, m.MAV_RESULT_ACCEPTED)
