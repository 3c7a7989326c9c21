"""A vehicle's parameters by name: ``PARAM_REQUEST_READ`` and ``PARAM_SET``, each answered by ``PARAM_VALUE``.

The parameter protocol has no acknowledgement of its own: the vehicle answers a read, and a set,
with a PARAM_VALUE of the parameter (a set's answer carries the value it now holds). A request
without an answer is sent again after the handshake timeout, up to ``max_retries`` times, then
:class:`ParamError` names the vehicle and the parameter (an autopilot stays silent for a name it
does not know).

PARAM_VALUE carries a float. ArduPilot *casts* integer parameters to it (``3`` is ``3.0``); PX4
puts an integer's four bytes in it as they are (``MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE``):
``bytewise`` says which (:attr:`bridge.autopilots.Conventions.param_bytewise`).

Examples:
    >>> from pymavlink.dialects.v20 import common as mavlink
    >>> encode_param(2, mavlink.MAV_PARAM_TYPE_INT32, bytewise=True) == 2.0
    False
    >>> decode_param(encode_param(2, mavlink.MAV_PARAM_TYPE_INT32, bytewise=True),
    ...              mavlink.MAV_PARAM_TYPE_INT32, bytewise=True)
    2.0
"""

from __future__ import annotations

import math
import queue
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink

from bridge.config import ProtocolConfig
from bridge.errors import BridgeError
from bridge.link.frames import MavMessage
from bridge.link.mavlink import MavlinkLink

__all__ = ["ParamValue", "ParamError", "read_param", "set_param", "encode_param", "decode_param"]

_INTEGER_FORMATS = {
    mavlink.MAV_PARAM_TYPE_UINT8: "<B", mavlink.MAV_PARAM_TYPE_INT8: "<b",
    mavlink.MAV_PARAM_TYPE_UINT16: "<H", mavlink.MAV_PARAM_TYPE_INT16: "<h",
    mavlink.MAV_PARAM_TYPE_UINT32: "<I", mavlink.MAV_PARAM_TYPE_INT32: "<i",
}


class ParamError(BridgeError):
    """A parameter could not be read or set (the message names the vehicle, the parameter and why)."""

    def __init__(self, system_id: int, name: str, reason: str) -> None:
        self.system_id = system_id
        self.name = name
        super().__init__(f"vehicle {system_id}: parameter {name}: {reason}")


@dataclass(frozen=True)
class ParamValue:
    """One parameter as the vehicle holds it: its value (decoded) and its ``MAV_PARAM_TYPE``."""

    name: str
    value: float
    param_type: int


def encode_param(value: float, param_type: int, *, bytewise: bool) -> float:
    """The PARAM_SET float of ``value`` for a parameter of ``param_type``."""
    fmt = _INTEGER_FORMATS.get(param_type)
    if fmt is None:
        return float(value)
    integer = int(round(value))
    if not bytewise:
        return float(integer)
    raw = struct.pack("<i" if fmt.islower() else "<I", integer)  # the union's four bytes
    return struct.unpack("<f", raw)[0]


def decode_param(value: float, param_type: int, *, bytewise: bool) -> float:
    """The number a PARAM_VALUE float means for a parameter of ``param_type``."""
    fmt = _INTEGER_FORMATS.get(param_type)
    if fmt is None or not bytewise:
        return float(value)
    raw = struct.pack("<f", value)
    return float(struct.unpack(fmt, raw[:struct.calcsize(fmt)])[0])


def _exchange(link: MavlinkLink, system_id: int, name: str, send: Callable[[], None],
              protocol: ProtocolConfig, what: str,
              accept: Callable[[MavMessage], bool] | None = None) -> MavMessage:
    """Send with ``send()`` until a PARAM_VALUE of ``name`` arrives (that ``accept`` takes); that message.

    A PARAM_VALUE that ``accept`` refuses may be a late answer to an earlier request (a retried read
    answered twice): it is kept and the exchange goes on; after every retry the last one kept is returned.
    """
    refused = None
    with link.inbox(system_id) as box:
        for _ in range(protocol.max_retries + 1):
            send()
            deadline_s = time.monotonic() + protocol.handshake_timeout_s
            while (left_s := deadline_s - time.monotonic()) > 0:
                try:
                    msg = box.get(timeout=left_s)
                except queue.Empty:
                    break
                if msg.get_type() == "PARAM_VALUE" and str(msg.param_id).rstrip("\x00") == name:
                    if accept is None or accept(msg):
                        return msg
                    refused = msg
    if refused is not None:
        return refused
    waited_s = protocol.handshake_timeout_s * (protocol.max_retries + 1)
    raise ParamError(system_id, name, f"no PARAM_VALUE answered {what} in {waited_s:.1f} s, "
                                      f"{protocol.max_retries + 1} tries (a name this autopilot does not "
                                      "have?)")


def read_param(link: MavlinkLink, system_id: int, name: str, *, bytewise: bool,
               protocol: ProtocolConfig | None = None, component_id: int = 1) -> ParamValue:
    """Read one parameter (``PARAM_REQUEST_READ`` by name).

    Raises:
        ParamError: No answer after every retry.
    """
    protocol = protocol or ProtocolConfig()

    def send() -> None:
        link.send(lambda mav: mav.param_request_read_send(system_id, component_id, name.encode(), -1))

    msg = _exchange(link, system_id, name, send, protocol, "PARAM_REQUEST_READ")
    return ParamValue(name, decode_param(msg.param_value, msg.param_type, bytewise=bytewise), msg.param_type)


def set_param(link: MavlinkLink, system_id: int, name: str, value: float, param_type: int, *, bytewise: bool,
              protocol: ProtocolConfig | None = None, component_id: int = 1) -> ParamValue:
    """Set one parameter (``PARAM_SET``) and check the value the vehicle answers that it holds.

    An answer with another value is taken as the vehicle's only when no answer with the value set comes
    within every retry (an earlier read's late answer is not a refusal).

    Raises:
        ParamError: No answer after every retry, or the vehicle kept another value.
    """
    protocol = protocol or ProtocolConfig()
    wire = encode_param(value, param_type, bytewise=bytewise)

    def send() -> None:
        link.send(lambda mav: mav.param_set_send(system_id, component_id, name.encode(), wire, param_type))

    def holds(msg: MavMessage) -> bool:
        held = decode_param(msg.param_value, msg.param_type, bytewise=bytewise)
        return math.isclose(held, value, rel_tol=1e-6, abs_tol=1e-6)

    msg = _exchange(link, system_id, name, send, protocol, "PARAM_SET", accept=holds)
    held = decode_param(msg.param_value, msg.param_type, bytewise=bytewise)
    if not math.isclose(held, value, rel_tol=1e-6, abs_tol=1e-6):
        raise ParamError(system_id, name, f"set to {value:g}, the vehicle holds {held:g}")
    return ParamValue(name, held, msg.param_type)
