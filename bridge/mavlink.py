"""MAVLink connections shared by every client of the vehicles behind them.

pymavlink connections are not thread-safe, so each :class:`MavlinkLink` has exactly
one reader: a :class:`LinkReader`, whose thread waits on the sockets of all its links
at once (one ``select``), receives every message and sends our ground-station
HEARTBEAT once a second, and which a caller waiting for answers can borrow to read on
its own thread meanwhile (:meth:`LinkReader.lend`); every send goes through the link's
send lock. A fleet shares one reader among its links (no thread per link competing for
the GIL); a link made alone gets its own. Received messages go to the state listeners
and, for the mission and command protocols, to the handler of the operation running
with that vehicle, which can answer at once on the reading thread. Each vehicle's recent
STATUSTEXT messages are kept (:meth:`MavlinkLink.status_texts`) so that an error can
show what the vehicle said.

Hot paths stay short: a datagram holding exactly one MAVLink 2 frame is decoded directly
(pymavlink's byte-stream parser only for anything else); a mission item request on an
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
import functools
import logging
import operator
import os
import queue
import select
import socket
import struct
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from typing import NamedTuple

from bridge.errors import HeartbeatTimeoutError
from bridge.signing import SigningKey

__all__ = ["MavlinkLink", "LinkReader", "PackedMessage", "PROTOCOL_MESSAGES", "use_mavlink2"]

log = logging.getLogger(__name__)

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
    }
)
"""Message types delivered to an operation's handler."""

_HEARTBEAT_PERIOD_S = 1.0
_POLL_S = 0.02
_RECV_BYTES = 65536
_RECONNECT_PERIOD_S = 1.0  # a TCP link the vehicle closed is tried again this often
_RECONNECT_TIMEOUT_S = 0.1  # each try waits at most this long (on the reading thread)
_STATUS_TEXTS_KEPT = 32  # per vehicle
_V2_MAGIC = 0xFD
_V2_OVERHEAD = 12  # magic, 9 header bytes, 2 CRC bytes
_SIGNATURE_LEN = 13
_IFLAG_SIGNED = 0x01
_V2_HEADER = struct.Struct("<BBBBBBHB")  # after the magic: len, incompat, compat, seq, sysid, compid, msgid
_SEQ_INDEX = 3  # of the sequence number in a packed body (the frame without magic and CRC)
_ITEM_REQUEST = struct.Struct("<HBBB")  # MISSION_REQUEST(_INT): seq, target system, component, mission type


def use_mavlink2():  # noqa: ANN201 - the pymavlink module
    """Import pymavlink's mavutil in MAVLink 2 mode (process-wide, as pymavlink decides it)."""
    os.environ["MAVLINK20"] = "1"
    from pymavlink import mavutil

    if mavutil.mavlink.WIRE_PROTOCOL_VERSION != "2.0":  # imported before MAVLINK20 was set
        mavutil.set_dialect(mavutil.current_dialect)
    return mavutil


class PackedMessage(NamedTuple):
    """A message packed once for one link (:meth:`MavlinkLink.pack`).

    Attributes:
        body: The MAVLink 2 frame without its magic byte and CRC (the sequence number is
            written in at each send); ``None`` on a signing link, where each send is signed anew.
        crc_extra: The message type's CRC seed, as one byte.
        message: The pymavlink message to send as such on a signing link, else ``None``.
    """

    body: bytearray | None
    crc_extra: bytes
    message: object | None


class _Layout(NamedTuple):
    """How one message type is packed: its class, CRC seed, wire-ordered fields and id."""

    cls: type
    crc_extra: bytes
    ordered: Callable[[dict], tuple]
    msg_id: int


@functools.cache
def _layout(dialect: object, message: str) -> _Layout:
    cls = getattr(dialect, f"MAVLink_{message}_message")
    return _Layout(cls, bytes([cls.crc_extra]), operator.itemgetter(*cls.ordered_fieldnames), cls.id)


def _crc_function(dialect: object) -> Callable[[bytes], int]:
    """The MAVLink CRC (CRC-16/MCRF4XX) of some bytes: pymavlink's own, called directly when it is native."""
    native = getattr(dialect, "mcrf4xx", None)  # fastcrc's, when installed
    if native is not None:
        return lambda data: native(data, 0xFFFF)
    return lambda data: dialect.x25crc(data).crc


