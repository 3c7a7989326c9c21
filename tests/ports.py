"""Free loopback ports for tests, chosen below the kernel's ephemeral range.

A test finds a free port, releases it and gives it to the code under test, which binds it later. A
port found by binding port 0 lies in the ephemeral range (Linux: ``ip_local_port_range``, 32768-60999
by default), where the kernel also picks the port of every socket bound to port 0 or sending
unbound: of the sockets a test opens meanwhile (relays, simulated vehicles, Zenoh connections, other
processes on a busy machine), one took such a port in about 1 % of the runs of the ten-vehicle
lossy-relay test, and the ground station then could not bind it. Ports below the ephemeral range
are never picked by the kernel; they are scanned from an offset that differs between processes, each
checked free by binding it.
"""

from __future__ import annotations

import itertools
import os
import socket
from collections.abc import Iterator
from pathlib import Path

__all__ = ["free_tcp_port", "free_udp_port"]

HOST = "127.0.0.1"
_LOWEST = 20000  # below: ports services commonly use
_DEFAULT_EPHEMERAL_LOW = 32768  # Linux's default; macOS and Windows start higher


def _ephemeral_low() -> int:
    try:
        return int(Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return _DEFAULT_EPHEMERAL_LOW


def _candidates() -> Iterator[int]:
    """Ports in ``[_LOWEST, ephemeral low)`` from an offset of this process's id, round and round."""
    span = _ephemeral_low() - _LOWEST
    if span < 1000:  # an unusual range, no room below it: the kernel's choice
        return itertools.repeat(0)
    start = (os.getpid() * 7919) % span
    return (_LOWEST + (start + i) % span for i in itertools.count())


_CANDIDATES = _candidates()


def _free_port(kind: socket.SocketKind) -> int:
    for _ in range(2000):
        with socket.socket(socket.AF_INET, kind) as sock:
            try:
                sock.bind((HOST, next(_CANDIDATES)))
            except OSError:  # in use: the next one
                continue
            return sock.getsockname()[1]
    raise RuntimeError(f"no free {kind.name} port on {HOST} below the ephemeral range after 2000 tries")


def free_udp_port() -> int:
    """A UDP port on 127.0.0.1 that no socket holds now and the kernel never gives to an unbound one."""
    return _free_port(socket.SOCK_DGRAM)


def free_tcp_port() -> int:
    """A TCP port on 127.0.0.1 that no socket holds now and the kernel never gives to a connection."""
    return _free_port(socket.SOCK_STREAM)
