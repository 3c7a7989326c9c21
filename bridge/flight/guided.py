"""Flying a vehicle: launch (ready, guided, armed, airborne), new targets in flight, and the end.

Each step follows the autopilot's own convention (:mod:`bridge.autopilots`, chosen from the
``autopilot`` of its HEARTBEAT):

- **ArduPilot** (Copter): ``MAV_CMD_DO_SET_MODE`` to GUIDED (custom mode 4), arm, then
  ``MAV_CMD_NAV_TAKEOFF`` with param7 the altitude above home.
- **PX4**: ``MAV_CMD_DO_SET_MODE`` to AUTO.LOITER (main mode 4, sub mode 3), arm, then
  ``MAV_CMD_NAV_TAKEOFF`` with param7 the altitude above mean sea level: the vehicle's own home
  altitude (its HOME_POSITION) + the take-off height. PX4 climbs in AUTO.TAKEOFF and holds in
  AUTO.LOITER.

Arming is retried while the autopilot refuses it (its pre-arm checks, e.g. no GPS fix yet)
until ``arm_timeout_s``; the take-off is done when the vehicle reports its altitude within
``takeoff_tolerance_m`` of the target. A flight ends with ``MAV_CMD_NAV_RETURN_TO_LAUNCH``
or ``MAV_CMD_NAV_LAND`` (both autopilots accept either). Every wait is bounded.
"""

from __future__ import annotations

import contextlib
import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal, TypeGuard

from pymavlink.dialects.v20 import common as mavlink

from bridge.autopilots import Conventions, conventions_for
from bridge.config import ProtocolConfig
from bridge.errors import BridgeError, CommandRejectedError
from bridge.flight.commands import command_long
from bridge.link.mavlink import MavlinkLink
from bridge.link.vehicle_state import VehicleState, VehicleStateTracker
from typed_config import Config, param

__all__ = [
    "FlightConfig",
    "FlightError",
    "has_position",
    "is_airborne",
    "launch",
    "set_mode",
    "end_flight",
    "request_position_stream",
]

log = logging.getLogger(__name__)

_POLL_S = 0.05


@dataclass(frozen=True)
class FlightConfig(Config):
    """Timing of a live flight: how long each step of the launch may take, the link, the end."""

    ready_timeout_s: float = param(60.0, gt=0.0, le=3600.0,
                                   doc="wait for each vehicle's heartbeat, then for its position fix and its "
                                       "home (HOME_POSITION), seconds")
    arm_timeout_s: float = param(60.0, gt=0.0, le=3600.0,
                                 doc="ask again to arm while the autopilot refuses (pre-arm checks), seconds")
    arm_retry_s: float = param(2.0, gt=0.0, le=60.0, doc="pause between two arming requests, seconds")
    takeoff_timeout_s: float = param(90.0, gt=0.0, le=3600.0, doc="climb to the cruise altitude, seconds")
    takeoff_tolerance_m: float = param(1.0, gt=0.0, le=100.0,
                                       doc="take-off done this close below the cruise altitude, metres")
    stream_rate_hz: float = param(10.0, ge=0.0, le=50.0,
                                  doc="GLOBAL_POSITION_INT rate asked of each vehicle (0: its own)")
    link_timeout_s: float = param(3.0, gt=0.0, le=600.0,
                                  doc="a vehicle silent this long is marked lost, seconds")
    end_action: Literal["rtl", "land"] = param("rtl", doc="what every vehicle is told at the end")


class FlightError(BridgeError):
    """A step of a vehicle's flight did not complete in its time (the message names vehicle and step)."""

    def __init__(self, system_id: int, message: str) -> None:
        self.system_id = system_id
        super().__init__(f"vehicle {system_id}: {message}")


def has_position(state: VehicleState | None) -> TypeGuard[VehicleState]:
    """True when the vehicle reports a position fix (:attr:`VehicleState.has_fix`)."""
    return state is not None and state.has_fix


def is_airborne(state: VehicleState | None, alt_m: float, tolerance_m: float) -> bool:
    """True when the vehicle is armed and within ``tolerance_m`` below ``alt_m`` above its home, or higher."""
    return (state is not None and bool(state.armed) and state.relative_alt_m is not None
            and state.relative_alt_m >= alt_m - tolerance_m)


