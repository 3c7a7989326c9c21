"""The MAVLink side of a simulated vehicle: its link, parameters, mission server and home, in a thread.

:class:`SimVehicle` sends HEARTBEAT, GLOBAL_POSITION_INT, SYS_STATUS, BATTERY_STATUS and
MISSION_CURRENT, and serves the mission protocol (upload with re-requests after 0.25 s, download,
clear, set current) and COMMAND_INT ``MAV_CMD_DO_REPOSITION``. It answers ``MAV_CMD_REQUEST_MESSAGE``
for HOME_POSITION (COMMAND_LONG) with its home, the position it starts at. The flying autopilots
(:mod:`bridge.simulated.ardupilot`, :mod:`bridge.simulated.px4`) build on it; alone it is a vehicle
that holds where it is, for the mission protocol's tests.

Faults on demand: a link cut both ways (``cut``: nothing it hears is handled, nothing it sends leaves,
as a radio out of range), never answer the mission protocol (``silent``), refuse an item with a
``MAV_MISSION_RESULT`` code, or use the legacy MISSION_REQUEST; a command link with latency and loss
(``link``: :class:`~bridge.simulated.dynamics.Realism`'s ``command_latency_s`` and ``command_loss``,
drawn from ``rng``): a lost COMMAND_LONG or COMMAND_INT gets no answer, the others are handled
(and answered) that much later.

``personality="ardupilot"`` answers as ArduPilot Copter does: for ``boot_no_space_s`` seconds from the
first MISSION_COUNT (an upload right after boot, before the mission storage is ready) every
MISSION_COUNT gets STATUSTEXT "Only 0 items are supported" and ``MAV_MISSION_NO_SPACE``; a mission
larger than ``max_items`` gets the same with its real capacity; items are asked for with the legacy
MISSION_REQUEST and stored as AP_Mission stores them (:mod:`bridge.simulated.ardupilot_storage`);
MISSION_CLEAR_ALL while armed in AUTO past item 0 is refused with ``MAV_MISSION_ERROR``, while a new
upload then is accepted. Alone it starts armed and holding in LOITER (``custom_mode``).

``personality="px4"`` answers a MISSION_COUNT that arrives during an upload as PX4's
MavlinkMissionManager does: before item 0 arrived it asks for item 0 again; after, it says
"WPM: REJ. CMD: Busy" (STATUSTEXT) and ``MAV_MISSION_ERROR`` and goes on with the upload. It asks
again for a missing item every 0.25 s for 5 s (PX4's retry and protocol timeouts). Any other
personality starts the upload again on every MISSION_COUNT (as ArduPilot does for the same ground
station) and gives up after 5 requests again (``request_retries``). ``transfers_started`` counts the
uploads the vehicle started.

Parameters (``params``: name to value and ``MAV_PARAM_TYPE``) are served as the autopilots serve them:
PARAM_REQUEST_READ by name or index and PARAM_SET are answered with PARAM_VALUE (a set's answer
carries the new value), PARAM_REQUEST_LIST with every one; a name it does not have gets no answer.
Integers travel cast to the float, or (``"px4"``) as their bytes in it, as PX4 sends them.
"""

from __future__ import annotations

import struct
import threading
import time

import numpy as np

from bridge.link.mavlink import use_mavlink2
from bridge.missions.items import DEG_E7, MissionItem
from bridge.simulated.ardupilot_storage import stored_by_ardupilot
from bridge.simulated.dynamics import Realism

mavutil = use_mavlink2()
m = mavutil.mavlink

__all__ = ["SimVehicle", "endpoint_pair", "TRANSPORTS", "m", "mavutil"]

TRANSPORTS = ("udpin", "udpout", "tcp")
PERSONALITIES = ("generic", "ardupilot", "px4")
AUTO, LOITER = 3, 5  # ArduCopter custom modes