class LinkReader:
    """The single reader of one or more links: one ``select`` over all their sockets.

    A thread of its own reads, starting with the first link and stopping when closed;
    a caller that waits for answers can read in its place for a while (:meth:`lend`), so
    that answering and waiting happen on one thread with no hand-off between the two.
    Either way one thread at a time reads, and every message is parsed and dispatched on it.
    """

    def __init__(self, name: str = "mavlink reader") -> None:
        self._name = name
        self._links: tuple[MavlinkLink, ...] = ()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._turn = threading.Condition(threading.Lock())  # guards _lent and _reading
        self._lent = False
        self._reading = False
        self._built_for: tuple[MavlinkLink, ...] | None = None
        self._by_fd: dict[int, MavlinkLink] = {}
        self._fds: list[int] = []
        self._next_heartbeat_check_s = 0.0

    def add(self, link: MavlinkLink) -> None:
        """Start reading ``link`` (starting the thread on first use)."""
        with self._lock:
            self._links = (*self._links, link)
            if self._thread is None:
                self._thread = threading.Thread(target=self._loop, name=self._name, daemon=True)
                self._thread.start()

    def remove(self, link: MavlinkLink) -> None:
        """Stop reading ``link``."""
        with self._lock:
            self._links = tuple(other for other in self._links if other is not link)

    def close(self) -> None:
        """Stop the thread (links are closed by their owners)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)

    @contextlib.contextmanager
    def lend(self) -> Iterator[Callable[[float], None] | None]:
        """Read on the calling thread for a while: yields ``step(timeout_s)`` (``None``: lent elsewhere).

        ``step`` waits at most ``timeout_s`` (and at most the heartbeat poll period) for the
        links' sockets and dispatches what arrived, as the reader thread would; meanwhile the
        reader thread reads nothing (it waits from the next time its ``select`` returns). When
        another caller holds the reader (or the caller is the reader thread itself), ``None`` is
        yielded: that caller reads for everyone, and this one waits as it would for the reader
        thread.
        """
        with self._turn:
            on_reader = threading.current_thread() is self._thread  # a listener: never wait for ourselves
            lent = not (self._lent or on_reader or self._stop.is_set())
            if lent:
                self._lent = True
                while self._reading:  # the reader thread is dispatching: let it finish that round
                    self._turn.wait()
        try:
            yield self._step if lent else None
        finally:
            if lent:
                with self._turn:
                    self._lent = False
                    self._turn.notify_all()

    def _loop(self) -> None:
        while not self._stop.is_set():
            ready = self._select(_POLL_S)
            with self._turn:
                if self._lent:  # the borrower reads what woke us; wait until it is done
                    while self._lent and not self._stop.is_set():
                        self._turn.wait(_POLL_S)
                    continue
                self._reading = True
            try:
                self._read(ready)
            finally:
                with self._turn:
                    self._reading = False
                    self._turn.notify_all()

    def _step(self, timeout_s: float) -> None:
        """One round on a borrowing thread: wait up to ``timeout_s``, then read."""
        self._read(self._select(timeout_s))

    def _select(self, timeout_s: float) -> list[int]:
        """The ready sockets, after waiting at most ``timeout_s`` (and the heartbeat poll period).

        The socket list is rebuilt only when the links change, one stops (end of stream) or
        ``select`` fails (a link closed while we waited).
        """
        links = self._links
        if links is not self._built_for:
            self._by_fd = {fd: link for link in links if (fd := link._fd()) is not None}
            self._fds = list(self._by_fd)
            self._built_for = links
        if not self._fds:
            time.sleep(min(timeout_s, _POLL_S))
            return []
        try:
            ready, _, _ = select.select(self._fds, [], [], min(timeout_s, _POLL_S))
        except (OSError, ValueError):  # a link closed while we waited
            self._built_for = None
            return []
        return ready

    def _read(self, ready: list[int]) -> None:
        """Send due heartbeats; read one datagram (or TCP chunk) from each ready socket and dispatch it."""
        now_s = time.monotonic()
        if now_s >= self._next_heartbeat_check_s:
            self._next_heartbeat_check_s = now_s + _POLL_S
            for link in self._links:
                link._heartbeat_if_due(now_s)
                if link._reconnect_if_due(now_s):
                    self._built_for = None  # its socket changed
        for fd in ready:
            link = self._by_fd.get(fd)
            if link is not None and not link._read_available():
                self._built_for = None


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
        self._conn = mavutil.mavlink_connection(
            url, source_system=source_system, source_component=source_component
        )
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
        self._heartbeats: dict[int, object] = {}
        self._handlers: dict[int, Callable[[object], None]] = {}
        self._responders: dict[int, Callable[[int], None]] = {}
        m = mavutil.mavlink
        self._crc = _crc_function(m)
        self._request_crc_extra = {
            cls.id: bytes([cls.crc_extra])
            for cls in (m.MAVLink_mission_request_message, m.MAVLink_mission_request_int_message)
        }
        self._busy: dict[int, threading.Lock] = {}
        self._listeners: list[tuple[Callable[[object], None], frozenset[int] | None]] = []
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
    def mavlink(self):  # noqa: ANN201 - the pymavlink dialect module
        """The pymavlink dialect module (for constants)."""
        return self._mavlink

    def add_listener(self, callback: Callable[[object], None], types: Iterable[str] | None = None) -> None:
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

    def send(self, action: Callable[[object], None]) -> None:
        """Run ``action(mav)`` (e.g. ``lambda mav: mav.mission_count_send(...)``) under the send lock."""
        with self._send_lock:
            action(self._conn.mav)

    def pack(self, message: str, **fields: float | int) -> PackedMessage:
        """Pack a message with numeric fields only (e.g. ``pack("mission_item_int", seq=0, ...)``) once.

        The body is pymavlink's own packing (field order, trailing zeros cut as MAVLink 2 does),
        so :meth:`send_packed` puts on the wire what ``mav.<message>_send(**fields)`` would.
        """
        layout = _layout(self._mavlink, message)
        if self._signing:
            return PackedMessage(None, layout.crc_extra, layout.cls(**fields))
        payload = layout.cls.unpacker.pack(*layout.ordered(fields))
        payload = payload[: max(1, len(payload.rstrip(b"\0")))]
        mav, msg_id = self._conn.mav, layout.msg_id
        header = _V2_HEADER.pack(
            len(payload), 0, 0, 0, mav.srcSystem, mav.srcComponent, msg_id & 0xFFFF, msg_id >> 16
        )
        return PackedMessage(bytearray(header + payload), layout.crc_extra, None)

    def send_packed(self, packed: PackedMessage) -> None:
        """Send a :meth:`pack`-ed message with the link's next sequence number (under the send lock)."""
        with self._send_lock:
            mav = self._conn.mav
            body = packed.body
            if body is None:
                mav.send(packed.message)
                return
            body[_SEQ_INDEX] = mav.seq
            crc = self._crc(body + packed.crc_extra)
            frame = bytes((_V2_MAGIC,)) + body + crc.to_bytes(2, "little")
            self._conn.write(frame)
            mav.seq = (mav.seq + 1) % 256
            mav.total_packets_sent += 1
            mav.total_bytes_sent += len(frame)

    def wait_heartbeat(self, system_id: int, timeout_s: float) -> object:
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
        handler: Callable[[object], None],
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

    def _fd(self) -> int | None:
        return None if self._closed or self._eof else self._conn.fd

    def _heartbeat_if_due(self, now_s: float) -> None:
        if now_s - self._last_heartbeat_s < _HEARTBEAT_PERIOD_S or self._closed:
            return
        self._last_heartbeat_s = now_s
        try:
            self._send_heartbeat()
        except OSError as exc:
            log.debug("%s: heartbeat not sent: %s", self.url, exc)

    def _reconnect_if_due(self, now_s: float) -> bool:
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

    def _read_available(self) -> bool:
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
        if listened is None or len(data) < _V2_OVERHEAD or data[0] != _V2_MAGIC:
            return True
        if len(data) != _V2_OVERHEAD + data[1] + (_SIGNATURE_LEN if data[2] & _IFLAG_SIGNED else 0):
            return True  # several frames, or a broken one: the parser decides
        msg_id = data[7] | data[8] << 8 | data[9] << 16
        return msg_id in listened or (msg_id in self._own_ids and not answered)

    def _answer_request(self, data: bytes) -> bool:
        """Pass a mission item request to its vehicle's ``on_request`` straight from the raw frame.

        Only for one whole unsigned MAVLink 2 frame on an unsigned link whose CRC checks;
        True when it was passed on (the decoded message then skips the handler).
        """
        if not self._responders or self._signing or len(data) < _V2_OVERHEAD or data[0] != _V2_MAGIC:
            return False
        extra = self._request_crc_extra.get(data[7] | data[8] << 8 | data[9] << 16)
        respond = self._responders.get(data[5])
        if extra is None or respond is None or data[2] or len(data) != _V2_OVERHEAD + data[1]:
            return False
        if self._crc(data[1:-2] + extra) != int.from_bytes(data[-2:], "little"):
            return False
        payload = data[10:-2].ljust(_ITEM_REQUEST.size, b"\0")  # MAVLink 2 cuts trailing zeros
        seq, target_system, _, mission_type = _ITEM_REQUEST.unpack_from(payload)
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
        if data[0] == _V2_MAGIC and len(data) >= _V2_OVERHEAD and mav.buf_len() == 0:
            flags = data[2]
            size = _V2_OVERHEAD + data[1] + (_SIGNATURE_LEN if flags & _IFLAG_SIGNED else 0)
            if size == len(data) and not flags & ~_IFLAG_SIGNED:
                try:
                    return [mav.decode(bytearray(data))]
                except self._mavlink.MAVError as exc:
                    log.debug("%s: dropped a frame: %s", self.url, exc)
                    return []
        return mav.parse_buffer(data) or []

    def _dispatch(self, msg: object, answered: bool = False) -> None:
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
