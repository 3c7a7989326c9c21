"""The one reader of a set of MAVLink links: one ``select`` over all their sockets.

pymavlink connections are not thread-safe, so each :class:`~bridge.link.mavlink.MavlinkLink` has
exactly one reader. A :class:`LinkReader`'s thread waits on the sockets of all its links at once,
receives every datagram (or TCP chunk) and has the link dispatch it, and sends each link's
ground-station HEARTBEAT once a second; a caller waiting for answers can borrow it to read on its
own thread meanwhile (:meth:`LinkReader.lend`), so that answering and waiting need no hand-off
between threads. A fleet shares one reader among its links (no thread per link competing for the
GIL); a link made alone gets its own.
"""

from __future__ import annotations

import contextlib
import select
import threading
import time
from collections.abc import Callable, Iterator
from typing import Protocol

__all__ = ["LinkReader", "POLL_S", "ReadableLink"]

POLL_S = 0.02
"""Longest wait of one ``select``: how often heartbeats and reconnections are checked."""


class ReadableLink(Protocol):
    """What the reader needs of a link (:class:`bridge.link.mavlink.MavlinkLink` registers itself as one)."""

    def reader_fd(self) -> int | None:
        """The socket to wait on; ``None`` while closed or disconnected."""

    def heartbeat_if_due(self, now_s: float) -> None:
        """Send the ground station's HEARTBEAT when one is due."""

    def reconnect_if_due(self, now_s: float) -> bool:
        """Try to reopen a closed connection when due; True once it is open again."""

    def read_available(self) -> bool:
        """Receive and dispatch what is waiting; False once the stream ended."""


class LinkReader:
    """The single reader of one or more links: one ``select`` over all their sockets.

    A thread of its own reads, starting with the first link and stopping when closed;
    a caller that waits for answers can read in its place for a while (:meth:`lend`), so
    that answering and waiting happen on one thread with no hand-off between the two.
    Either way one thread at a time reads, and every message is parsed and dispatched on it.
    """

    def __init__(self, name: str = "mavlink reader") -> None:
        self._name = name
        self._links: tuple[ReadableLink, ...] = ()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._turn = threading.Condition(threading.Lock())  # guards _lent and _reading
        self._lent = False
        self._reading = False
        self._built_for: tuple[ReadableLink, ...] | None = None
        self._by_fd: dict[int, ReadableLink] = {}
        self._fds: list[int] = []
        self._next_heartbeat_check_s = 0.0

    def add(self, link: ReadableLink) -> None:
        """Start reading ``link`` (starting the thread on first use)."""
        with self._lock:
            self._links = (*self._links, link)
            if self._thread is None:
                self._thread = threading.Thread(target=self._loop, name=self._name, daemon=True)
                self._thread.start()

    def remove(self, link: ReadableLink) -> None:
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
            ready = self._select(POLL_S)
            with self._turn:
                if self._lent:  # the borrower reads what woke us; wait until it is done
                    while self._lent and not self._stop.is_set():
                        self._turn.wait(POLL_S)
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
            self._by_fd = {fd: link for link in links if (fd := link.reader_fd()) is not None}
            self._fds = list(self._by_fd)
            self._built_for = links
        if not self._fds:
            time.sleep(min(timeout_s, POLL_S))
            return []
        try:
            ready, _, _ = select.select(self._fds, [], [], min(timeout_s, POLL_S))
        except (OSError, ValueError):  # a link closed while we waited
            self._built_for = None
            return []
        return ready

    def _read(self, ready: list[int]) -> None:
        """Send due heartbeats; read one datagram (or TCP chunk) from each ready socket and dispatch it."""
        now_s = time.monotonic()
        if now_s >= self._next_heartbeat_check_s:
            self._next_heartbeat_check_s = now_s + POLL_S
            for link in self._links:
                link.heartbeat_if_due(now_s)
                if link.reconnect_if_due(now_s):
                    self._built_for = None  # its socket changed
        for fd in ready:
            readable = self._by_fd.get(fd)
            if readable is not None and not readable.read_available():
                self._built_for = None
