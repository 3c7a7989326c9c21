"""Commands to a vehicle (COMMAND_INT, COMMAND_LONG) and guided replanning with ``MAV_CMD_DO_REPOSITION``.

The reposition's altitude follows the vehicle's autopilot (:mod:`bridge.autopilots`): ArduPilot
takes ``MAV_FRAME_GLOBAL_RELATIVE_ALT_INT`` with z above its home; PX4 reads z above mean sea level
whatever the frame says, so it gets ``MAV_FRAME_GLOBAL_INT`` with z = its home altitude (its
HOME_POSITION) + the height.

A command is sent again when no COMMAND_ACK arrives within the handshake
timeout (up to ``max_retries`` times); ``MAV_RESULT_IN_PROGRESS`` keeps waiting,
``MAV_RESULT_ACCEPTED`` succeeds, any other result raises
:class:`~bridge.errors.CommandRejectedError`.
"""

from __future__ import annotations

import queue
import time
from collections.abc import Callable

from bridge.autopilots import GENERIC, Conventions
from bridge.config import ProtocolConfig
from bridge.errors import CommandRejectedError, CommandTimeoutError, RefusedError
from bridge.geo import Home, enu_to_geodetic
from bridge.geofence import GeofenceConfig, check_geofence
from bridge.link.mavlink import MavlinkLink
from bridge.missions.items import DEG_E7

__all__ = ["command_int", "command_long", "reposition"]


def _await_ack(
    link: MavlinkLink, system_id: int, command: int, send: Callable[[], None], protocol: ProtocolConfig
) -> None:
    """Send with ``send()`` and wait for ``command``'s final COMMAND_ACK, re-sending on silence."""
    m = link.mavlink
    with link.inbox(system_id) as box:
        send()
        tries = 0
        deadline_s = time.monotonic() + protocol.handshake_timeout_s
        while True:
            try:
                msg = box.get(timeout=max(0.0, deadline_s - time.monotonic()))
            except queue.Empty:
                tries += 1
                if tries > protocol.max_retries:
                    raise CommandTimeoutError(
                        system_id, command, protocol.handshake_timeout_s * tries
                    ) from None
                deadline_s = time.monotonic() + protocol.handshake_timeout_s
                send()
                continue
            if msg.get_type() != "COMMAND_ACK" or msg.command != command:
                continue
            if msg.result == m.MAV_RESULT_ACCEPTED:
                return
            if msg.result == m.MAV_RESULT_IN_PROGRESS:
                tries = 0
                deadline_s = time.monotonic() + protocol.handshake_timeout_s
                continue
            raise CommandRejectedError(system_id, command, msg.result)


def command_int(
    link: MavlinkLink,
    system_id: int,
    *,
    command: int,
    frame: int,
    params: tuple[float, ...] = (),
    x: int = 0,
    y: int = 0,
    z: float = 0.0,
    protocol: ProtocolConfig | None = None,
    component_id: int = 1,
) -> None:
    """Send a COMMAND_INT and wait for its final COMMAND_ACK.

    Args:
        link: The connection reaching the vehicle.
        system_id: The vehicle.
        command: ``MAV_CMD_*``.
        frame: ``MAV_FRAME_*`` of ``x``, ``y``, ``z``.
        params: param1..param4 (missing ones are 0).
        x: Latitude, degE7 (global frames).
        y: Longitude, degE7.
        z: Altitude, metres.
        protocol: Timeouts and retries.
        component_id: The vehicle's autopilot component.

    Raises:
        CommandRejectedError: The ACK's result is not accepted (nor in progress).
        CommandTimeoutError: No final ACK after every retry.
    """
    p = (*params, 0.0, 0.0, 0.0, 0.0)[:4]

    def send() -> None:
        link.send(
            lambda mav: mav.command_int_send(
                target_system=system_id,
                target_component=component_id,
                frame=frame,
                command=command,
                current=0,
                autocontinue=0,
                param1=p[0],
                param2=p[1],
                param3=p[2],
                param4=p[3],
                x=x,
                y=y,
                z=z,
            )
        )

    _await_ack(link, system_id, command, send, protocol or ProtocolConfig())


def command_long(
    link: MavlinkLink,
    system_id: int,
    *,
    command: int,
    params: tuple[float, ...] = (),
    protocol: ProtocolConfig | None = None,
    component_id: int = 1,
) -> None:
    """Send a COMMAND_LONG and wait for its final COMMAND_ACK.

    A re-send after silence carries an incremented ``confirmation`` field, as the command
    protocol asks, so the vehicle can tell a retry from a new command.

    Args:
        link: The connection reaching the vehicle.
        system_id: The vehicle.
        command: ``MAV_CMD_*``.
        params: param1..param7 (missing ones are 0).
        protocol: Timeouts and retries.
        component_id: The vehicle's autopilot component.

    Raises:
        CommandRejectedError: The ACK's result is not accepted (nor in progress).
        CommandTimeoutError: No final ACK after every retry.
    """
    p = (*params, *([0.0] * 7))[:7]
    confirmation = -1

    def send() -> None:
        nonlocal confirmation
        confirmation = min(confirmation + 1, 255)
        link.send(
            lambda mav: mav.command_long_send(
                system_id, component_id, command, confirmation, p[0], p[1], p[2], p[3], p[4], p[5], p[6]
            )
        )

    _await_ack(link, system_id, command, send, protocol or ProtocolConfig())


def reposition(
    link: MavlinkLink,
    system_id: int,
    home: Home,
    fence: GeofenceConfig,
    x_m: float,
    y_m: float,
    z_m: float,
    *,
    speed_m_s: float = -1.0,
    protocol: ProtocolConfig | None = None,
    conventions: Conventions = GENERIC,
    home_alt_m: float | None = None,
) -> None:
    """Send a guided vehicle to a new ENU point (``MAV_CMD_DO_REPOSITION``, switching to guided mode).

    Args:
        link: The connection reaching the vehicle.
        system_id: The vehicle.
        home: Origin of the ENU frame.
        fence: Checked before anything is sent.
        x_m: East of home, metres.
        y_m: North of home, metres.
        z_m: Height above home, metres.
        speed_m_s: Ground speed, m/s (-1: the vehicle's default).
        protocol: Timeouts and retries.
        conventions: The vehicle's autopilot conventions (frame and altitude reference).
        home_alt_m: The vehicle's own home altitude above mean sea level (needed when its
            conventions read the altitude above sea level).

    Raises:
        RefusedError: ``home_alt_m`` is missing where it is needed (nothing sent).
        GeofenceError: The point is outside the fence (nothing sent).
        CommandRejectedError: The vehicle refused.
        CommandTimeoutError: No answer.
    """
    check_geofence([(x_m, y_m, z_m)], fence)
    z = z_m
    if conventions.reposition_amsl:
        if home_alt_m is None:
            raise RefusedError(f"vehicle {system_id}: {conventions.name} reads a reposition altitude above "
                               "sea level and its home altitude (HOME_POSITION) is unknown: nothing sent")
        z = home_alt_m + z_m
    m = link.mavlink
    lat_deg, lon_deg, _ = enu_to_geodetic(home, x_m, y_m, z_m)
    command_int(
        link,
        system_id,
        command=m.MAV_CMD_DO_REPOSITION,
        frame=conventions.reposition_frame,
        params=(speed_m_s, float(m.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE), 0.0, float("nan")),
        x=round(lat_deg * DEG_E7),
        y=round(lon_deg * DEG_E7),
        z=z,
        protocol=protocol,
    )
