"""A local Ray run listens on 127.0.0.1 only, without dashboard or usage reporting; --address still joins."""

from __future__ import annotations

import ipaddress
import operator
import os
import socket
from pathlib import Path

import pytest

from learning import executors
from learning.executors import ray_session, run_ray

PROC = Path("/proc")


def _listening_sockets() -> dict[int, tuple[str, int]]:
    """Socket inode -> (address, port) of every listening TCP socket and bound UDP socket of the machine."""
    found = {}
    for table, family, listening in (("tcp", socket.AF_INET, "0A"), ("tcp6", socket.AF_INET6, "0A"),
                                     ("udp", socket.AF_INET, "07"), ("udp6", socket.AF_INET6, "07")):
        path = PROC / "net" / table
        if not path.exists():
            continue
        for line in path.read_text().splitlines()[1:]:
            fields = line.split()
            address, port = fields[1].split(":")
            if fields[3] != listening:
                continue
            raw = bytes.fromhex(address)  # /proc writes each 32-bit word in host (little-endian) order
            raw = b"".join(raw[i:i + 4][::-1] for i in range(0, len(raw), 4))
            found[int(fields[9])] = (socket.inet_ntop(family, raw), int(port, 16))
    return found


def _process_tree(root: int) -> list[int]:
    """``root`` and all its descendants."""
    children: dict[int, list[int]] = {}
    for entry in PROC.iterdir():
        if entry.name.isdigit():
            try:
                parent = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            children.setdefault(parent, []).append(int(entry.name))
    tree, todo = [], [root]
    while todo:
        pid = todo.pop()
        tree.append(pid)
        todo += children.get(pid, [])
    return tree


def _socket_inodes(pid: int) -> set[int]:
    inodes = set()
    try:
        for fd in (PROC / str(pid) / "fd").iterdir():
            try:
                target = os.readlink(fd)
            except OSError:
                continue
            if target.startswith("socket:["):
                inodes.add(int(target[8:-1]))
    except OSError:
        pass
    return inodes


def _command(pid: int) -> str:
    try:
        return (PROC / str(pid) / "cmdline").read_bytes().replace(b"\0", b" ").decode()[:100]
    except OSError:
        return "?"


def _environment(pid: int) -> dict[str, str]:
    try:
        pairs = (PROC / str(pid) / "environ").read_bytes().split(b"\0")
    except OSError:
        return {}
    return dict(p.decode(errors="replace").split("=", 1) for p in pairs if b"=" in p)


def _is_loopback(address: str) -> bool:
    ip = ipaddress.ip_address(address)
    mapped = getattr(ip, "ipv4_mapped", None)
    return (mapped or ip).is_loopback


@pytest.mark.skipif(not (PROC / "net" / "tcp").exists(), reason="lists sockets through Linux /proc")
def test_a_local_ray_run_listens_on_loopback_only_without_dashboard_or_usage_reporting():
    import ray
    if ray.is_initialized():
        pytest.skip("a Ray session is already running in this process")
    ours = _socket_inodes(os.getpid())
    env_before = {key: os.environ.get(key) for key in ("RAY_USAGE_STATS_ENABLED",
                                                       "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER")}
    jobs = [(i, 3 * i, 3 * i + 3) for i in range(4)]
    results = run_ray(operator.mul, jobs)  # a job function every Ray worker can import
    try:
        first = next(results)  # the local instance is up and has run a task
        sockets = _listening_sockets()
        opened = []
        for pid in _process_tree(os.getpid()):
            inodes = _socket_inodes(pid) - (ours if pid == os.getpid() else set())
            opened += [(pid, _command(pid), *sockets[i]) for i in inodes if i in sockets]
        ray_processes = [pid for pid in _process_tree(os.getpid())[1:] if "gcs_server" in _command(pid)]
        environments = [_environment(pid) for pid in ray_processes]
        done = dict([first, *results])
    finally:
        results.close()
    assert done == {job: job[1] * job[2] for job in jobs}
    assert len(opened) >= 3, opened  # at least the GCS, the raylet and the driver's worker listen
    exposed = [s for s in opened if not _is_loopback(s[2])]
    assert not exposed, "Ray sockets not on loopback:\n" + "\n".join(map(str, exposed))
    assert 8265 not in {s[3] for s in opened}  # no dashboard
    assert environments and all(e.get("RAY_USAGE_STATS_ENABLED") == "0" for e in environments)
    assert not ray.is_initialized()  # the session the run opened is closed
    assert {key: os.environ.get(key) for key in env_before} == env_before  # and the settings restored


def test_an_address_joins_that_cluster_as_given(monkeypatch):
    import ray
    if ray.is_initialized():
        pytest.skip("a Ray session is already running in this process")
    calls = []
    monkeypatch.setattr(ray, "init", lambda **kwargs: calls.append(kwargs))
    monkeypatch.setattr(ray, "shutdown", lambda: calls.append("shutdown"))
    monkeypatch.delenv("RAY_USAGE_STATS_ENABLED", raising=False)
    with ray_session("ray://head:10001", num_cpus=2):
        assert "RAY_USAGE_STATS_ENABLED" not in os.environ
    assert calls[0]["address"] == "ray://head:10001" and calls[0]["include_dashboard"] is False
    assert "_node_ip_address" not in calls[0] and "num_cpus" not in calls[0]  # local options stay local
    assert calls[1] == "shutdown"


def test_without_an_address_a_private_loopback_instance_is_asked_for(monkeypatch):
    import ray
    if ray.is_initialized():
        pytest.skip("a Ray session is already running in this process")
    from ray._private import ray_constants

    calls = []

    def init(**kwargs):
        calls.append({**kwargs, "cluster": ray_constants.ENABLE_RAY_CLUSTER,
                      "stats": os.environ.get("RAY_USAGE_STATS_ENABLED")})

    monkeypatch.setattr(ray, "init", init)
    monkeypatch.setattr(ray, "shutdown", lambda: None)
    monkeypatch.setenv("RAY_ADDRESS", "head:6379")  # ignored: without --address the run is local
    cluster_before = ray_constants.ENABLE_RAY_CLUSTER
    with ray_session(num_cpus=1):
        pass
    (call,) = calls
    assert call["address"] == "local" and call["_node_ip_address"] == executors.LOOPBACK
    assert call["include_dashboard"] is False and call["dashboard_host"] == executors.LOOPBACK
    assert call["num_cpus"] == 1 and call["cluster"] is False and call["stats"] == "0"
    assert ray_constants.ENABLE_RAY_CLUSTER == cluster_before