def _wait_for(tracker: VehicleStateTracker, system_id: int, condition: Callable[[VehicleState | None], bool],
              timeout_s: float, cancel: threading.Event) -> VehicleState | None:
    """Poll the vehicle's state until ``condition`` holds; the last state, or None on timeout.

    Raises:
        FlightError: ``cancel`` was set.
    """
    deadline_s = time.monotonic() + timeout_s
    while True:
        state = tracker.state(system_id)
        if condition(state):
            return state
        if time.monotonic() >= deadline_s:
            return None
        _pause(system_id, _POLL_S, cancel)


def _pause(system_id: int, seconds: float, cancel: threading.Event) -> None:
    if cancel.wait(seconds):
        raise FlightError(system_id, "launch cancelled (the flight is ending)")


def request_position_stream(link: MavlinkLink, system_id: int, rate_hz: float,
                            protocol: ProtocolConfig) -> bool:
    """Ask for GLOBAL_POSITION_INT at ``rate_hz`` (``MAV_CMD_SET_MESSAGE_INTERVAL``); False if refused."""
    try:
        command_long(link, system_id, command=mavlink.MAV_CMD_SET_MESSAGE_INTERVAL,
                     params=(float(mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT), 1e6 / rate_hz),
                     protocol=protocol)
    except BridgeError as exc:
        log.warning("vehicle %d: position stream at %.1f Hz not set (%s: %s); using its own rate",
                    system_id, rate_hz, type(exc).__name__, exc)
        return False
    return True


def set_mode(link: MavlinkLink, system_id: int, custom_mode: tuple[float, ...],
             protocol: ProtocolConfig) -> None:
    """``MAV_CMD_DO_SET_MODE`` to a custom mode (its conventions' ``guided_mode`` or ``mission_mode``)."""
    command_long(link, system_id, command=mavlink.MAV_CMD_DO_SET_MODE,
                 params=(float(mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED), *custom_mode), protocol=protocol)


def _arm(link: MavlinkLink, system_id: int, conventions: Conventions, config: FlightConfig,
         protocol: ProtocolConfig, cancel: threading.Event) -> None:
    deadline_s = time.monotonic() + config.arm_timeout_s
    while True:
        try:
            command_long(link, system_id, command=mavlink.MAV_CMD_COMPONENT_ARM_DISARM, params=(1.0,),
                         protocol=protocol)
            return
        except CommandRejectedError as exc:
            said = list(dict.fromkeys(link.status_texts(system_id, time.monotonic() - config.arm_retry_s)))
            said = [text for text in said if text.startswith(conventions.prearm_prefixes)] or said
            said_text = "; it says: " + ", ".join(f'"{text}"' for text in said[-3:]) if said else ""
            if time.monotonic() + config.arm_retry_s >= deadline_s:
                raise FlightError(system_id, f"arming refused for {config.arm_timeout_s:.0f} s "
                                             f"(last answer: {exc}{said_text})") from None
            log.info("vehicle %d: arming refused (%s%s), asking again in %.1f s", system_id, exc, said_text,
                     config.arm_retry_s)
            _pause(system_id, config.arm_retry_s, cancel)


def _takeoff(link: MavlinkLink, system_id: int, conventions: Conventions, state: VehicleState, alt_m: float,
             protocol: ProtocolConfig, home_alt_m: float | None) -> None:
    nan = math.nan
    if conventions.takeoff_amsl:  # PX4: param7 above mean sea level
        if home_alt_m is None:  # its home from its own position report: altitude less height above home
            if state.alt_m is None or state.relative_alt_m is None:
                raise FlightError(system_id, "take-off altitude unknown: no home altitude (HOME_POSITION) "
                                             "and no altitude in its position report")
            home_alt_m = state.alt_m - state.relative_alt_m
        params = (-1.0, 0.0, 0.0, nan, nan, nan, home_alt_m + alt_m)
    else:  # ArduPilot and the rest: param7 above home
        params = (0.0, 0.0, 0.0, nan, 0.0, 0.0, alt_m)
    command_long(link, system_id, command=mavlink.MAV_CMD_NAV_TAKEOFF, params=params, protocol=protocol)