def endpoint_pair(transport: str, port: int) -> tuple[str, str]:
    """``(vehicle_url, ground_station_url)`` on 127.0.0.1 for the ground station's transport."""
    vehicle = {"udpin": "udpout", "udpout": "udpin", "tcp": "tcpin"}[transport]
    return f"{vehicle}:127.0.0.1:{port}", f"{transport}:127.0.0.1:{port}"


class SimVehicle:
    """A vehicle on ``url`` (``udpout:``, ``udpin:`` or ``tcpin:``) with MAVLink system id ``system_id``."""

    def __init__(
        self,
        url: str,
        system_id: int,
        *,
        autopilot: int = m.MAV_AUTOPILOT_GENERIC,
        silent: bool = False,
        refuse_code: int | None = None,
        refuse_seq: int = 1,
        legacy_requests: bool = False,
        command_result: int = m.MAV_RESULT_ACCEPTED,
        signing_key: bytes | None = None,
        lat_deg: float = 47.3977418,
        lon_deg: float = 8.5455938,
        alt_m: float = 488.0,
        telemetry_period_s: float = 0.1,
        personality: str = "generic",
        boot_no_space_s: float = 0.0,
        max_items: int = 700,
        armed: bool = True,
        request_retries: int | None = None,
        custom_mode: int = LOITER,
        params: dict[str, tuple[float, int]] | None = None,
        link: Realism | None = None,
        rng: np.random.Generator | None = None,
    ) -> None:
        if personality not in PERSONALITIES:
            raise ValueError(f"personality = {personality!r}: choose one of {PERSONALITIES}")
        ardupilot = personality == "ardupilot"
        self.system_id = system_id
        self.personality = personality
        self.autopilot = m.MAV_AUTOPILOT_ARDUPILOTMEGA if ardupilot else autopilot
        self.silent = silent
        self.cut = False
        self.refuse_code = refuse_code
        self.refuse_seq = refuse_seq
        self.legacy_requests = legacy_requests or ardupilot
        self.boot_no_space_s = boot_no_space_s
        self.max_items = max_items
        self.armed = armed
        self.home = (round(lat_deg * DEG_E7), round(lon_deg * DEG_E7), alt_m)
        self.refused_counts = 0
        self.transfers_started = 0
        px4 = personality == "px4"
        self.request_retries = request_retries if request_retries is not None else (20 if px4 else 5)
        self.command_result = command_result
        self.lat_deg, self.lon_deg, self.alt_m = lat_deg, lon_deg, alt_m
        self.telemetry_period_s = telemetry_period_s
        self.mission: list[MissionItem] = []
        self.current_seq = 0
        self.reached_seq: int | None = None
        self.uploads = 0
        self.reposition_target: tuple[int, int, float] | None = None
        self.custom_mode = custom_mode
        self.params: dict[str, tuple[float, int]] = dict(params or {})
        self.param_sets: list[tuple[str, float]] = []
        self.link = link or Realism()
        self._link_rng = rng or np.random.default_rng(system_id)
        self._delayed: list[tuple[float, object]] = []
        self._first_count_s: float | None = None
        self._rx: dict | None = None
        self._last_done_seq: int | None = None
        self._conn = mavutil.mavlink_connection(url, source_system=system_id, source_component=1)
        send = self._conn.write
        self._conn.write = lambda buf: None if self.cut else send(buf)
        if signing_key is not None:
            self._conn.setup_signing(signing_key, sign_outgoing=True)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name=f"sim vehicle {system_id}", daemon=True)
        self._thread.start()

    def close(self) -> None:
        """Stop its thread and close its link."""
        self._stop.set()
        self._thread.join(timeout=2.0)
        self._conn.close()

    def __enter__(self) -> SimVehicle:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- sending -------------------------------------------------------------------------------
    def _targets(self, msg) -> dict[str, int]:
        return {"target_system": msg.get_srcSystem(), "target_component": msg.get_srcComponent()}

    def _ack(self, msg, code: int) -> None:
        self._conn.mav.mission_ack_send(
            type=code, mission_type=m.MAV_MISSION_TYPE_MISSION, **self._targets(msg)
        )

    def _request(self, seq: int) -> None:
        rx = self._rx
        assert rx is not None  # asked only during an upload
        kwargs = {"target_system": rx["gcs"][0], "target_component": rx["gcs"][1], "seq": seq,
                  "mission_type": m.MAV_MISSION_TYPE_MISSION}
        if self.legacy_requests:
            self._conn.mav.mission_request_send(**kwargs)
        else:
            self._conn.mav.mission_request_int_send(**kwargs)
        rx["asked_s"] = time.monotonic()

    def _telemetry(self) -> None:
        mav = self._conn.mav
        armed = m.MAV_MODE_FLAG_SAFETY_ARMED if self.armed else 0
        mav.heartbeat_send(type=m.MAV_TYPE_QUADROTOR, autopilot=self.autopilot,
                           base_mode=m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | armed,
                           custom_mode=self.custom_mode, system_status=m.MAV_STATE_ACTIVE)
        mav.global_position_int_send(
            time_boot_ms=int(time.monotonic() * 1000) % 2**32, lat=round(self.lat_deg * DEG_E7),
            lon=round(self.lon_deg * DEG_E7), alt=round(self.alt_m * 1000),
            relative_alt=round((self.alt_m - self.home[2]) * 1000), vx=100, vy=200, vz=-50, hdg=9000)
        mav.sys_status_send(
            onboard_control_sensors_present=0, onboard_control_sensors_enabled=0,
            onboard_control_sensors_health=0, load=0, voltage_battery=15800, current_battery=-1,
            battery_remaining=76, drop_rate_comm=0, errors_comm=0, errors_count1=0, errors_count2=0,
            errors_count3=0, errors_count4=0)
        mav.battery_status_send(
            id=0, battery_function=0, type=0, temperature=32767,
            voltages=[4000, 4000, 4000, 3900] + [65535] * 6,
            current_battery=-1, current_consumed=-1, energy_consumed=-1, battery_remaining=75)
        mav.mission_current_send(seq=self.current_seq, total=len(self.mission))

    # -- receiving -----------------------------------------------------------------------------
    def _loop(self) -> None:
        next_telemetry_s = 0.0
        while not self._stop.is_set():
            now_s = time.monotonic()
            try:
                if now_s >= next_telemetry_s:
                    next_telemetry_s = now_s + self.telemetry_period_s
                    self._telemetry()
                if self._rx is not None and now_s - self._rx["asked_s"] > 0.25:
                    self._rx["retries"] += 1
                    if self._rx["retries"] > self.request_retries:
                        self._rx = None
                    else:
                        self._request(self._rx["expected"])
                msg = self._conn.recv_match(blocking=True, timeout=0.02)
            except OSError:
                time.sleep(0.02)
                continue
            while self._delayed and self._delayed[0][0] <= time.monotonic():
                self._dispatch(self._delayed.pop(0)[1])
            if msg is None or msg.get_type() == "BAD_DATA" or self.silent or self.cut:
                continue
            if getattr(msg, "target_system", self.system_id) not in (0, self.system_id):
                continue
            if msg.get_type() in ("COMMAND_LONG", "COMMAND_INT"):
                if self._link_rng.random() < self.link.command_loss:
                    continue  # lost on the way: no answer
                if self.link.command_latency_s > 0.0:
                    self._delayed.append((time.monotonic() + self.link.command_latency_s, msg))
                    continue
            self._dispatch(msg)

    def _dispatch(self, msg) -> None:
        handler = getattr(self, "_on_" + msg.get_type().lower(), None)
        if handler is not None:
            handler(msg)

    def _flying_mission(self) -> bool:
        return self.armed and self.custom_mode == AUTO and self.current_seq > 0

    def _stored(self, item: MissionItem) -> MissionItem:
        """The item as this vehicle keeps it (ArduPilot: as AP_Mission stores and returns it)."""
        return stored_by_ardupilot(item, self.home) if self.personality == "ardupilot" else item

    def _refuse_count(self, msg, capacity: int) -> None:
        self.refused_counts += 1
        self._conn.mav.statustext_send(
            severity=m.MAV_SEVERITY_WARNING, text=f"Only {capacity} items are supported".encode()
        )
        self._ack(msg, m.MAV_MISSION_NO_SPACE)

    def _on_mission_count(self, msg) -> None:
        if self.personality == "ardupilot":
            if self._first_count_s is None:
                self._first_count_s = time.monotonic()
            if time.monotonic() - self._first_count_s < self.boot_no_space_s:
                self._refuse_count(msg, 0)  # the mission storage is not ready yet
                return
            if msg.count > self.max_items:
                self._refuse_count(msg, self.max_items)
                return
        if self.personality == "px4" and self._rx is not None:
            if self._rx["expected"] == 0:  # our request was lost: ask again
                self._request(0)
                return
            self._conn.mav.statustext_send(severity=m.MAV_SEVERITY_CRITICAL, text=b"WPM: REJ. CMD: Busy")
            self._ack(msg, m.MAV_MISSION_ERROR)  # the upload in progress goes on
            return
        if msg.count == 0:
            self.mission, self._rx = [], None
            self._ack(msg, m.MAV_MISSION_ACCEPTED)
            return
        self.transfers_started += 1
        self._rx = {
            "count": msg.count,
            "items": [],
            "expected": 0,
            "retries": 0,
            "asked_s": 0.0,
            "gcs": (msg.get_srcSystem(), msg.get_srcComponent()),
        }
        self._request(0)

    def _on_mission_item_int(self, msg) -> None:
        rx = self._rx
        if rx is None:
            if msg.seq == self._last_done_seq:
                self._ack(msg, m.MAV_MISSION_ACCEPTED)  # our final ACK was lost: say it again
            return
        if msg.seq != rx["expected"]:
            self._ack(msg, m.MAV_MISSION_INVALID_SEQUENCE)  # as ArduPilot does; the transfer goes on
            return
        if self.refuse_code is not None and msg.seq == self.refuse_seq:
            self._rx = None
            self._ack(msg, self.refuse_code)
            return
        x, y = (
            (round(msg.x * DEG_E7), round(msg.y * DEG_E7))
            if msg.get_type() == "MISSION_ITEM"
            else (msg.x, msg.y)
        )
        rx["items"].append(
            MissionItem(
                seq=msg.seq,
                frame=msg.frame,
                command=msg.command,
                current=msg.current,
                autocontinue=msg.autocontinue,
                param1=msg.param1,
                param2=msg.param2,
                param3=msg.param3,
                param4=msg.param4,
                x=x,
                y=y,
                z=msg.z,
            )
        )
        rx["expected"] += 1
        rx["retries"] = 0
        if rx["expected"] == rx["count"]:
            self.mission = [self._stored(item) for item in rx["items"]]
            self._rx, self._last_done_seq = None, msg.seq
            self.uploads += 1
            self._ack(msg, m.MAV_MISSION_ACCEPTED)
        else:
            self._request(rx["expected"])

    _on_mission_item = _on_mission_item_int

    def _on_mission_request_list(self, msg) -> None:
        self._conn.mav.mission_count_send(
            count=len(self.mission), mission_type=m.MAV_MISSION_TYPE_MISSION, **self._targets(msg)
        )

    def _on_mission_request_int(self, msg) -> None:
        if not 0 <= msg.seq < len(self.mission):
            self._ack(msg, m.MAV_MISSION_INVALID_SEQUENCE)
            return
        fields = {**self.mission[msg.seq].message_fields(), "current": int(msg.seq == self.current_seq)}
        if msg.get_type() == "MISSION_REQUEST":
            fields["x"], fields["y"] = fields["x"] / DEG_E7, fields["y"] / DEG_E7
            self._conn.mav.mission_item_send(**fields, **self._targets(msg))
        else:
            self._conn.mav.mission_item_int_send(**fields, **self._targets(msg))

    _on_mission_request = _on_mission_request_int

    def _on_mission_clear_all(self, msg) -> None:
        if self.personality == "ardupilot" and self._flying_mission():
            self._ack(msg, m.MAV_MISSION_ERROR)  # AP_Mission::clear() refuses while running
            return
        self.mission, self.current_seq = [], 0
        self._ack(msg, m.MAV_MISSION_ACCEPTED)

    def _on_mission_set_current(self, msg) -> None:
        if not 0 <= msg.seq < len(self.mission):
            self._ack(msg, m.MAV_MISSION_INVALID_SEQUENCE)
            return
        self.current_seq = msg.seq
        self._conn.mav.mission_current_send(seq=msg.seq, total=len(self.mission))
        if msg.seq > 0:
            self.reached_seq = msg.seq - 1
            self._conn.mav.mission_item_reached_send(seq=msg.seq - 1)

    def _on_command_int(self, msg) -> None:
        if msg.command != m.MAV_CMD_DO_REPOSITION:
            result = m.MAV_RESULT_UNSUPPORTED
        else:
            result = self.command_result
            if result == m.MAV_RESULT_ACCEPTED:
                self.reposition_target = (msg.x, msg.y, msg.z)
                self.custom_mode = 4  # ArduCopter GUIDED
        self._conn.mav.command_ack_send(command=msg.command, result=result, **self._targets(msg))

    def _on_command_long(self, msg) -> None:
        if msg.command == m.MAV_CMD_REQUEST_MESSAGE and int(msg.param1) == m.MAVLINK_MSG_ID_HOME_POSITION:
            lat, lon, alt_m = self.home
            self._command_ack(msg, m.MAV_RESULT_ACCEPTED)
            self._conn.mav.home_position_send(
                latitude=lat,
                longitude=lon,
                altitude=round(alt_m * 1000),
                x=0.0,
                y=0.0,
                z=0.0,
                q=[1.0, 0.0, 0.0, 0.0],
                approach_x=0.0,
                approach_y=0.0,
                approach_z=0.0,
            )
            return
        self._command_ack(msg, m.MAV_RESULT_UNSUPPORTED)

    # -- parameters ----------------------------------------------------------------------------
    def param(self, name: str) -> float:
        """The value of one of its parameters."""
        return self.params[name][0]

    def _param_wire(self, value: float, param_type: int) -> float:
        if self.personality != "px4" or param_type == m.MAV_PARAM_TYPE_REAL32:
            return float(value)
        return struct.unpack("<f", struct.pack("<i", int(value)))[0]  # PX4: the int32's bytes

    def _param_number(self, wire: float, param_type: int) -> float:
        if self.personality != "px4" or param_type == m.MAV_PARAM_TYPE_REAL32:
            return float(wire)
        return float(struct.unpack("<i", struct.pack("<f", wire))[0])

    def _send_param(self, name: str) -> None:
        names = list(self.params)
        value, param_type = self.params[name]
        wire = self._param_wire(value, param_type)
        self._conn.mav.param_value_send(param_id=name.encode(), param_value=wire, param_type=param_type,
                                        param_count=len(names), param_index=names.index(name))

    def _on_param_request_read(self, msg) -> None:
        names = list(self.params)
        name = str(msg.param_id).rstrip("\x00") if msg.param_index < 0 else (
            names[msg.param_index] if msg.param_index < len(names) else "")
        if name in self.params:
            self._send_param(name)

    def _on_param_request_list(self, msg) -> None:
        for name in self.params:
            self._send_param(name)

    def _on_param_set(self, msg) -> None:
        name = str(msg.param_id).rstrip("\x00")
        if name not in self.params:
            return
        param_type = self.params[name][1]
        value = self._param_number(msg.param_value, param_type)
        if param_type != m.MAV_PARAM_TYPE_REAL32:
            value = float(round(value))
        self.params[name] = (value, param_type)
        self.param_sets.append((name, value))
        self._send_param(name)

    def _command_ack(self, msg, result: int) -> None:
        self._conn.mav.command_ack_send(command=msg.command, result=result, **self._targets(msg))
