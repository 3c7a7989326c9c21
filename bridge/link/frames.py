"""MAVLink 2 frames as bytes: packing a message once, and reading a raw frame without decoding it.

A message that is sent more than once (a mission item answering repeated requests) is packed
once into a :class:`PackedMessage` with pymavlink's own field packing; each send then only
writes a fresh sequence number and CRC (:func:`frame`). A received datagram holding exactly
one frame can be inspected in place (:func:`whole_frame_size`, :func:`message_id`) to decide
whether it needs decoding at all, and a mission item request can be read from its raw payload
(:data:`ITEM_REQUEST`).
"""

from __future__ import annotations

import functools
import operator
import struct
from collections.abc import Callable
from typing import Any, NamedTuple

__all__ = [
    "PROTOCOL_MESSAGES",
    "V2_MAGIC",
    "V2_OVERHEAD",
    "SIGNATURE_LEN",
    "IFLAG_SIGNED",
    "ITEM_REQUEST",
    "MavMessage",
    "PackedMessage",
    "Layout",
    "layout",
    "crc_function",
    "pack_body",
    "frame",
    "whole_frame_size",
    "message_id",
]

PROTOCOL_MESSAGES = frozenset(
    {
        "MISSION_REQUEST",
        "MISSION_REQUEST_INT",
        "MISSION_ACK",
        "MISSION_COUNT",
        "MISSION_ITEM",
        "MISSION_ITEM_INT",
        "MISSION_CURRENT",
        "COMMAND_ACK",
        "PARAM_VALUE",
    }
)
"""Message types delivered to an operation's handler."""

V2_MAGIC = 0xFD
V2_OVERHEAD = 12  # magic, 9 header bytes, 2 CRC bytes
SIGNATURE_LEN = 13
IFLAG_SIGNED = 0x01
ITEM_REQUEST = struct.Struct("<HBBB")
"""Payload of MISSION_REQUEST(_INT): seq, target system, target component, mission type."""

_V2_HEADER = struct.Struct("<BBBBBBHB")  # after the magic: len, incompat, compat, seq, sysid, compid, msgid
_SEQ_INDEX = 3  # of the sequence number in a packed body (the frame without magic and CRC)
_MAGIC = bytes((V2_MAGIC,))


MavMessage = Any
"""A decoded pymavlink message, or a pymavlink dialect or connection: pymavlink ships no type information
(its messages are classes generated per dialect, their fields read by name)."""

class PackedMessage(NamedTuple):
    """A message packed once for one link (:meth:`~bridge.link.mavlink.MavlinkLink.pack`).

    Attributes:
        body: The MAVLink 2 frame without its magic byte and CRC (the sequence number is
            written in at each send); ``None`` on a signing link, where each send is signed anew.
        crc_extra: The message type's CRC seed, as one byte.
        message: The pymavlink message to send as such on a signing link, else ``None``.
    """

    body: bytearray | None
    crc_extra: bytes
    message: MavMessage | None


class Layout(NamedTuple):
    """How one message type is packed: its class, CRC seed, wire-ordered fields and id."""

    cls: Any
    crc_extra: bytes
    ordered: Callable[[dict], tuple]
    msg_id: int


@functools.cache
def layout(dialect: MavMessage, message: str) -> Layout:
    """The :class:`Layout` of ``message`` (e.g. ``"mission_item_int"``) in a pymavlink dialect module."""
    cls = getattr(dialect, f"MAVLink_{message}_message")
    return Layout(cls, bytes([cls.crc_extra]), operator.itemgetter(*cls.ordered_fieldnames), cls.id)


def crc_function(dialect: MavMessage) -> Callable[[bytes | bytearray], int]:
    """The MAVLink CRC (CRC-16/MCRF4XX) of some bytes: pymavlink's own, called directly when it is native."""
    native = getattr(dialect, "mcrf4xx", None)  # fastcrc's, when installed
    if native is not None:
        return lambda data: native(data, 0xFFFF)
    return lambda data: dialect.x25crc(data).crc


def pack_body(message: Layout, fields: dict, source_system: int, source_component: int) -> bytearray:
    """A frame without its magic byte and CRC, sequence number 0, trailing zeros cut as MAVLink 2 does."""
    payload = message.cls.unpacker.pack(*message.ordered(fields))
    payload = payload[: max(1, len(payload.rstrip(b"\0")))]
    msg_id = message.msg_id
    header = _V2_HEADER.pack(
        len(payload), 0, 0, 0, source_system, source_component, msg_id & 0xFFFF, msg_id >> 16
    )
    return bytearray(header + payload)


def frame(packed: PackedMessage, seq: int, crc: Callable[[bytes | bytearray], int]) -> bytes:
    """The wire frame of an unsigned :class:`PackedMessage` with sequence number ``seq``."""
    body = packed.body
    if body is None:
        raise ValueError("a message packed for a signing link is sent as such, not framed")
    body[_SEQ_INDEX] = seq
    return _MAGIC + body + crc(body + packed.crc_extra).to_bytes(2, "little")


def whole_frame_size(data: bytes) -> int:
    """The size a MAVLink 2 frame starting ``data`` has (signature included); 0 if it is not one."""
    if len(data) < V2_OVERHEAD or data[0] != V2_MAGIC:
        return 0
    return V2_OVERHEAD + data[1] + (SIGNATURE_LEN if data[2] & IFLAG_SIGNED else 0)


def message_id(data: bytes) -> int:
    """The message id in the header of the MAVLink 2 frame starting ``data``."""
    return data[7] | data[8] << 8 | data[9] << 16
