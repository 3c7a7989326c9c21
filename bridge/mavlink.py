"""MAVLink connections shared by every client of the vehicles behind them.

pymavlink connections are not thread-safe, so each :class:`MavlinkLink` has exactly
one reader: a :class:`LinkReader` thread, which waits on the sockets of all its links
at once (one ``select``), receives every message and sends our ground-station
HEARTBEAT once a second; every send goes through the link's send lock. A fleet
shares one reader among its links (no thread per link competing for the GIL); a
link made alone gets its own. Received messages go to the state listeners and, for
the mission and command protocols, to the handler of the operation running with
that vehicle, which can answer at once on the reader thread. Each vehicle's recent
STATUSTEXT messages are kept (:meth:`MavlinkLink.status_texts`) so that an error can
show what the vehicle said.

Works over ``udpin:``, ``udpout:`` and ``tcp:`` connection strings. The process
speaks MAVLink 2 (pymavlink selects the protocol through the ``MAVLINK20``
environment variable, which :class:`MavlinkLink` sets before its first connection).
"""

from __future__ import annotations

import collections
import contextlib
import logging
import os
import queue
import select
import threading
import time
from collections.abc import Callable, Iterator

from bridge.errors import HeartbeatTimeoutError
from bridge.signing import SigningKey

__all__ = ["MavlinkLink", "LinkReader", "PROTOCOL_MESSAGES", "use_mavlink2"]

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
_MAX_READS = 64  # datagrams read from one link before looking at the others
_STATUS_TEXTS_KEPT = 32  # per vehicle


def use_mavlink2():  # noqa: ANN201 - the pymavlink module
    """Import pymavlink's mavutil in MAVLink 2 mode (process-wide, as pymavlink decides it)."""
    os.environ["MAVLINK20"] = "1"
    from pymavlink import mavutil

    if mavutil.mavlink.WIRE_PROTOCOL_VERSION != "2.0":  # imported before MAVLINK20 was set
        mavutil.set_dialect(mavutil.current_dialect)
    return mavutil


class LinkReader:
    """The single reader thread of one or more links: one ``select`` over all their sockets.

    Starts with its first link and stops when closed. Every message is parsed and
    dispatched on this thread.
    """

    def __init__(self, name: str = "mavlink reader") -> None:
        self._name = name
        self._links: tuple[MavlinkLink, ...] = ()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

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

    def _loop(self) -> None:
        next_heartbeat_check_s = 0.0
        while not self._stop.is_set():
            links = self._links
            now_s = time.monotonic()
            if now_s >= next_heartbeat_check_s:
                next_heartbeat_check_s = now_s + _POLL_S
                for link in links:
                    link._heartbeat_if_due(now_s)
            by_fd = {fd: link for link in links if (fd := link._fd()) is not None}
            if not by_fd:
                time.sleep(_POLL_S)
                continue
            try:
                ready, _, _ = select.select(list(by_fd), [], [], _POLL_S)
            except (OSError, ValueError):  # a link closed while we waited
                continue
            for fd in ready:
                by_fd[fd]._read_available()


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
        self._send_lock = threading.Lock()
        self._state_lock = threading.Condition()
        self._heartbeats: dict[int, object] = {}
        self._handlers: dict[int, Callable[[object], None]] = {}
        self._busy: dict[int, threading.Lock] = {}
        self._listeners: list[Callable[[object], None]] = []
        self._status_texts: dict[int, collections.deque[tuple[float, str]]] = {}
        self._recv_lock = threading.Lock()
        self._closed = False
        self._tcp = url.startswith("tcp:")
        self._eof = False
        self._last_heartbeat_s = 0.0
        self._own_reader = reader is None
        self._reader = LinkReader(f"mavlink {url}") if reader is None else reader
        self._reader.add(self)

    @property
    def mavlink(self):  # noqa: ANN201 - the pymavlink dialect module
        """The pymavlink dialect module (for constants)."""
        return self._mavlink

    def add_listener(self, callback: Callable[[object], None]) -> None:
        """Call ``callback(msg)`` for every received message (on the reader thread: keep it short)."""
        with self._state_lock:
            self._listeners = [*self._listeners, callback]  # copy on write: the reader iterates freely

    def send(self, action: Callable[[object], None]) -> None:
        """Run ``action(mav)`` (e.g. ``lambda mav: mav.mission_count_send(...)``) under the send lock."""
        with self._send_lock:
            action(self._conn.mav)

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
    def protocol_handler(self, system_id: int, handler: Callable[[object], None]) -> Iterator[None]:
        """Route one vehicle's protocol messages to ``handler`` during one operation.

        ``handler(msg)`` runs on the reader thread as each message arrives, so it can answer
        at once (keep it short). Operations with the same vehicle run one after the other;
        messages that arrive while none runs are dropped, so each operation starts clean.
        """
        with self._state_lock:
            busy = self._busy.setdefault(system_id, threading.Lock())
        with busy:
            with self._state_lock:
                self._handlers[system_id] = handler
            try:
                yield
            finally:
                with self._state_lock:
                    self._handlers.pop(system_id, None)

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

    def _read_available(self) -> None:
        """Receive and dispatch what the socket holds (reader thread only).

        ``recv`` + ``parse_buffer`` rather than ``recv_match``: the same transport and
        signing checks without mavutil's per-message bookkeeping, which we do not use.
        """
        for count in range(_MAX_READS):
            with self._recv_lock:
                if self._closed:
                    return
                try:
                    data = self._conn.recv(_RECV_BYTES)
                    messages = self._conn.mav.parse_buffer(data) if data else None
                except (OSError, ValueError, self._mavlink.MAVError) as exc:
                    log.debug("%s: receive error: %s", self.url, exc)
                    return
            if not data:
                if count == 0 and self._tcp:  # readable yet empty: the vehicle closed the connection
                    log.warning("%s: connection closed by the vehicle; no longer reading it", self.url)
                    self._eof = True
                return
            for msg in messages or ():
                self._dispatch(msg)

    def _dispatch(self, msg: object) -> None:
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
            and kind in PROTOCOL_MESSAGES
            and getattr(msg, "target_system", self.source_system) in (0, self.source_system)
        ):
            try:
                handler(msg)
            except Exception:
                log.exception("%s: protocol handler failed for vehicle %d", self.url, system_id)
        for callback in listeners:
            try:
                callback(msg)
            except Exception:
                log.exception("%s: message listener failed", self.url)
