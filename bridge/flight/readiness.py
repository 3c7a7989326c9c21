"""Ask a vehicle for the messages our decisions depend on, and wait until it is ready to be flown.

An autopilot does not stream everything to a new ground station: ArduPilot sends only HEARTBEAT
on a link until it is asked for more (its stream rates, or ``MAV_CMD_SET_MESSAGE_INTERVAL``), and
a freshly booted one has no position for several seconds (GLOBAL_POSITION_INT at latitude 0,
longitude 0) and no home for several more (no HOME_POSITION; its pre-arm checks say
"PreArm: Need Position Estimate" meanwhile). So:

- :func:`request_message` asks for one message once (``MAV_CMD_REQUEST_MESSAGE``): what a mission
  command needs (HOME_POSITION, MISSION_CURRENT) is asked for that way, which changes no stream rate
  another ground station on the link may rely on;
- :func:`request_streams` asks a vehicle we fly for GLOBAL_POSITION_INT, GPS_RAW_INT,
  EKF_STATUS_REPORT, MISSION_CURRENT and HOME_POSITION with ``MAV_CMD_SET_MESSAGE_INTERVAL``;
- neither waits for the answers (a vehicle that ignores them costs no time): they are asked again
  while we wait;
- :func:`wait_ready` waits, for at most ``timeout_s``, until the vehicle has a position fix (when
  asked) and a home, asks again for what has not come, says every few seconds what it waits for
  and what the vehicle said (STATUSTEXT), and raises :class:`~bridge.errors.HomeUnknownError`
  naming the vehicle and what was missing once the time is up.

The home is the vehicle's HOME_POSITION (asked for with ``MAV_CMD_REQUEST_MESSAGE``). An
autopilot that may not report one (``fix_stands_in``: not ArduPilot) may instead give its first
position fix after one handshake timeout; ArduPilot has a fix well before it sets its home, and
refuses to arm until then, so only its HOME_POSITION counts.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from bridge.config import ProtocolConfig
from bridge.errors import BridgeError, HomeUnknownError
from bridge.flight.vehicle_home import HomeWatcher, ReportedHome
from bridge.link.frames import MavMessage
from bridge.link.mavlink import MavlinkLink
from bridge.link.vehicle_state import VehicleStateTracker

__all__ = ["STREAMS_HZ", "request_streams", "request_message", "wait_ready"]

log = logging.getLogger(__name__)

STREAMS_HZ = {
    mavlink.MAVLINK_MSG_ID_GPS_RAW_INT: 2.0,
    mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT: 2.0,
    mavlink.MAVLINK_MSG_ID_MISSION_CURRENT: 2.0,
    mavlink.MAVLINK_MSG_ID_HOME_POSITION: 0.5,
}
"""Messages asked for on every new link besides GLOBAL_POSITION_INT, and their rates (Hz)."""

_AUTOPILOT_COMPONENT = 1
_POLL_S = 0.05
_FIRST_REPORT_S = 2.0  # say what we wait for after this long, then every _REPORT_S
_REPORT_S = 5.0


def request_streams(link: MavlinkLink, system_id: int, position_rate_hz: float) -> None:
    """Ask for GLOBAL_POSITION_INT at ``position_rate_hz`` and the :data:`STREAMS_HZ` messages.

    Each request is one ``MAV_CMD_SET_MESSAGE_INTERVAL``, sent once without waiting for its answer.
    """
    rates = {mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: position_rate_hz, **STREAMS_HZ}
    for message_id, rate_hz in rates.items():
        if rate_hz <= 0:
            continue
        link.send(_message_interval(system_id, message_id, rate_hz))


def _message_interval(system_id: int, message_id: int, rate_hz: float) -> Callable[[MavMessage], None]:
    """The send action of one ``MAV_CMD_SET_MESSAGE_INTERVAL`` (``message_id`` at ``rate_hz``)."""
    return lambda mav: mav.command_long_send(
        system_id, _AUTOPILOT_COMPONENT, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
        float(message_id), 1e6 / rate_hz, 0.0, 0.0, 0.0, 0.0, 0.0)


def request_message(link: MavlinkLink, system_id: int, message_id: int) -> None:
    """Ask for one message now (``MAV_CMD_REQUEST_MESSAGE``), without waiting for the answer."""
    link.send(lambda mav: mav.command_long_send(
        system_id, _AUTOPILOT_COMPONENT, mavlink.MAV_CMD_REQUEST_MESSAGE, 0, float(message_id),
        0.0, 0.0, 0.0, 0.0, 0.0, 0.0))


def _quoted(texts: list[str]) -> str:
    unique = list(dict.fromkeys(texts))[-3:]
    return "; it says: " + ", ".join(f'"{text}"' for text in unique) if unique else ""


def wait_ready(link: MavlinkLink, tracker: VehicleStateTracker, homes: HomeWatcher, system_id: int, *,
               timeout_s: float, protocol: ProtocolConfig, need_fix: bool = True, fix_stands_in: bool = False,
               fresh: bool = False, position_rate_hz: float = 0.0,
               cancel: threading.Event | None = None) -> ReportedHome:
    """Wait until the vehicle has a position fix (``need_fix``) and a home; its home.

    Args:
        link: The connection reaching the vehicle.
        tracker: Its state (the fix).
        homes: Its HOME_POSITION and first fix.
        system_id: The vehicle.
        timeout_s: The most time spent waiting.
        protocol: ``handshake_timeout_s`` paces the requests (and the fallback to the first fix).
        need_fix: Also wait for a position fix (``VehicleState.has_fix``).
        fix_stands_in: The first fix may stand in for the home after one handshake timeout.
        fresh: Only what the vehicle says from now counts (a restarted vehicle's old home does not).
        position_rate_hz: Ask for the streams (:func:`request_streams`) with GLOBAL_POSITION_INT at this
            rate (a vehicle we fly); 0: ask only for single messages (:func:`request_message`).
        cancel: Set it to stop waiting (a flight ending).

    Raises:
        HomeUnknownError: Not ready within ``timeout_s``, naming what was missing and what the vehicle said.
        BridgeError: ``cancel`` was set.
    """
    cancel = cancel or threading.Event()
    start_s, start_wall_s = time.monotonic(), time.time()
    since_s = start_s if fresh else float("-inf")
    deadline_s = start_s + timeout_s
    next_request_s = start_s
    next_report_s = start_s + _FIRST_REPORT_S
    said_since_s = start_s
    while True:
        now_s = time.monotonic()
        state = tracker.state(system_id)
        fixed = state is not None and state.has_fix and (
            not fresh or (state.position_time_s or 0.0) >= start_wall_s)
        home = homes.home(system_id, since_s)
        source = "HOME_POSITION"
        if home is None and fix_stands_in and now_s >= start_s + protocol.handshake_timeout_s:
            home, source = homes.first_fix(system_id, since_s), "GLOBAL_POSITION_INT"
        missing = ([] if fixed or not need_fix else ["position fix"]) + (
            [] if home is not None else ["home (HOME_POSITION" + (", or a fix)" if fix_stands_in else ")")])
        if home is not None and not missing:
            return ReportedHome(home, source)
        if now_s >= deadline_s:
            raise HomeUnknownError(system_id, timeout_s, " and ".join(missing),
                                   _quoted(link.status_texts(system_id, start_s)))
        if now_s >= next_request_s:
            next_request_s = now_s + protocol.handshake_timeout_s
            streamed = state is not None and (state.position_time_s or 0.0) >= start_wall_s
            if position_rate_hz > 0 and not streamed:
                request_streams(link, system_id, position_rate_hz)
            elif fix_stands_in and home is None:
                request_message(link, system_id, mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT)
            if home is None:
                request_message(link, system_id, mavlink.MAVLINK_MSG_ID_HOME_POSITION)
        if now_s >= next_report_s:
            next_report_s = now_s + _REPORT_S
            log.info("vehicle %d: waiting for %s (%.0f s of %.0f s)%s", system_id, " and ".join(missing),
                     now_s - start_s, timeout_s, _quoted(link.status_texts(system_id, said_since_s)))
            said_since_s = now_s
        if cancel.wait(_POLL_S):
            raise BridgeError(f"vehicle {system_id}: waiting for it to be ready cancelled")
