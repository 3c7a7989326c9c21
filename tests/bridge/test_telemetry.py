"""Telemetry over real Zenoh sessions in separate processes on loopback (multicast scouting off).

Each test starts ``telemetry_peer.py`` in its own process, listening on a free ``tcp/127.0.0.1`` port;
this process subscribes by connecting to it. Every wait is bounded.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from ports import free_tcp_port

from bridge.geo import Home, enu_to_geodetic
from bridge.telemetry import SwarmSubscriber
from bridge.telemetry.config import TelemetryConfig
from bridge.telemetry.schema import Plan, Presence, Qos, UavState
from uav_swarm.cli import telemetry as telemetry_cli

PEER = Path(__file__).with_name("telemetry_peer.py")
SWARM = "test"


class Peer:
    """A telemetry_peer.py process whose stdout lines are read by a thread (so waits can be bounded)."""

    def __init__(self, *args: str) -> None:
        port = free_tcp_port()
        self.proc = subprocess.Popen(
            [sys.executable, str(PEER), *args, "--port", str(port), "--swarm", SWARM],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        self.config = TelemetryConfig(swarm=SWARM, listen=(), connect=(f"tcp/127.0.0.1:{port}",))
        self._lines: queue.Queue[str] = queue.Queue()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            self._lines.put(line.strip())

    def wait_line(self, expected: str, timeout_s: float) -> None:
        deadline = time.monotonic() + timeout_s
        while (left := deadline - time.monotonic()) > 0:
            try:
                if self._lines.get(timeout=left) == expected:
                    return
            except queue.Empty:
                break
        raise AssertionError(f"peer did not print {expected!r} in {timeout_s} s (exit {self.proc.poll()})")

    def kill(self) -> None:
        self.proc.kill()
        self.proc.wait(timeout=5)
        self.proc.stdin.close()


@pytest.fixture
def peer() -> Iterator:
    """Start a Peer with arguments once it is ready; every peer is killed at the end of the test."""
    peers: list[Peer] = []

    def start(*args: str) -> tuple[Peer, TelemetryConfig]:
        peers.append(Peer(*args))
        peers[-1].wait_line("ready", 10.0)
        return peers[-1], peers[-1].config

    yield start
    for started in peers:
        started.kill()


def test_subscriber_receives_every_message_of_a_10_uav_stream_in_order(peer):
    peer_proc, config = peer("stream", "--uavs", "10", "--rounds", "20", "--rate-hz", "200", "--home")
    with SwarmSubscriber(config) as sub:
        items = list(sub.messages(duration_s=10.0, count=10 + 20 * 12))
        assert sub.malformed == 0 and sub.dropped == 0
    states = [item for item in items if isinstance(item, UavState)]
    assert len(states) == 200
    for uav_id in range(10):
        assert [s.seq for s in states if s.uav_id == uav_id] == list(range(20))
    assert [p.seq for p in items if isinstance(p, Plan)] == list(range(20))
    assert [q.seq for q in items if isinstance(q, Qos)] == list(range(20))
    assert {p.uav_id for p in items if isinstance(p, Presence) and p.alive} == set(range(10))
    last = states[-1]
    assert last.source == "sim" and last.position_wgs84 is not None
    expected = enu_to_geodetic(Home(), *last.position_enu_m)
    assert (last.position_wgs84.lat_deg, last.position_wgs84.lon_deg) == pytest.approx(expected[:2], abs=1e-9)


def test_late_joiner_gets_the_latest_states_through_the_queryable(peer):
    # 11 UAVs flew; UAV 10 was retired (left the swarm) before we joined.
    peer_proc, config = peer("stream", "--uavs", "11", "--rounds", "5", "--no-wait", "--retire", "10")
    peer_proc.wait_line("done", 10.0)
    with SwarmSubscriber(config, presence=False) as sub:
        snapshot = sub.latest(timeout_s=5.0)
        alive = sub.alive(timeout_s=5.0)
    assert sorted(snapshot.states) == list(range(10))
    assert {state.seq for state in snapshot.states.values()} == {4}
    assert snapshot.plan is not None and snapshot.plan.seq == 4 and len(snapshot.plan.targets) == 11
    assert snapshot.qos is not None and snapshot.qos.seq == 4
    assert alive == set(range(10))


def test_liveliness_shows_the_loss_of_uavs_whose_publisher_is_killed(peer):
    peer_proc, config = peer("stream", "--uavs", "3", "--rounds", "1", "--no-wait")
    peer_proc.wait_line("done", 10.0)
    with SwarmSubscriber(config) as sub:
        appeared = [item for item in sub.messages(duration_s=5.0, count=3) if isinstance(item, Presence)]
        assert {(p.uav_id, p.alive) for p in appeared} == {(0, True), (1, True), (2, True)}
        os.kill(peer_proc.proc.pid, signal.SIGKILL)
        peer_proc.proc.wait(timeout=5)
        killed_s = time.time()
        lost = [item for item in sub.messages(duration_s=5.0, count=3) if isinstance(item, Presence)]
        assert {(p.uav_id, p.alive) for p in lost} == {(0, False), (1, False), (2, False)}
        assert max(p.received_s for p in lost) - killed_s < 5.0
        assert sub.alive(timeout_s=1.0) == set()


def test_malformed_samples_are_skipped_with_a_warning(peer, caplog):
    received: list = []
    peer_proc, config = peer("raw")
    with caplog.at_level(logging.WARNING, logger="bridge.telemetry"):
        with SwarmSubscriber(config, callback=received.append, presence=False) as sub:
            deadline = time.monotonic() + 10.0
            while (sub.malformed < 6 or not received) and time.monotonic() < deadline:
                time.sleep(0.01)
            malformed = sub.malformed
    assert malformed == 6
    assert [(s.uav_id, s.seq) for s in received] == [(0, 7)]
    warnings = [r for r in caplog.records if "malformed telemetry" in r.getMessage()]
    assert len(warnings) == 6


def _cli(*argv: str) -> int:
    parser = argparse.ArgumentParser()
    telemetry_cli.register(parser.add_subparsers())
    args = parser.parse_args(["telemetry", *argv])
    return args.func(args)


def test_cli_record_and_watch_are_bounded(peer, tmp_path, capsys):
    peer_proc, config = peer("stream", "--uavs", "4", "--rounds", "150", "--rate-hz", "50")
    endpoint = config.connect[0]
    out = tmp_path / "rec" / "telemetry.jsonl"
    assert (
        _cli(
            "record",
            "--out",
            str(out),
            "--swarm",
            SWARM,
            "--connect",
            endpoint,
            "--count",
            "40",
            "--duration-s",
            "10",
        )
        == 0
    )
    lines = [json.loads(line) for line in out.read_text().splitlines()]
    assert len(lines) == 40 and not list(out.parent.glob("*.part"))
    payloads = [line["payload"] for line in lines if "payload" in line]
    assert {p["kind"] for p in payloads} == {"state", "plan", "qos"}
    assert all(line["key"].startswith(f"uav_swarm/{SWARM}/") for line in lines)
    assert {line["uav_id"] for line in lines if line.get("presence") == "alive"} == {0, 1, 2, 3}

    started = time.monotonic()
    assert _cli("watch", "--swarm", SWARM, "--connect", endpoint, "--duration-s", "0.5") == 0
    assert time.monotonic() - started < 5.0
    table = capsys.readouterr().out
    assert f"swarm {SWARM}: 4 alive, 4 with state" in table
    assert "plan seq" in table and "qos seq" in table
