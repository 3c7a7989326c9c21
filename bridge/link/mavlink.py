"""MAVLink connections shared by every client of the vehicles behind them.

A :class:`MavlinkLink` is one pymavlink connection with exactly one reader (a
:class:`~bridge.link.reader.LinkReader`, shared by the links of a fleet) and a send lock.
Received messages go to the state listeners and, for the mission and command protocols,
to the handler of the operation running with that vehicle, which can answer at once on the
reading thread. Each vehicle's recent STATUSTEXT messages are kept
(:meth:`MavlinkLink.status_texts`) so that an error can show what the vehicle said.

Hot paths stay short (frames as bytes: :mod:`bridge.link.frames`): a datagram holding
exactly one MAVLink 2 frame is decoded directly (pymavlink's byte-stream parser only for
anything else), and not at all when no one reads its type; a mission item request on an
unsigned link is answered from its checked raw frame before it is decoded (see
:meth:`MavlinkLink.protocol_handler`); and a message sent more than once (a mission item)
can be packed once (:meth:`MavlinkLink.pack`) and then sent with only its sequence number
and CRC renewed (:meth:`MavlinkLink.send_packed`).

Works over ``udpin:``, ``udpout:`` and ``tcp:`` connection strings; a TCP connection
the vehicle closes (a restarted autopilot) is tried again every second. The process
speaks MAVLink 2 (pymavlink selects the protocol through the ``MAVLINK20``
environment variable, which :class:`MavlinkLink` sets before its first connection).
"""

from __future__ import annotations

import collections
import contextlib
import logging
import os
import queue
import socket
import threading
import time
from collections.abc import Callable, Iterable, Iterator

from bridge.errors import HeartbeatTimeoutError
from bridge.link.frames import (
    IFLAG_SIGNED,
    ITEM_REQUEST,
    PROTOCOL_MESSAGES,
    MavMessage,
    PackedMessage,
    crc_function,
    frame,
    layout,
    message_id,
    pack_body,
    whole_frame_size,
)
from bridge.link.reader import LinkReader
from bridge.link.signing import SigningKey

__all__ = ["MavlinkLink", "LinkReader", "PackedMessage", "PROTOCOL_MESSAGES", "use_mavlink2"]

log = logging.getLogger(__name__)

_HEARTBEAT_PERIOD_S = 1.0
_RECV_BYTES = 65536
_RECONNECT_PERIOD_S = 1.0  # a TCP link the vehicle closed is tried again this often
_RECONNECT_TIMEOUT_S = 0.1  # each try waits at most this long (on the reading thread)
_STATUS_TEXTS_KEPT = 32  # per vehicle


def use_mavlink2() -> MavMessage:
    """Import pymavlink's mavutil in MAVLink 2 mode (process-wide, as pymavlink decides it)."""
    os.environ["MAVLINK20"] = "1"
    from pymavlink import mavutil

    if mavutil.mavlink.WIRE_PROTOCOL_VERSION != "2.0":  # imported before MAVLINK20 was set
        mavutil.set_dialect(mavutil.current_dialect)
    return mavutil


