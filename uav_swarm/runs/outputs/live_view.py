"""``--live [HOST:]PORT``: where the live view listens, and what it logs of its clients.

The live view is the Foxglove SDK's WebSocket server, started by the recorder
(:mod:`uav_swarm.runs.outputs.recording`). This module holds what needs no SDK: the address, checked before
any work (a clear error naming ``live``), and the listener the server calls when a client subscribes
or leaves. The listener only logs, hands a new subscriber of a latched topic (the static scene) its
message again, and tells whoever waits for a first viewer; it never raises into the server.

Examples:
    >>> parse_live_view("8765")
    LiveView(host='127.0.0.1', port=8765, wait_for_client_s=0.0, speed=None, max_rate_hz=25.0)
    >>> parse_live_view("[::1]:9000", wait_for_client_s=30, speed=1).speed
    1.0
    >>> parse_live_view("0.0.0.0:99999")
    Traceback (most recent call last):
    ...
    typed_config.ConfigError: live = '0.0.0.0:99999': the port must be 0..65535 (0: any free port)
"""

from __future__ import annotations

import ipaddress
import logging
import re
import threading
from collections import defaultdict
from collections.abc import Callable, Collection
from dataclasses import dataclass
from typing import Any

from typed_config import ConfigError

__all__ = ["DEFAULT_HOST", "LiveView", "parse_live_view", "live_view_option", "LiveListener"]

logger = logging.getLogger(__name__)

DEFAULT_HOST = "127.0.0.1"
"""Where the live view listens when ``--live`` names only a port: this machine only."""

_HOSTNAME = re.compile(r"^(?=.{1,253}$)[A-Za-z0-9]([A-Za-z0-9-]{0,61}[A-Za-z0-9])?"
                       r"(\.[A-Za-z0-9]([A-Za-z0-9-]{0,61}[A-Za-z0-9])?)*$")


@dataclass(frozen=True)
class LiveView:
    """Where the live view's WebSocket server listens, and how long the run waits for a first viewer.

    Attributes:
        host: An IP address or a host name (``127.0.0.1``: this machine only).
        port: TCP port, 0 for any free port (the one taken is logged).
        wait_for_client_s: Before its first step, the run waits at most this long for a client to
            subscribe to the scene (0: it starts at once). Once it runs, it never waits on a client.
        speed: Run seconds per wall-clock second while streaming (``simulate``: 1 is the crowd's own pace,
            to watch); None: as fast as the run computes.
        max_rate_hz: Recorded steps streamed per wall-clock second at most; the others are skipped for
            the live view only (the file keeps every one). An unpaced ``simulate`` records hundreds of
            steps a second, more than a viewer draws. None: stream every step.
    """

    host: str
    port: int
    wait_for_client_s: float = 0.0
    speed: float | None = None
    max_rate_hz: float | None = 25.0

    @property
    def is_loopback(self) -> bool:
        """True when only this machine can connect."""
        if self.host == "localhost":
            return True
        try:
            return ipaddress.ip_address(self.host).is_loopback
        except ValueError:
            return False


def parse_live_view(text: str, wait_for_client_s: float = 0.0, speed: float | None = None) -> LiveView:
    """``PORT``, ``HOST:PORT`` or ``[IPv6]:PORT`` as a :class:`LiveView` (host default 127.0.0.1).

    Raises:
        ConfigError: Naming ``live`` and the text: no port, a port outside 0..65535, or a host that is
            neither an IP address nor a host name; naming ``live_wait_s`` when it is negative or not finite,
            ``live_speed`` when it is not a positive finite number.
    """
    wait_s = float(wait_for_client_s)
    if not 0.0 <= wait_s < float("inf"):
        raise ConfigError(f"live_wait_s = {wait_for_client_s}: give the seconds to wait for a viewer, >= 0")
    if speed is not None and not 0.0 < float(speed) < float("inf"):
        raise ConfigError(f"live_speed = {speed}: give run seconds per wall-clock second, > 0")
    value = text.strip()
    host, port_text = DEFAULT_HOST, value
    if ":" in value:
        host, _, port_text = value.rpartition(":")
        if host.startswith("[") and host.endswith("]"):
            host = host[1:-1]
        elif ":" in host:
            raise ConfigError(f"live = {text!r}: write an IPv6 host in brackets, e.g. [::1]:8765")
    if not re.fullmatch(r"[0-9]{1,5}", port_text):
        raise ConfigError(f"live = {text!r}: give PORT or HOST:PORT, e.g. 8765 or 127.0.0.1:8765")
    port = int(port_text)
    if port > 65535:
        raise ConfigError(f"live = {text!r}: the port must be 0..65535 (0: any free port)")
    if not _valid_host(host):
        raise ConfigError(f"live = {text!r}: host {host!r} is neither an IP address nor a host name")
    return LiveView(host=host, port=port, wait_for_client_s=wait_s,
                    speed=None if speed is None else float(speed))


