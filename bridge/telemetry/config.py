"""Zenoh session settings for telemetry: loopback-only by default.

Zenoh's own defaults scout by multicast and listen on every interface; ours never do. A session
opened from :class:`TelemetryConfig` listens and connects only on the endpoints listed (by default
``tcp/127.0.0.1:7447`` for the publishing side), with multicast scouting off unless switched on, and
every connect, listen and query wait bounded by ``timeout_s``. Before the session opens, each
``host:port`` it is to listen on is tried with a plain socket, so an endpoint held by another process
is reported by name ("tcp/127.0.0.1:7447 is in use") instead of as Zenoh's timeout; a run left at
the default endpoint can move to a free loopback port instead (:func:`listen_elsewhere_if_taken`), so
that two runs share a machine.

Examples:
    >>> config = TelemetryConfig(swarm="demo", listen=(), connect=("tcp/127.0.0.1:7447",))
    >>> zenoh_config(config).get_json("scouting/multicast/enabled")
    'false'
"""

from __future__ import annotations

import errno
import json
import os
import re
import socket
from dataclasses import dataclass
from typing import Literal

import zenoh

from bridge.telemetry.keys import check_swarm_name
from typed_config import Config, ConfigError, param

__all__ = [
    "DEFAULT_ENDPOINT",
    "LOCATOR_SCHEMES",
    "TelemetryConfig",
    "TelemetryConnectionError",
    "check_endpoint",
    "check_listen_endpoints",
    "listen_elsewhere_if_taken",
    "zenoh_config",
    "open_session",
]

DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"
"""Where the publishing side listens, and the other side connects, unless configured."""

LOCATOR_SCHEMES: tuple[str, ...] = (
    "tcp", "udp", "tls", "quic", "ws", "unixsock-stream", "unixpipe", "serial", "vsock")
"""Zenoh locator schemes accepted in endpoints (``<scheme>/<address>``)."""

_IP_SCHEMES = frozenset({"tcp", "udp", "tls", "quic", "ws"})
_SOCKET_TYPES = {"tcp": socket.SOCK_STREAM, "tls": socket.SOCK_STREAM, "ws": socket.SOCK_STREAM,
                 "udp": socket.SOCK_DGRAM, "quic": socket.SOCK_DGRAM}
_IN_USE_ERRNOS = frozenset({errno.EADDRINUSE, getattr(errno, "WSAEADDRINUSE", errno.EADDRINUSE)})
_HOST_PORT_RE = re.compile(r"(?P<host>\[[0-9A-Fa-f:.%a-zA-Z]+\]|[A-Za-z0-9_.-]+):(?P<port>\d{1,5})")


class TelemetryConnectionError(ConnectionError):
    """A Zenoh session could not be opened with the configured endpoints."""


def check_endpoint(endpoint: str, where: str) -> str:
    """Validate one Zenoh endpoint ``<scheme>/<address>[?config][#metadata]``.

    IP-based schemes (tcp, udp, tls, quic, ws) need ``host:port`` with a port in [0, 65535].

    Args:
        endpoint: The endpoint text, e.g. ``tcp/127.0.0.1:7447``.
        where: The config field, for the error message.

    Raises:
        ConfigError: The scheme is unknown or the address malformed.
    """
    scheme, sep, address = endpoint.partition("/")
    if not sep or scheme not in LOCATOR_SCHEMES:
        allowed = [s + "/" for s in LOCATOR_SCHEMES]
        raise ConfigError(f"{where} = {endpoint!r}: must start with one of {allowed}")
    address = re.split(r"[?#]", address, maxsplit=1)[0]
    if not address:
        raise ConfigError(f"{where} = {endpoint!r}: the address after {scheme}/ is empty")
    if scheme in _IP_SCHEMES:
        match = _HOST_PORT_RE.fullmatch(address)
        if not match or int(match["port"]) > 65535:
            raise ConfigError(
                f"{where} = {endpoint!r}: expected {scheme}/<host>:<port> with 0 <= port <= 65535")
    return endpoint


@dataclass(frozen=True)
class TelemetryConfig(Config):
    """How a telemetry publisher or subscriber joins Zenoh.

    The defaults are for the publishing side (the simulator or the MAVLink bridge): a peer listening
    on ``tcp/127.0.0.1:7447``. A watcher connects there instead (``listen=()``,
    ``connect=("tcp/127.0.0.1:7447",)``). Client mode connects to a Zenoh router in ``connect``.
    """

    swarm: str = param("default", doc="swarm name, one key chunk of A-Z a-z 0-9 _ -")
    mode: Literal["peer", "client"] = param("peer", doc="Zenoh session mode: peer, or client of a router")
    listen: tuple[str, ...] = param((DEFAULT_ENDPOINT,), doc="endpoints to listen on (peer mode only)")
    connect: tuple[str, ...] = param((), doc="endpoints to connect to, e.g. tcp/127.0.0.1:7447")
    multicast_scouting: bool = param(False, doc="discover peers by UDP multicast (sends to the network)")
    timeout_s: float = param(2.0, gt=0.0, le=60.0, doc="bound on connecting, listening and queries, seconds")

    def check(self) -> None:
        """Validate the swarm name and endpoints; the session must be able to reach someone."""
        try:
            check_swarm_name(self.swarm)
        except ValueError as exc:
            raise ConfigError(f"TelemetryConfig.swarm: {exc}") from None
        for name in ("listen", "connect"):
            for i, endpoint in enumerate(getattr(self, name)):
                check_endpoint(endpoint, f"TelemetryConfig.{name}[{i}]")
        if self.mode == "client" and self.listen:
            raise ConfigError(
                f"TelemetryConfig.listen = {list(self.listen)}: a client does not listen; use []")
        if self.mode == "client" and not self.connect and not self.multicast_scouting:
            raise ConfigError("TelemetryConfig.connect is empty: client mode needs a router endpoint")
        if not self.listen and not self.connect and not self.multicast_scouting:
            raise ConfigError("TelemetryConfig: listen and connect are both empty and multicast scouting is "
                              "off, so the session could reach nobody; give at least one endpoint")


