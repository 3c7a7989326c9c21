"""A simulated ArduCopter: the MAVLink commands ``uav-swarm fly`` sends, answered as ArduCopter 4.6 does.

It answers ``MAV_CMD_DO_SET_MODE`` (custom modes STABILIZE 0, AUTO 3, GUIDED 4, RTL 6, LAND 9),
``MAV_CMD_COMPONENT_ARM_DISARM`` (refused with ``MAV_RESULT_FAILED`` during ``prearm_s`` after start, as
pre-arm checks do), ``MAV_CMD_NAV_TAKEOFF`` (only armed and in GUIDED; param7 above home),
``MAV_CMD_NAV_RETURN_TO_LAUNCH``, ``MAV_CMD_NAV_LAND``, ``MAV_CMD_SET_MESSAGE_INTERVAL`` for
GLOBAL_POSITION_INT, and ``MAV_CMD_DO_REPOSITION`` (only airborne; z above home in
``MAV_FRAME_GLOBAL_RELATIVE_ALT_INT``, above sea level in ``MAV_FRAME_GLOBAL_INT``, as ArduPilot reads
the frame). Like ArduPilot on a new link it sends only HEARTBEAT until GLOBAL_POSITION_INT is asked for
(``stream_until_asked``). Missions are served and stored as AP_Mission does
(:class:`~bridge.simulated.peer.SimVehicle`'s ``"ardupilot"`` personality) and flown in AUTO.

**Flight.** It flies on a :class:`~bridge.simulated.dynamics.PointMassCopter` whose limits are its own
parameters, at ArduCopter's defaults unless ``params`` says otherwise: ``WPNAV_SPEED`` (cm/s, horizontal
speed), ``WPNAV_ACCEL`` (cm/s^2, acceleration and braking), ``WPNAV_SPEED_UP``, ``WPNAV_SPEED_DN``
(cm/s, climb and descent, the landing included), ``WPNAV_ACCEL_Z`` (cm/s^2); a PARAM_SET takes effect
at once. ``PSC_JERK_XY`` and the position controller's gains are served at their defaults; the point
mass reaches its acceleration without a jerk limit. Arrival (a waypoint, a leg of the return, home) is
judged by the controller's set point, as AC_WPNav judges it; with wind the true position differs by the
tracking error. ``realism`` adds the imperfections of :class:`~bridge.simulated.dynamics.Realism`:
GLOBAL_POSITION_INT carries its latest report (age, rate, noise; ``time_boot_ms`` is when it was true),
and its command link loses and delays COMMAND_LONG and COMMAND_INT.

**The end.** RTL is ArduCopter's: climb where it is to ``RTL_ALT`` (centimetres above home; its current
altitude when higher, or when ``RTL_ALT`` is 0), fly home at that altitude, descend and land, then disarm.
With ``RTL_CONE_SLOPE`` > 0 (its default, 3) the return altitude is lowered near home to the cone's,
``max(slope * distance, altitude + 2.5 m)`` at most, as ArduCopter does (set 0: no cone). LAND descends
where it is. Its ground station failsafe is ArduCopter's too: with ``FS_GCS_ENABLE`` set, once a heartbeat
of its ground station (``SYSID_MYGCS``, a ``MAV_TYPE_GCS`` heartbeat) was heard, an armed vehicle that
hears none for ``FS_GCS_TIMEOUT`` seconds switches to RTL (LAND for 5); ``FS_GCS_ENABLE = 0``
(ArduPilot's default) leaves it where it is. ``track`` keeps each true position it flew:
``(time.monotonic(), x, y, z)``.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from bridge.geo import Home, enu_to_geodetic, geodetic_to_enu
from bridge.missions.items import DEG_E7
from bridge.simulated.dynamics import AutopilotLimits, PointMassCopter, Realism
from bridge.simulated.peer import SimVehicle, m

__all__ = ["ArduCopter", "GUIDED", "AUTO", "RTL", "LAND", "STABILIZE", "ARDUPILOT_PARAMS", "FAILSAFE_ON"]

STABILIZE, AUTO, GUIDED, RTL, LAND = 0, 3, 4, 6, 9
_INT8, _INT16, _INT32, _REAL32 = (m.MAV_PARAM_TYPE_INT8, m.MAV_PARAM_TYPE_INT16, m.MAV_PARAM_TYPE_INT32,
                                  m.MAV_PARAM_TYPE_REAL32)
ARDUPILOT_PARAMS = {
    "FS_GCS_ENABLE": (0.0, _INT8), "FS_GCS_TIMEOUT": (5.0, _REAL32), "SYSID_MYGCS": (255.0, _INT16),
    "RTL_ALT": (1500.0, _INT32), "FENCE_ENABLE": (0.0, _INT8), "RTL_CONE_SLOPE": (3.0, _REAL32),
    "RTL_ALT_TYPE": (0.0, _INT8), "FS_OPTIONS": (16.0, _INT32),
    "WPNAV_SPEED": (1000.0, _REAL32), "WPNAV_ACCEL": (250.0, _REAL32), "WPNAV_SPEED_UP": (250.0, _REAL32),
    "WPNAV_SPEED_DN": (150.0, _REAL32), "WPNAV_ACCEL_Z": (100.0, _REAL32), "WPNAV_RADIUS": (200.0, _REAL32),
    "PSC_JERK_XY": (5.0, _REAL32), "PSC_POSXY_P": (1.0, _REAL32), "PSC_VELXY_P": (2.0, _REAL32)}
"""ArduCopter 4.6's defaults of the parameters ``fly`` and its guard read (value, ``MAV_PARAM_TYPE``)."""
FAILSAFE_ON = {"FS_GCS_ENABLE": 1.0}
"""ArduCopter's ground station failsafe set to RTL (``params`` of a vehicle an operator prepared)."""
_POSITIONED = (m.MAV_CMD_NAV_WAYPOINT, m.MAV_CMD_NAV_LOITER_UNLIM, m.MAV_CMD_NAV_LOITER_TIME)
_ARRIVED_M = 0.5
_CONE_MIN_CLIMB_M = 2.5  # ArduCopter's RTL_ABS_MIN_CLIMB: the least climb a cone leaves
_SLOWEST = 0.1  # m/s or m/s^2: ArduCopter constrains its speeds and accelerations to a positive floor