def launch(link: MavlinkLink, tracker: VehicleStateTracker, system_id: int, autopilot: int, alt_m: float,
           config: FlightConfig, protocol: ProtocolConfig, cancel: threading.Event | None = None,
           home_alt_m: float | None = None,
           takeoff_gate: Callable[[], contextlib.AbstractContextManager[None]] | None = None) -> None:
    """Bring one vehicle to guided flight at ``alt_m`` above its home.

    Asks for the position stream, waits for the first position fix, switches to the guided mode,
    arms (retried while refused) and takes off, then waits until it reaches the altitude. A vehicle
    already armed and airborne is only switched to the guided mode (a vehicle taken back in flight).
    Setting ``cancel`` stops the launch between two steps (nothing more is sent). ``autopilot``
    (its HEARTBEAT's) chooses the conventions (:func:`~bridge.autopilots.conventions_for`);
    ``home_alt_m`` is its home's altitude above mean sea level, from its HOME_POSITION, for an
    autopilot whose take-off altitude is above sea level (``None``: taken from its position report).
    Arming, take-off and climb run inside ``takeoff_gate()`` (a context manager: the caller's turn
    to climb, e.g. one vehicle at a time), so a vehicle is never armed and left waiting on the ground.

    Raises:
        FlightError: No position fix, arming refused or no climb within the configured time, or cancelled.
        CommandRejectedError: The mode or take-off command was refused.
        CommandTimeoutError: A command was never acknowledged.
    """
    started_s = time.time()
    cancel = cancel or threading.Event()

    def fresh_fix(state: VehicleState | None) -> bool:  # not what a restarted vehicle said before
        return (has_position(state) and (state.position_time_s or 0.0) >= started_s
                and (state.heartbeat_time_s or 0.0) >= started_s)

    if config.stream_rate_hz > 0:  # first: ArduPilot streams no position on a link until asked
        request_position_stream(link, system_id, config.stream_rate_hz, protocol)
    state = _wait_for(tracker, system_id, fresh_fix, config.ready_timeout_s, cancel)
    if state is None:
        raise FlightError(system_id, f"no position fix within {config.ready_timeout_s:.0f} s")
    conventions = conventions_for(autopilot)
    guided = conventions.guided_mode
    if is_airborne(state, alt_m, max(config.takeoff_tolerance_m, 0.5 * alt_m)):
        set_mode(link, system_id, guided, protocol)
        log.info("vehicle %d: already airborne at %.1f m, taken back in guided mode", system_id,
                 state.relative_alt_m)
        return
    set_mode(link, system_id, guided, protocol)
    with (takeoff_gate or contextlib.nullcontext)():
        _arm(link, system_id, conventions, config, protocol, cancel)
        state = tracker.state(system_id) or state
        _pause(system_id, 0.0, cancel)
        _takeoff(link, system_id, conventions, state, alt_m, protocol, home_alt_m)
        reached = _wait_for(tracker, system_id, lambda s: is_airborne(s, alt_m, config.takeoff_tolerance_m),
                            config.takeoff_timeout_s, cancel)
    if reached is None:
        last = tracker.state(system_id)
        height = "unknown" if last is None or last.relative_alt_m is None else f"{last.relative_alt_m:.1f} m"
        raise FlightError(system_id, f"did not reach {alt_m:.1f} m within {config.takeoff_timeout_s:.0f} s "
                                     f"(last altitude above home: {height})")
    log.info("vehicle %d: airborne at %.1f m", system_id, reached.relative_alt_m)


def end_flight(link: MavlinkLink, system_id: int, action: Literal["rtl", "land"],
               protocol: ProtocolConfig) -> None:
    """Send the vehicle home (``MAV_CMD_NAV_RETURN_TO_LAUNCH``) or land it where it is (``MAV_CMD_NAV_LAND``).

    Raises:
        CommandRejectedError: The vehicle refused.
        CommandTimeoutError: No answer after every retry.
    """
    if action == "rtl":
        command_long(link, system_id, command=mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, protocol=protocol)
    else:
        nan = math.nan
        command_long(link, system_id, command=mavlink.MAV_CMD_NAV_LAND,
                     params=(0.0, 0.0, 0.0, nan, nan, nan, 0.0), protocol=protocol)