def zenoh_config(config: TelemetryConfig) -> zenoh.Config:
    """The :class:`zenoh.Config` for ``config``: explicit endpoints only, bounded waits.

    Args:
        config: The telemetry settings.
    """
    timeout_ms = round(config.timeout_s * 1000)
    client = config.mode == "client"
    settings = {
        "mode": config.mode,
        "listen": {"endpoints": list(config.listen), "timeout_ms": timeout_ms},
        "connect": {
            "endpoints": list(config.connect),
            "timeout_ms": timeout_ms,
            "exit_on_failure": client,
            "retry": {"period_init_ms": 100, "period_max_ms": 1000, "period_increase_factor": 2.0},
        },
        "scouting": {"timeout": timeout_ms, "multicast": {"enabled": config.multicast_scouting}},
        "queries_default_timeout": timeout_ms,
    }
    return zenoh.Config.from_json5(json.dumps(settings))


def _probe_socket(family: int, kind: int) -> socket.socket:
    """A socket that binds as Zenoh's listener does (address reuse on POSIX, exclusive on Windows).

    Address reuse lets the bind succeed over connections of a previous run left in TIME_WAIT, which
    Zenoh ignores too, and still fails on a port another socket listens on.
    """
    sock = socket.socket(family, kind)
    if os.name == "nt":
        sock.setsockopt(socket.SOL_SOCKET, getattr(socket, "SO_EXCLUSIVEADDRUSE", -5), 1)
    else:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    return sock


def _probe_listen_endpoint(endpoint: str) -> None:
    """Bind (and for TCP listen on) the endpoint's ``host:port`` for a moment; raise if that fails."""
    scheme, _, address = endpoint.partition("/")
    kind = _SOCKET_TYPES.get(scheme)
    match = _HOST_PORT_RE.fullmatch(re.split(r"[?#]", address, maxsplit=1)[0])
    if kind is None or match is None or int(match["port"]) == 0:
        return  # not an IP endpoint, or a port the system picks
    host, port = match["host"].strip("[]"), int(match["port"])
    try:
        infos = socket.getaddrinfo(host, port, type=kind, flags=socket.AI_PASSIVE)
    except socket.gaierror as exc:
        raise TelemetryConnectionError(f"cannot listen on {endpoint}: unknown host ({exc})") from None
    family, _, _, _, sockaddr = infos[0]
    try:
        with _probe_socket(family, kind) as sock:
            sock.bind(sockaddr)
            if kind == socket.SOCK_STREAM:
                sock.listen(1)
    except OSError as exc:
        if exc.errno in _IN_USE_ERRNOS:
            raise TelemetryConnectionError(
                f"{endpoint} is in use (another socket listens there: a running simulation, bridge "
                "or Zenoh router?)") from None
        if exc.errno == errno.EADDRNOTAVAIL:
            raise TelemetryConnectionError(
                f"cannot listen on {endpoint}: {host} is not an address of this machine") from None
        if exc.errno == errno.EACCES:
            raise TelemetryConnectionError(
                f"cannot listen on {endpoint}: permission denied (ports < 1024 need privileges)") from None
        raise TelemetryConnectionError(f"cannot listen on {endpoint}: {exc.strerror or exc}") from None


def check_listen_endpoints(config: TelemetryConfig) -> None:
    """Check that this machine can listen on each IP endpoint of ``config.listen`` right now.

    Each ``host:port`` (port 0 and non-IP endpoints are skipped) is bound with a plain socket, which is
    closed again at once.

    Args:
        config: The telemetry settings.

    Raises:
        TelemetryConnectionError: An endpoint is in use (the message names it), its host is not an
            address of this machine, or binding failed otherwise (the message gives the cause).
    """
    for endpoint in config.listen:
        _probe_listen_endpoint(endpoint)


def listen_elsewhere_if_taken(config: TelemetryConfig) -> tuple[TelemetryConfig, str | None]:
    """``config``, or, when its only listen endpoint is the default one and that is in use, a free one.

    The free endpoint is a TCP port of 127.0.0.1; the line returned with it says so (None: unchanged).
    For a run whose endpoint nobody chose: one the user gave is opened as given (or refused).
    """
    if config.listen != (DEFAULT_ENDPOINT,):
        return config, None
    try:
        _probe_listen_endpoint(DEFAULT_ENDPOINT)
        return config, None
    except TelemetryConnectionError:
        pass
    with _probe_socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        endpoint = f"tcp/127.0.0.1:{sock.getsockname()[1]}"
    line = (f"{DEFAULT_ENDPOINT} is in use (another run?): telemetry listens on {endpoint} instead "
            f"(uav-swarm telemetry watch --connect {endpoint})")
    return config.replace(listen=(endpoint,)), line


def open_session(config: TelemetryConfig) -> zenoh.Session:
    """Open a Zenoh session for ``config``, its listen endpoints checked first.

    Args:
        config: The telemetry settings.

    Raises:
        TelemetryConnectionError: A listen endpoint cannot be bound (see :func:`check_listen_endpoints`),
            Zenoh refused the settings or (client mode) reached no router in time.
    """
    check_listen_endpoints(config)
    try:
        return zenoh.open(zenoh_config(config))
    except zenoh.ZError as exc:
        raise TelemetryConnectionError(
            f"cannot open a Zenoh {config.mode} session (listen={list(config.listen)}, "
            f"connect={list(config.connect)}): {exc}") from None
