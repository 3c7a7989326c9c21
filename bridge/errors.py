"""Named exceptions of the MAVLink bridge.

Every ``MAV_MISSION_RESULT`` error code has its own exception class, a subclass of
:class:`MissionResultError` carrying the vehicle's system id and the item sequence
number the vehicle refused (``None`` when the refusal was not about one item).
Timeouts raise :class:`MissionTimeoutError`; refused commands
:class:`CommandRejectedError`; waypoints outside the fence :class:`GeofenceError`
(raised before anything is sent). The bridge's own safety refusals, raised before
anything is sent to the vehicle, are :class:`RefusedError` subclasses:
:class:`HomeMismatchError` and :class:`MissionRunningError`.

Every message of a per-vehicle error starts with ``vehicle <id>``; what the vehicle
said meanwhile (STATUSTEXT) is appended with :meth:`BridgeError.add_detail`.
"""

from __future__ import annotations

from pymavlink.dialects.v20 import common as mavlink

__all__ = [
    "BridgeError",
    "GeofenceError",
    "PlanError",
    "RefusedError",
    "HomeMismatchError",
    "HomeUnknownError",
    "MissionRunningError",
    "VehicleUnreachableError",
    "MissionResultError",
    "MissionGenericError",
    "MissionUnsupportedFrameError",
    "MissionUnsupportedError",
    "MissionNoSpaceError",
    "MissionInvalidError",
    "MissionInvalidParam1Error",
    "MissionInvalidParam2Error",
    "MissionInvalidParam3Error",
    "MissionInvalidParam4Error",
    "MissionInvalidParam5XError",
    "MissionInvalidParam6YError",
    "MissionInvalidParam7Error",
    "MissionInvalidSequenceError",
    "MissionDeniedError",
    "MissionOperationCancelledError",
    "MissionMismatchError",
    "MissionTimeoutError",
    "CommandRejectedError",
    "CommandTimeoutError",
    "HeartbeatTimeoutError",
    "mission_result_error",
]


class BridgeError(Exception):
    """Base class of every error raised by the bridge."""

    def add_detail(self, detail: str) -> None:
        """Append ``detail`` (what the vehicle said, a hint) to the message, once."""
        message = str(self.args[0]) if self.args else ""
        if detail and detail not in message:
            self.args = (f"{message}; {detail}" if message else detail, *self.args[1:])


class GeofenceError(BridgeError, ValueError):
    """A waypoint lies outside the configured area or altitude band; nothing was sent."""


class PlanError(BridgeError, ValueError):
    """A plan or mission file cannot become this vehicle's mission; nothing was sent."""


class RefusedError(BridgeError):
    """The bridge refused, for safety, to send anything to the vehicle (the user can fix or override it)."""


class VehicleUnreachableError(BridgeError):
    """The connection to a vehicle could not be opened (e.g. nothing listens on its TCP port)."""

    def __init__(self, system_id: int, endpoint: str, reason: BaseException) -> None:
        self.system_id = system_id
        super().__init__(f"vehicle {system_id}: cannot connect to {endpoint}: {reason}")


class MissionResultError(BridgeError):
    """The vehicle answered a mission transfer with a ``MAV_MISSION_RESULT`` error code.

    Attributes:
        system_id: The vehicle's MAVLink system id.
        seq: The mission item sequence number concerned, or ``None``.
        result: The ``MAV_MISSION_RESULT`` code.
    """

    result: int = mavlink.MAV_MISSION_ERROR

    def __init__(self, system_id: int, seq: int | None, detail: str = "") -> None:
        self.system_id = system_id
        self.seq = seq
        name = mavlink.enums["MAV_MISSION_RESULT"][self.result].name
        where = f"item {seq}" if seq is not None else "the transfer"
        text = f"vehicle {system_id} refused {where}: {name} ({self.result})"
        super().__init__(f"{text}: {detail}" if detail else text)


def _result_class(name: str, code: int, doc: str) -> type[MissionResultError]:
    return type(name, (MissionResultError,), {"result": code, "__doc__": doc, "__module__": __name__})


