"""What a process sent, as strace saw it: every connect and send of it and all its threads.

:func:`strace_prefix` runs a command under ``strace -f``; :func:`destinations` lists the IP addresses it
connected or sent to; :func:`off_loopback` lists the calls that reached beyond this machine or reached a
name resolver, a DNS query whatever the resolver's address: port 53 (also 127.0.0.53, whose local
resolver forwards the query), the nscd socket, systemd-resolved's socket. A connect that failed (no nscd
running: ``= -1 ENOENT``) sent nothing; the C library then reads its files (``/etc/hosts``,
``/etc/passwd``: Fast DDS looks its user up) and asks DNS only for a name they do not hold.
"""

from __future__ import annotations

import ipaddress
import re
import shutil
from pathlib import Path

__all__ = ["strace_prefix", "destinations", "off_loopback"]

_CALL = re.compile(r"\b(connect|sendto|sendmsg|sendmmsg)\(")
_ADDRESS = re.compile(r'inet_addr\("([0-9.]+)"\)|inet_pton\(AF_INET6, "([^"]+)"')
_PORT = re.compile(r"sin6?_port=htons\((\d+)\)")
_UNIX_PATH = re.compile(r'sun_path="([^"]*)"')
_RESOLVER_SOCKETS = ("nscd", "systemd/resolve")  # glibc's name service cache, systemd-resolved's varlink


def strace_prefix(out: Path) -> list[str]:
    """Run a command under strace, logging every connect and send of it and its threads to ``out``."""
    return [shutil.which("strace") or "strace", "-f", "-qq", "-e", "trace=connect,sendto,sendmsg,sendmmsg",
            "-o", str(out)]


def destinations(trace: Path) -> tuple[set[str], int]:
    """The IPv4 / IPv6 addresses a process connected or sent to, and how many such calls strace saw."""
    found: set[str] = set()
    calls = 0
    for line in trace.read_text().splitlines():
        if not _CALL.search(line):
            continue
        addresses = {a or b for a, b in _ADDRESS.findall(line)}
        calls += bool(addresses)
        found |= addresses
    return found, calls


def off_loopback(trace: Path) -> list[str]:
    """The calls of ``trace`` that left the machine or asked a name resolver (each strace line, as is)."""
    found = []
    for line in trace.read_text().splitlines():
        if not _CALL.search(line):
            continue
        addresses = {a or b for a, b in _ADDRESS.findall(line)}
        remote = any(not ipaddress.ip_address(a).is_loopback for a in addresses)
        dns = "53" in _PORT.findall(line)
        resolver = " = -1 " not in line and any(k in path for path in _UNIX_PATH.findall(line)
                                                 for k in _RESOLVER_SOCKETS)
        if remote or dns or resolver:
            found.append(line)
    return found
