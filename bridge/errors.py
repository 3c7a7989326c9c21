"""Named exceptions of the MAVLink bridge.

Every ``MAV_MISSION_RESULT`` error code has its own exception class, a subclass of
:class:`MissionResultError` carrying the vehicle's system id and the item sequence
number the vehicle refused (``None`` when the refusal was not about one item).
Timeouts raise :class:`MissionTimeoutError`; refused commands
:class:`CommandRejectedError`; waypoints outside the fence :class:`GeofenceError`
(raised before anything is sent).
"""

from __future__ import annotations

from pymavlink.dialects.v20 import common as mavlink

__all__ = [
    "BridgeError",
    "GeofenceError",
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


class GeofenceError(BridgeError, ValueError):
    """A waypoint lies outside the configured area or altitude band; nothing was sent."""


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
        super().__init__(f"vehicle {system_id}: downloaded mission differs at item {seq}: {detail}")


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
    """A COMMAND_INT was answered with a COMMAND_ACK result other than accepted."""

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
    """A COMMAND_INT got no final COMMAND_ACK after every retry."""

    def __init__(self, system_id: int, command: int, waited_s: float) -> None:
        self.system_id = system_id
        self.command = command
        super().__init__(f"vehicle {system_id}: no COMMAND_ACK for command {command} after {waited_s:.2f} s")


class HeartbeatTimeoutError(BridgeError, TimeoutError):
    """No HEARTBEAT was heard from a vehicle within the discovery time."""

    def __init__(self, system_id: int, endpoint: str, waited_s: float) -> None:
        self.system_id = system_id
        super().__init__(f"no HEARTBEAT from vehicle {system_id} on {endpoint} within {waited_s:.1f} s")