MissionGenericError = _result_class(
    "MissionGenericError", mavlink.MAV_MISSION_ERROR, "MAV_MISSION_ERROR: generic error."
)
MissionUnsupportedFrameError = _result_class(
    "MissionUnsupportedFrameError",
    mavlink.MAV_MISSION_UNSUPPORTED_FRAME,
    "MAV_MISSION_UNSUPPORTED_FRAME: the coordinate frame is not supported.",
)
MissionUnsupportedError = _result_class(
    "MissionUnsupportedError",
    mavlink.MAV_MISSION_UNSUPPORTED,
    "MAV_MISSION_UNSUPPORTED: the command is not supported.",
)
MissionNoSpaceError = _result_class(
    "MissionNoSpaceError",
    mavlink.MAV_MISSION_NO_SPACE,
    "MAV_MISSION_NO_SPACE: the mission does not fit in the vehicle's storage.",
)
MissionInvalidError = _result_class(
    "MissionInvalidError", mavlink.MAV_MISSION_INVALID, "MAV_MISSION_INVALID: a parameter is invalid."
)
MissionInvalidParam1Error = _result_class(
    "MissionInvalidParam1Error", mavlink.MAV_MISSION_INVALID_PARAM1, "MAV_MISSION_INVALID_PARAM1."
)
MissionInvalidParam2Error = _result_class(
    "MissionInvalidParam2Error", mavlink.MAV_MISSION_INVALID_PARAM2, "MAV_MISSION_INVALID_PARAM2."
)
MissionInvalidParam3Error = _result_class(
    "MissionInvalidParam3Error", mavlink.MAV_MISSION_INVALID_PARAM3, "MAV_MISSION_INVALID_PARAM3."
)
MissionInvalidParam4Error = _result_class(
    "MissionInvalidParam4Error", mavlink.MAV_MISSION_INVALID_PARAM4, "MAV_MISSION_INVALID_PARAM4."
)
MissionInvalidParam5XError = _result_class(
    "MissionInvalidParam5XError",
    mavlink.MAV_MISSION_INVALID_PARAM5_X,
    "MAV_MISSION_INVALID_PARAM5_X: the x (latitude) value is invalid.",
)
MissionInvalidParam6YError = _result_class(
    "MissionInvalidParam6YError",
    mavlink.MAV_MISSION_INVALID_PARAM6_Y,
    "MAV_MISSION_INVALID_PARAM6_Y: the y (longitude) value is invalid.",
)
MissionInvalidParam7Error = _result_class(
    "MissionInvalidParam7Error",
    mavlink.MAV_MISSION_INVALID_PARAM7,
    "MAV_MISSION_INVALID_PARAM7: the z (altitude) value is invalid.",
)
MissionInvalidSequenceError = _result_class(
    "MissionInvalidSequenceError",
    mavlink.MAV_MISSION_INVALID_SEQUENCE,
    "MAV_MISSION_INVALID_SEQUENCE: an item arrived out of sequence.",
)
MissionDeniedError = _result_class(
    "MissionDeniedError", mavlink.MAV_MISSION_DENIED, "MAV_MISSION_DENIED: the vehicle refuses missions now."
)
MissionOperationCancelledError = _result_class(
    "MissionOperationCancelledError",
    mavlink.MAV_MISSION_OPERATION_CANCELLED,
    "MAV_MISSION_OPERATION_CANCELLED: the vehicle cancelled the transfer.",
)

_BY_CODE: dict[int, type[MissionResultError]] = {
    cls.result: cls
    for cls in (
        MissionGenericError,
        MissionUnsupportedFrameError,
        MissionUnsupportedError,
        MissionNoSpaceError,
        MissionInvalidError,
        MissionInvalidParam1Error,
        MissionInvalidParam2Error,
        MissionInvalidParam3Error,
        MissionInvalidParam4Error,
        MissionInvalidParam5XError,
        MissionInvalidParam6YError,
        MissionInvalidParam7Error,
        MissionInvalidSequenceError,
        MissionDeniedError,
        MissionOperationCancelledError,
    )
}


def mission_result_error(result: int, system_id: int, seq: int | None) -> MissionResultError:
    """The named exception for a ``MAV_MISSION_RESULT`` error code (unknown codes: generic).

    Args:
        result: The code from MISSION_ACK.type.
        system_id: The vehicle that sent it.
        seq: The item concerned, or ``None``.
    """
    cls = _BY_CODE.get(result)
    if cls is None:
        return MissionGenericError(system_id, seq, f"unknown MAV_MISSION_RESULT {result}")
    return cls(system_id, seq)


class MissionMismatchError(BridgeError):
    """The mission read back from a vehicle differs from the one uploaded."""

    def __init__(self, system_id: int, seq: int | None, detail: str) -> None:
        self.system_id = system_id
        self.seq = seq
        where = f"item {seq}" if seq is not None else "its length"
        super().__init__(f"vehicle {system_id}: the mission read back differs in {where}: {detail}")