class MavlinkLink:
    """A pymavlink connection with one reader, a send lock and per-vehicle protocol handlers.

    Args:
        url: ``udpin:HOST:PORT``, ``udpout:HOST:PORT`` or ``tcp:HOST:PORT``.
        source_system: Our system id.
        source_component: Our component id.
        signing_key: MAVLink 2 signing key, or ``None``.
        signing_link_id: Our signing link id.
        allow_unsigned: Accept unsigned messages when signing.
        reader: The reader thread to join (a fleet's shared one); ``None``: a reader of its own.
    """

    def __init__(
        self,
        url: str,
        *,
        source_system: int = 255,
        source_component: int = 190,
        signing_key: SigningKey | None = None,
        signing_link_id: int = 0,
        allow_unsigned: bool = False,
        reader: LinkReader | None = None,
    ) -> None:
        mavutil = use_mavlink2()
        self.url = url
        self.source_system = source_system
        self._mavlink = mavutil.mavlink
        # One try (retries=0): pymavlink's own retries print to stdout; a refused TCP connection is
        # tried again by the fleet (FleetVehicles), which logs it.
        self._conn = mavutil.mavlink_connection(
            url, source_system=source_system, source_component=source_component, retries=0
        )
        if url.startswith("tcp:"):  # pymavlink prints these too; this link logs and reconnects itself
            self._conn.handle_eof = self._conn.handle_disconnect = lambda: None
        if signing_key is not None:
            self._conn.setup_signing(
                signing_key.secret,
                sign_outgoing=True,
                link_id=signing_link_id,
                allow_unsigned_callback=(lambda _mav, _msg_id: True) if allow_unsigned else None,
            )
        self._signing = signing_key is not None
        self._send_lock = threading.Lock()
        self._state_lock = threading.Condition()
        self._heartbeats: dict[int, MavMessage] = {}
        self._handlers: dict[int, Callable[[MavMessage], None]] = {}
        self._responders: dict[int, Callable[[int], None]] = {}
        m = mavutil.mavlink
        self._crc = crc_function(m)
        self._request_crc_extra = {
            cls.id: bytes([cls.crc_extra])
            for cls in (m.MAVLink_mission_request_message, m.MAVLink_mission_request_int_message)
        }
        self._busy: dict[int, threading.Lock] = {}
        self._listeners: list[tuple[Callable[[MavMessage], None], frozenset[int] | None]] = []
        self._listened_ids: frozenset[int] | None = frozenset()  # None: some listener takes every message
        self._own_ids = self._message_ids((*PROTOCOL_MESSAGES, "HEARTBEAT", "STATUSTEXT"))
        self._status_texts: dict[int, collections.deque[tuple[float, str]]] = {}
        self._recv_lock = threading.Lock()
        self._closed = False
        self._tcp = url.startswith("tcp:")
        self._eof = False
        self._next_reconnect_s = 0.0
        self._last_heartbeat_s = 0.0
        self._own_reader = reader is None
        self._reader = LinkReader(f"mavlink {url}") if reader is None else reader
        self._reader.add(self)

    @property
    def reader(self) -> LinkReader:
        """The reader of this link (shared with the other links of a fleet)."""
        return self._reader

    @property
    def mavlink(self) -> MavMessage:
        """The pymavlink dialect module (for constants)."""
        return self._mavlink

    def add_listener(self, callback: Callable[[MavMessage], None],
                     types: Iterable[str] | None = None) -> None:
        """Call ``callback(msg)`` for every received message (on the reading thread: keep it short).

        Args:
            callback: Called with each message.
            types: Only these message types (e.g. ``{"HEARTBEAT"}``); a message that neither
                we nor any listener wants is not decoded at all. ``None``: every message.
        """
        ids = None if types is None else self._message_ids(types)
        with self._state_lock:
            self._listeners = [*self._listeners, (callback, ids)]  # copy on write: the reader iterates freely
            listened = self._listened_ids
            self._listened_ids = None if ids is None or listened is None else listened | ids

    def _message_ids(self, types: Iterable[str]) -> frozenset[int]:
        return frozenset(getattr(self._mavlink, f"MAVLINK_MSG_ID_{kind}") for kind in types)

    def send(self, action: Callable[[MavMessage], None]) -> None:
        """Run ``action(mav)`` (e.g. ``lambda mav: mav.mission_count_send(...)``) under the send lock."""
        with self._send_lock:
            action(self._conn.mav)

    def pack(self, message: str, **fields: float | int) -> PackedMessage:
        """Pack a message with numeric fields only (e.g. ``pack("mission_item_int", seq=0, ...)``) once.

        The body is pymavlink's own packing (field order, trailing zeros cut as MAVLink 2 does),
        so :meth:`send_packed` puts on the wire what ``mav.<message>_send(**fields)`` would.
        """
        kind = layout(self._mavlink, message)
        if self._signing:
            return PackedMessage(None, kind.crc_extra, kind.cls(**fields))
        mav = self._conn.mav
        return PackedMessage(pack_body(kind, fields, mav.srcSystem, mav.srcComponent), kind.crc_extra, None)

    def send_packed(self, packed: PackedMessage) -> None:
        """Send a :meth:`pack`-ed message with the link's next sequence number (under the send lock)."""
        with self._send_lock:
            mav = self._conn.mav
            if packed.body is None:
                mav.send(packed.message)
                return
            wire = frame(packed, mav.seq, self._crc)
            self._conn.write(wire)
            mav.seq = (mav.seq + 1) % 256
            mav.total_packets_sent += 1
            mav.total_bytes_sent += len(wire)

    def wait_heartbeat(self, system_id: int, timeout_s: float) -> MavMessage:
        """The first (or latest) HEARTBEAT of a vehicle, waiting at most ``timeout_s``.

        Raises:
            HeartbeatTimeoutError: None arrived in time.
        """
        deadline = time.monotonic() + timeout_s
        with self._state_lock:
            while system_id not in self._heartbeats:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise HeartbeatTimeoutError(system_id, self.url, timeout_s)
                self._state_lock.wait(remaining)
            return self._heartbeats[system_id]

    def status_texts(self, system_id: int, since_s: float) -> list[str]:
        """The vehicle's STATUSTEXT texts received since ``since_s`` (``time.monotonic()``), oldest first."""
        with self._state_lock:
            kept = list(self._status_texts.get(system_id, ()))
        return [text for time_s, text in kept if time_s >= since_s]

    @contextlib.contextmanager
    def protocol_handler(
        self,
        system_id: int,
        handler: Callable[[MavMessage], None],
        on_request: Callable[[int], None] | None = None,
    ) -> Iterator[None]:
        """Route one vehicle's protocol messages to ``handler`` during one operation.

        ``handler(msg)`` runs on the reading thread as each message arrives, so it can answer
        at once (keep it short). With ``on_request``, a mission item request (MISSION_REQUEST_INT
        or MISSION_REQUEST, mission type 0, for us) arriving alone in an unsigned datagram is
        answered sooner: ``on_request(seq)`` is called from its raw frame once its CRC checks,
        before it is decoded, and ``handler`` does not get that request. Operations with the
        same vehicle run one after the other; messages that arrive while none runs are
        dropped, so each operation starts clean.
        """
        with self._state_lock:
            busy = self._busy.setdefault(system_id, threading.Lock())
        with busy:
            with self._state_lock:
                self._handlers[system_id] = handler
                if on_request is not None:
                    self._responders[system_id] = on_request
            try:
                yield
            finally:
                with self._state_lock:
                    self._handlers.pop(system_id, None)
                    self._responders.pop(system_id, None)

    @contextlib.contextmanager
    def inbox(self, system_id: int) -> Iterator[queue.Queue]:
        """Like :meth:`protocol_handler`, with the messages put in a queue for the caller to read."""
        box: queue.Queue = queue.Queue()
        with self.protocol_handler(system_id, box.put):
            yield box

    def close(self) -> None:
        """Stop reading (and the reader thread if it is this link's own) and close the connection."""
        self._reader.remove(self)
        if self._own_reader:
            self._reader.close()
        with self._recv_lock, self._send_lock:
            self._closed = True
            self._conn.close()

    def __enter__(self) -> MavlinkLink:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _send_heartbeat(self) -> None:
        m = self._mavlink
        self.send(
            lambda mav: mav.heartbeat_send(
                type=m.MAV_TYPE_GCS,
                autopilot=m.MAV_AUTOPILOT_INVALID,
                base_mode=0,
                custom_mode=0,
                system_status=m.MAV_STATE_ACTIVE,
            )
        )

    def reader_fd(self) -> int | None:
        """The socket its reader waits on; ``None`` while closed or disconnected."""
        return None if self._closed or self._eof else self._conn.fd

    def heartbeat_if_due(self, now_s: float) -> None:
        """Send our HEARTBEAT when a second has passed since the last (its reader calls this)."""
        if now_s - self._last_heartbeat_s < _HEARTBEAT_PERIOD_S or self._closed:
            return
        self._last_heartbeat_s = now_s
        try:
            self._send_heartbeat()
        except OSError as exc:
            log.debug("%s: heartbeat not sent: %s", self.url, exc)

    def reconnect_if_due(self, now_s: float) -> bool:
        """Try now and then to reopen a TCP connection the vehicle closed; True when it is open again.

        A restarted autopilot (a SITL instance, a companion computer's router) listens again on its
        port: the link is taken back as it was, its listeners and handlers kept.
        """
        if not (self._tcp and self._eof) or self._closed or now_s < self._next_reconnect_s:
            return False
        self._next_reconnect_s = now_s + _RECONNECT_PERIOD_S
        try:
            sock = socket.create_connection(self._conn.destination_addr, timeout=_RECONNECT_TIMEOUT_S)
        except OSError as exc:
            log.debug("%s: reconnection failed: %s", self.url, exc)
            return False
        sock.setblocking(False)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        with self._recv_lock, self._send_lock:
            if self._closed:
                sock.close()
                return False
            old, self._conn.port, self._conn.fd = self._conn.port, sock, sock.fileno()
            if old is not None:
                old.close()
            self._eof = False
        log.warning("%s: connection to the vehicle re-established", self.url)
        return True

    def read_available(self) -> bool:
        """Receive one datagram (or TCP chunk) and dispatch its messages; False once the stream ended.

        Reading thread only. ``recv`` + decoding rather than ``recv_match``: the same transport
        and signing checks without mavutil's per-message bookkeeping, which we do not use.
        """
        with self._recv_lock:
            if self._closed:
                return False
            try:
                data = self._conn.recv(_RECV_BYTES)
            except (OSError, ValueError) as exc:
                log.debug("%s: receive error: %s", self.url, exc)
                return True
            if not data:
                if self._tcp:  # readable yet empty: the vehicle closed the connection
                    log.warning("%s: connection closed by the vehicle; reconnecting every %.0f s",
                                self.url, _RECONNECT_PERIOD_S)
                    self._eof = True
                    self._next_reconnect_s = time.monotonic() + _RECONNECT_PERIOD_S
                return not self._tcp
            answered = self._answer_request(data)
            if not self._wanted(data, answered):
                return True
            try:
                messages = self._parse(data)
            except (ValueError, self._mavlink.MAVError) as exc:
                log.debug("%s: receive error: %s", self.url, exc)
                return True
        for msg in messages:
            self._dispatch(msg, answered)
        return True

    def _wanted(self, data: bytes, answered: bool) -> bool:
        """False for a datagram holding one MAVLink 2 frame that no one would read: not decoded.

        Wanted are the message types of the listeners, and ours (heartbeats, status texts,
        the protocols' messages) unless the message is a request already answered.
        """
        listened = self._listened_ids
        if listened is None or whole_frame_size(data) != len(data):
            return True  # not one whole MAVLink 2 frame: the parser decides
        msg_id = message_id(data)
        return msg_id in listened or (msg_id in self._own_ids and not answered)

    def _answer_request(self, data: bytes) -> bool:
        """Pass a mission item request to its vehicle's ``on_request`` straight from the raw frame.

        Only for one whole unsigned MAVLink 2 frame on an unsigned link whose CRC checks;
        True when it was passed on (the decoded message then skips the handler).
        """
        if not self._responders or self._signing or whole_frame_size(data) != len(data) or data[2]:
            return False
        extra = self._request_crc_extra.get(message_id(data))
        respond = self._responders.get(data[5])
        if extra is None or respond is None:
            return False
        if self._crc(data[1:-2] + extra) != int.from_bytes(data[-2:], "little"):
            return False
        payload = data[10:-2].ljust(ITEM_REQUEST.size, b"\0")  # MAVLink 2 cuts trailing zeros
        seq, target_system, _, mission_type = ITEM_REQUEST.unpack_from(payload)
        if mission_type != 0 or target_system not in (0, self.source_system):
            return False
        try:
            respond(seq)
        except Exception:
            log.exception("%s: request responder failed for vehicle %d", self.url, data[5])
        return True

    def _parse(self, data: bytes) -> list:
        """The messages in ``data``: one whole MAVLink 2 frame decoded at once, else pymavlink's parser.

        ``decode`` checks the CRC and the signature as the parser would; a frame that fails is
        dropped, as the parser's BAD_DATA would be.
        """
        mav = self._conn.mav
        if mav.buf_len() == 0 and whole_frame_size(data) == len(data) and not data[2] & ~IFLAG_SIGNED:
            try:
                return [mav.decode(bytearray(data))]
            except self._mavlink.MAVError as exc:
                log.debug("%s: dropped a frame: %s", self.url, exc)
                return []
        return mav.parse_buffer(data) or []

    def _dispatch(self, msg: MavMessage, answered: bool = False) -> None:
        """Note heartbeats and status texts; hand ``msg`` to its handler (unless ``answered``), listeners."""
        kind = msg.get_type()
        if kind == "BAD_DATA":
            return
        system_id = msg.get_srcSystem()
        if system_id == self.source_system:
            return
        if kind == "HEARTBEAT" and msg.get_srcComponent() == self._mavlink.MAV_COMP_ID_AUTOPILOT1:
            with self._state_lock:
                self._heartbeats[system_id] = msg
                self._state_lock.notify_all()
        elif kind == "STATUSTEXT":
            text = str(msg.text).rstrip("\x00").strip()
            with self._state_lock:
                kept = self._status_texts.setdefault(system_id, collections.deque(maxlen=_STATUS_TEXTS_KEPT))
                kept.append((time.monotonic(), text))
        handler = self._handlers.get(system_id)  # dict reads are atomic; writes hold the lock
        listeners = self._listeners
        if (
            handler is not None
            and not answered
            and kind in PROTOCOL_MESSAGES
            and getattr(msg, "target_system", self.source_system) in (0, self.source_system)
        ):
            try:
                handler(msg)
            except Exception:
                log.exception("%s: protocol handler failed for vehicle %d", self.url, system_id)
        msg_id = msg.get_msgId()
        for callback, ids in listeners:
            if ids is not None and msg_id not in ids:
                continue
            try:
                callback(msg)
            except Exception:
                log.exception("%s: message listener failed", self.url)