class ArduCopter(SimVehicle):
    """An ArduCopter at ``home`` (East-North-Up kinematics around it; see the module docstring).

    Args:
        url: Its end of the link (``udpout:``, ``udpin:`` or ``tcpin:``).
        system_id: Its MAVLink system id.
        home: Where it stands at start (its home).
        realism: Its imperfections (ideal by default).
        rng: The source of its random draws (default: seeded by ``system_id``).
        prearm_s: Arming is refused this long after start.
        position_period_s: Period of its telemetry until asked otherwise.
        stream_until_asked: Send no GLOBAL_POSITION_INT before ``MAV_CMD_SET_MESSAGE_INTERVAL`` asks.
        personality: :class:`SimVehicle`'s mission server personality (``"ardupilot"``: as AP_Mission).
        autopilot: The ``MAV_AUTOPILOT_*`` of its HEARTBEAT.
        custom_mode: Its mode at start (on the ground, disarmed).
        params: Parameter values that differ from its autopilot's defaults.
    """

    def __init__(self, url: str, system_id: int, *, home: Home | None = None, realism: Realism | None = None,
                 rng: np.random.Generator | None = None, prearm_s: float = 0.0,
                 position_period_s: float = 0.2,
                 stream_until_asked: bool = True, personality: str = "ardupilot",
                 autopilot: int = m.MAV_AUTOPILOT_ARDUPILOTMEGA, custom_mode: int = STABILIZE,
                 params: dict[str, float] | None = None) -> None:
        self.url = url
        self.geo_home = home = home or Home()
        self.realism = realism = realism or Realism()
        rng = rng or np.random.default_rng(system_id)
        flight_rng, link_rng = rng.spawn(2)
        self.armed = False
        self.streaming = not stream_until_asked
        self.target: tuple[float, float, float] | None = None
        self.commands: list[int] = []
        self.modes: list[int] = []
        self.reposition_frames: list[int] = []
        self.track: list[tuple[float, float, float, float]] = []
        self.failsafes: list[float] = []
        self._gcs_heard_s: float | None = None
        self._return_alt_m: float | None = None
        self._goal: tuple[float, float, float] | None = None
        self._boot_s = time.monotonic()
        self._ready_at_s = self._boot_s + prearm_s
        defaults = self._default_params()
        unknown = set(params or {}) - set(defaults)
        if unknown:
            raise ValueError(f"params: {sorted(unknown)} are not among {sorted(defaults)}")
        given = params or {}
        table = {name: (float(given.get(name, value)), kind) for name, (value, kind) in defaults.items()}
        self.params = table
        flight = replace(realism, command_latency_s=0.0, command_loss=0.0)  # the link carries those
        self._copter = PointMassCopter(np.zeros(3), self.limits(), flight, flight_rng)
        super().__init__(url, system_id, autopilot=autopilot, armed=False, custom_mode=custom_mode,
                         lat_deg=home.lat_deg, lon_deg=home.lon_deg, alt_m=home.alt_m,
                         telemetry_period_s=position_period_s, personality=personality, params=table,
                         link=realism, rng=link_rng)

    def _default_params(self) -> dict[str, tuple[float, int]]:
        return dict(ARDUPILOT_PARAMS)

    def limits(self) -> AutopilotLimits:
        """How it flies now: its ``WPNAV_*`` parameters."""
        cm = {name: max(_SLOWEST, self.param(name) / 100.0) for name in
              ("WPNAV_SPEED", "WPNAV_ACCEL", "WPNAV_SPEED_UP", "WPNAV_SPEED_DN", "WPNAV_ACCEL_Z")}
        return AutopilotLimits(max_speed_m_s=cm["WPNAV_SPEED"], max_accel_m_s2=cm["WPNAV_ACCEL"],
                               climb_m_s=cm["WPNAV_SPEED_UP"], descent_m_s=cm["WPNAV_SPEED_DN"],
                               vertical_accel_m_s2=cm["WPNAV_ACCEL_Z"])

    # -- state ---------------------------------------------------------------------------------
    @property
    def enu(self) -> list[float]:
        """Its true position (East, North, Up metres from home); set it to place it there at rest."""
        return [float(x) for x in self._copter.position_m]

    @enu.setter
    def enu(self, position_m: list[float]) -> None:
        self._copter.settle(np.asarray(position_m, dtype=float))
        self._goal = tuple(float(x) for x in position_m)  # type: ignore[assignment]

    @property
    def velocity(self) -> list[float]:
        """Its true velocity (East, North, Up m/s)."""
        return [float(x) for x in self._copter.velocity_m_s]

    def _setpoint(self) -> tuple[float, float, float]:
        x, y, z = self._copter.setpoint_m
        return float(x), float(y), float(z)

    # -- ground station failsafe ---------------------------------------------------------------
    def _on_heartbeat(self, msg) -> None:
        if msg.type == m.MAV_TYPE_GCS and self._watches(msg.get_srcSystem()):
            self._gcs_heard_s = time.monotonic()

    def _watches(self, gcs_system_id: int) -> bool:
        """ArduPilot: only its ground station's heartbeat (``SYSID_MYGCS``) keeps the link."""
        return gcs_system_id == int(self.param("SYSID_MYGCS"))

    def _silent_s(self) -> float | None:
        return None if self._gcs_heard_s is None else time.monotonic() - self._gcs_heard_s

    def _check_failsafe(self) -> None:
        action, silent_s = int(self.param("FS_GCS_ENABLE")), self._silent_s()
        if (action == 0 or not self.armed or self.custom_mode in (RTL, LAND) or silent_s is None
                or silent_s < self.param("FS_GCS_TIMEOUT") or self._setpoint()[2] <= 0.0):
            return
        self.failsafes.append(time.monotonic())
        self._switch(LAND if action == 5 else RTL)
        self._conn.mav.statustext_send(severity=m.MAV_SEVERITY_WARNING, text=b"GCS Failsafe")

    def _switch(self, custom_mode: int) -> None:
        self.custom_mode = custom_mode
        self.modes.append(custom_mode)

    def _rtl_alt_m(self) -> float:
        return self.param("RTL_ALT") / 100.0

    def _return_alt_for(self, distance_m: float, z_m: float) -> float:
        """ArduCopter's return altitude ``distance_m`` off home at ``z_m``: ``RTL_ALT`` within its cone."""
        target = max(self._rtl_alt_m(), z_m)
        slope = self.param("RTL_CONE_SLOPE")
        if slope > 0:
            target = min(target, max(distance_m * slope, z_m + _CONE_MIN_CLIMB_M))
        return max(target, z_m)

    def _returning(self) -> bool:
        return self.custom_mode == RTL

    def _rtl_goal(self) -> tuple[float, float, float]:
        """RTL: climb to the return altitude where it is, fly home at it, then descend."""
        x, y, z = self._setpoint()
        if self._return_alt_m is None:
            self._return_alt_m = self._return_alt_for(math.hypot(x, y), z)
        if math.hypot(x, y) <= _ARRIVED_M:
            return (0.0, 0.0, 0.0)
        if z < self._return_alt_m - 0.05:
            return (x, y, self._return_alt_m)
        return (0.0, 0.0, self._return_alt_m)

    # -- flight --------------------------------------------------------------------------------
    def _mission_target(self) -> tuple[float, float, float] | None:
        while 0 < self.current_seq < len(self.mission):
            item = self.mission[self.current_seq]
            if item.command in _POSITIONED:
                target = self._item_enu(item)
                passed = math.dist(target, self._setpoint()) < _ARRIVED_M
                if item.command == m.MAV_CMD_NAV_WAYPOINT and passed:
                    self.reached_seq = self.current_seq
                    self.current_seq += 1  # on to the next item
                    continue
                return target
            self.current_seq += 1
        return None

    def _item_enu(self, item) -> tuple[float, float, float]:
        x, y, _ = geodetic_to_enu(self.geo_home, item.x / DEG_E7, item.y / DEG_E7, self.geo_home.alt_m)
        return (x, y, item.z)

    def _flight_goal(self) -> tuple[float, float, float] | None:
        """Where its mode flies it now (None: brake and hold)."""
        if not self.armed:
            return None
        if self.custom_mode == GUIDED:
            return self.target
        if self.custom_mode == AUTO:
            return self._mission_target()
        if self.custom_mode == RTL:
            return self._rtl_goal()
        if self.custom_mode == LAND:
            x, y, _ = self._setpoint()
            return (x, y, 0.0)
        return None

    def _step(self) -> None:
        self._copter.limits = self.limits()
        self._copter.advance(max(0.0, time.monotonic() - self._boot_s - self._copter.now_s))
        self._check_failsafe()
        if not self._returning():
            self._return_alt_m = None
        goal = self._flight_goal()
        if goal is not None:
            goal = (goal[0], goal[1], max(0.0, goal[2]))  # the ground stops it
        if goal != self._goal:
            self._goal = goal
            self._copter.send(self._copter.now_s, None if goal is None else np.array(goal))
        self._after_step(goal)

    def _after_step(self, goal: tuple[float, float, float] | None) -> None:
        """Touch down and disarm when the descent of RTL or LAND reaches the ground."""
        x, y, z = self._setpoint()
        if self.armed and self.custom_mode in (RTL, LAND) and goal is not None and goal[2] == 0.0 \
                and z <= 0.01 and math.hypot(goal[0] - x, goal[1] - y) < _ARRIVED_M:
            self._touch_down()

    def _touch_down(self) -> None:
        x, y, _ = self.enu
        self.enu = [x, y, 0.0]
        self.armed = False

    def _telemetry(self) -> None:
        self._step()
        x, y, z = self.enu
        self.track.append((self._boot_s + self._copter.now_s, x, y, z))  # when it was there
        mav = self._conn.mav
        base_mode = m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (m.MAV_MODE_FLAG_SAFETY_ARMED if self.armed else 0)
        mav.heartbeat_send(type=m.MAV_TYPE_QUADROTOR, autopilot=self.autopilot, base_mode=base_mode,
                           custom_mode=self.custom_mode, system_status=m.MAV_STATE_ACTIVE)
        if not self.streaming:
            return
        self._send_position()
        mav.mission_current_send(seq=self.current_seq, total=len(self.mission))

    def _send_position(self) -> None:
        """GLOBAL_POSITION_INT of its latest report (``time_boot_ms``: when it was true)."""
        report = self._copter.report()
        east_m, north_m, up_m = (float(x) for x in report.position_m)
        vx, vy, vz = (float(x) for x in report.velocity_m_s)
        lat_deg, lon_deg, alt_m = enu_to_geodetic(self.geo_home, east_m, north_m, up_m)
        self._conn.mav.global_position_int_send(
            time_boot_ms=round(max(0.0, report.stamp_s) * 1000) % 2**32, lat=round(lat_deg * DEG_E7),
            lon=round(lon_deg * DEG_E7), alt=round(alt_m * 1000), relative_alt=round(up_m * 1000),
            vx=round(vy * 100), vy=round(vx * 100), vz=round(-vz * 100), hdg=0)

    # -- commands ------------------------------------------------------------------------------
    def _answer(self, msg, result: int) -> None:
        self._conn.mav.command_ack_send(command=msg.command, result=result, **self._targets(msg))

    def _on_command_long(self, msg) -> None:
        self.commands.append(msg.command)
        if msg.command == m.MAV_CMD_REQUEST_MESSAGE:  # HOME_POSITION: the base vehicle answers
            super()._on_command_long(msg)
            return
        self._answer(msg, self._command(msg))

    def _airborne(self) -> bool:
        return self.armed and self._setpoint()[2] > 0.5

    def _command(self, msg) -> int:
        if msg.command == m.MAV_CMD_SET_MESSAGE_INTERVAL:
            if int(msg.param1) != m.MAVLINK_MSG_ID_GLOBAL_POSITION_INT or msg.param2 <= 0:
                return m.MAV_RESULT_DENIED
            self.telemetry_period_s, self.streaming = msg.param2 / 1e6, True
            return m.MAV_RESULT_ACCEPTED
        if msg.command == m.MAV_CMD_DO_SET_MODE:
            if int(msg.param2) not in (STABILIZE, AUTO, GUIDED, RTL, LAND):
                return m.MAV_RESULT_DENIED
            self._switch(int(msg.param2))
            return m.MAV_RESULT_ACCEPTED
        if msg.command == m.MAV_CMD_COMPONENT_ARM_DISARM:
            if msg.param1 == 1.0 and time.monotonic() < self._ready_at_s:
                return m.MAV_RESULT_FAILED  # pre-arm checks still failing
            self.armed = msg.param1 == 1.0
            return m.MAV_RESULT_ACCEPTED
        if msg.command == m.MAV_CMD_NAV_TAKEOFF:
            if not self.armed or self.custom_mode != GUIDED or msg.param7 <= 0:
                return m.MAV_RESULT_FAILED
            x, y, _ = self._setpoint()
            self.target = (x, y, msg.param7)
            return m.MAV_RESULT_ACCEPTED
        if msg.command in (m.MAV_CMD_NAV_RETURN_TO_LAUNCH, m.MAV_CMD_NAV_LAND):
            if not self.armed:
                return m.MAV_RESULT_FAILED
            self._switch(RTL if msg.command == m.MAV_CMD_NAV_RETURN_TO_LAUNCH else LAND)
            return m.MAV_RESULT_ACCEPTED
        return m.MAV_RESULT_UNSUPPORTED if not self._airborne() else m.MAV_RESULT_DENIED

    def _on_command_int(self, msg) -> None:
        self.commands.append(msg.command)
        if msg.command != m.MAV_CMD_DO_REPOSITION:
            self._answer(msg, m.MAV_RESULT_UNSUPPORTED)
            return
        if not self._airborne():
            self._answer(msg, m.MAV_RESULT_FAILED)  # ArduPilot: not flying
            return
        x, y, _ = geodetic_to_enu(self.geo_home, msg.x / DEG_E7, msg.y / DEG_E7, self.geo_home.alt_m)
        self.reposition_frames.append(msg.frame)  # ArduPilot honours the frame: GLOBAL_INT is above sea level
        height_m = msg.z - self.geo_home.alt_m if msg.frame == m.MAV_FRAME_GLOBAL_INT else msg.z
        self.target = (x, y, height_m)
        self.reposition_target = (msg.x, msg.y, msg.z)
        self.custom_mode = GUIDED
        self._answer(msg, m.MAV_RESULT_ACCEPTED)