_FLAGS = {"live": "--live", "live_wait_s": "--live-wait-s", "live_speed": "--speedup"}
"""The command line's names of :func:`parse_live_view`'s values."""


def live_view_option(live: str | None, wait_for_client_s: float | None = None,
                     speed: float | None = None) -> LiveView | None:
    """The ``--live``, ``--live-wait-s`` and ``--speedup`` options as a :class:`LiveView`, or None.

    Raises:
        ConfigError: As :func:`parse_live_view`, naming the flags; or ``--live-wait-s`` or ``--speedup``
            given without ``--live``.
    """
    if live is None:
        for name, value in (("live_wait_s", wait_for_client_s), ("live_speed", speed)):
            if value is not None:
                raise ConfigError(f"{_FLAGS[name]} {value}: it is for the live view, give --live too")
        return None
    try:
        return parse_live_view(live, 0.0 if wait_for_client_s is None else wait_for_client_s, speed)
    except ConfigError as exc:
        name, _, rest = str(exc).partition(" = ")
        raise ConfigError(f"{_FLAGS.get(name, name)} {rest}" if name in _FLAGS else str(exc)) from None


def _valid_host(host: str) -> bool:
    try:
        ipaddress.ip_address(host)
        return True
    except ValueError:
        return bool(_HOSTNAME.match(host))


class LiveListener:
    """The server's listener: logs subscriptions and departures; re-sends latched topics to a subscriber.

    Args:
        latched: Topics whose last message a new subscriber gets at once; the first subscription to one
            sets :attr:`viewer`.
        resend: Called with the topic when a client subscribes to a latched one (from the server's
            thread); an error it raises is logged, not raised.
    """

    def __init__(self, latched: Collection[str], resend: Callable[[str], None]) -> None:
        self._latched = frozenset(latched)
        self._resend = resend
        self._lock = threading.Lock()
        self._topics: defaultdict[int, set[str]] = defaultdict(set)
        self.viewer = threading.Event()
        """Set once a client has subscribed to a latched topic."""

    def on_subscribe(self, client: Any, channel: Any) -> None:
        """A client subscribed to a channel."""
        with self._lock:
            first = client.id not in self._topics
            self._topics[client.id].add(channel.topic)
        if first:
            logger.info("live client %d subscribed (first topic %s)", client.id, channel.topic)
        if channel.topic in self._latched:
            try:
                self._resend(channel.topic)
            except Exception:  # the server's thread must go on: a failed re-send is only logged
                logger.exception("live client %d: could not re-send %s", client.id, channel.topic)
            self.viewer.set()

    def on_unsubscribe(self, client: Any, channel: Any) -> None:
        """A client unsubscribed from a channel, or left (then once per channel it had)."""
        with self._lock:
            topics = self._topics.get(client.id, set())
            topics.discard(channel.topic)
            gone = not topics and self._topics.pop(client.id, None) is not None
        if gone:
            logger.info("live client %d left (disconnected, or unsubscribed from every topic)", client.id)

    @property
    def clients(self) -> int:
        """Clients subscribed to at least one topic now."""
        with self._lock:
            return len(self._topics)