class MissionTimeoutError(BridgeError, TimeoutError):
    """The vehicle stopped answering a mission transfer after every retry.

    Attributes:
        system_id: The vehicle's MAVLink system id.
        seq: The item being transferred when the time ran out, or ``None``.
        stage: What was awaited (``"MISSION_REQUEST"``, ``"MISSION_ACK"``, ...).
    """

    def __init__(self, system_id: int, seq: int | None, stage: str, waited_s: float) -> None:
        self.system_id = system_id
        self.seq = seq
        self.stage = stage
        where = f" (item {seq})" if seq is not None else ""
        super().__init__(f"vehicle {system_id}: no {stage}{where} after {waited_s:.2f} s and all retries")


class CommandRejectedError(BridgeError):
    """A command was answered with a COMMAND_ACK result other than accepted."""

    def __init__(self, system_id: int, command: int, result: int) -> None:
        self.system_id = system_id
        self.command = command
        self.result = result
        cmd = mavlink.enums["MAV_CMD"][command].name if command in mavlink.enums["MAV_CMD"] else str(command)
        res = (
            mavlink.enums["MAV_RESULT"][result].name if result in mavlink.enums["MAV_RESULT"] else str(result)
        )
        super().__init__(f"vehicle {system_id} rejected {cmd}: {res} ({result})")


class CommandTimeoutError(BridgeError, TimeoutError):
    """A command got no final COMMAND_ACK after every retry."""

    def __init__(self, system_id: int, command: int, waited_s: float) -> None:
        self.system_id = system_id
        self.command = command
        name = mavlink.enums["MAV_CMD"][command].name if command in mavlink.enums["MAV_CMD"] else str(command)
        super().__init__(f"vehicle {system_id}: no COMMAND_ACK for {name} in {waited_s:.2f} s, all retries")


class HeartbeatTimeoutError(BridgeError, TimeoutError):
    """No HEARTBEAT was heard from a vehicle within the discovery time."""

    def __init__(self, system_id: int, endpoint: str, waited_s: float) -> None:
        self.system_id = system_id
        super().__init__(f"vehicle {system_id}: no HEARTBEAT on {endpoint} within {waited_s:.1f} s")


class HomeUnknownError(BridgeError, TimeoutError):
    """A vehicle was not ready in time: no home (HOME_POSITION), or no position fix when one was needed.

    Attributes:
        system_id: The vehicle.
        missing: What did not come (e.g. ``"position fix and home (HOME_POSITION)"``).
    """

    def __init__(self, system_id: int, waited_s: float, missing: str = "home (HOME_POSITION)",
                 said: str = "") -> None:
        self.system_id = system_id
        self.missing = missing
        super().__init__(
            f"vehicle {system_id}: not ready within {waited_s:.1f} s: still no {missing}{said}; its home "
            "cannot be compared with the configured one and nothing was sent (a freshly booted "
            "autopilot needs its GPS fix and its home first: wait longer, [flight] ready_timeout_s or "
            "[protocol] home_timeout_s, or set max_home_offset_m = 0 to upload without the home check)"
        )


class HomeMismatchError(RefusedError, ValueError):
    """A vehicle's reported home is farther from the mission's home than ``max_home_offset_m``.

    Attributes:
        system_id: The vehicle.
        offset_m: Horizontal distance between the two homes, metres.
    """

    def __init__(self, system_id: int, offset_m: float, detail: str) -> None:
        self.system_id = system_id
        self.offset_m = offset_m
        super().__init__(f"vehicle {system_id}: {detail}")


class MissionRunningError(RefusedError):
    """The vehicle flies its mission (armed in its mission mode, any item): clearing or replacing needs force.

    The mission mode is its autopilot's (ArduPilot AUTO, PX4 AUTO.MISSION); ``seq`` is None when
    its mission item could not be learned.
    """

    def __init__(self, system_id: int, operation: str, mode: str, seq: int | None) -> None:
        self.system_id = system_id
        where = (f"at item {seq}" if seq is not None
                 else "its mission item unknown: no MISSION_CURRENT after asking")
        super().__init__(
            f"vehicle {system_id}: is flying its mission (armed, mode {mode}, {where}); refusing to "
            f"{operation} it: a new or empty mission changes what it flies now. Nothing was sent. Switch "
            f"it out of {mode} first, or force it (--force)"
        )
