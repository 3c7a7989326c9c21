"""Nothing leaves the machine unless asked: the main jobs under strace send to loopback only, and ask no DNS.

Each command runs in its own process under ``strace -f`` (every thread, every connect and send), with
no telemetry setting of its own in the environment: what keeps the libraries quiet is the package's
default (:data:`uav_swarm.TELEMETRY_OFF`). ``simulate`` runs with ONNX Runtime for more than a minute of
wall time (its telemetry first resolves its collector about 10 s after a session starts).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import onnxruntime  # noqa: F401  (the inference extra: the test command installs it; missing, the test fails)
from ports import free_tcp_port
from traffic import destinations, off_loopback, strace_prefix

import uav_swarm
from bridge.telemetry import SwarmSubscriber
from bridge.telemetry.config import TelemetryConfig

REPO = Path(__file__).resolve().parents[1]
CHECKPOINTS = REPO / "uav_swarm" / "checkpoints"
BUILDING = REPO / "tests" / "data" / "buildings" / "alta_east_outer.geojson"
PACED_S = 60.0  # simulate's flown run, paced: 30 s of crowd time at half speed


def _quiet_env() -> dict[str, str]:
    """This process's environment without any telemetry setting, the worktree first on the path."""
    env = {k: v for k, v in os.environ.items() if k not in uav_swarm.TELEMETRY_OFF}
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return env


def _traced(trace: Path, *argv: str, cwd: Path) -> subprocess.CompletedProcess:
    command = strace_prefix(trace) + [sys.executable, "-m", "uav_swarm", *argv]
    return subprocess.run(command, env=_quiet_env(), cwd=cwd, capture_output=True, text=True, timeout=900)


def test_importing_the_package_turns_telemetry_off_and_keeps_the_users_choice():
    probe = ("import json, os, uav_swarm; "
             "print(json.dumps({k: os.environ.get(k) for k in uav_swarm.TELEMETRY_OFF}))")
    env = _quiet_env()
    quiet = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, check=True)
    assert json.loads(quiet.stdout) == {"ORT_DISABLE_TELEMETRY": "1", "RAY_USAGE_STATS_ENABLED": "0"}
    env["ORT_DISABLE_TELEMETRY"] = "0"
    chosen = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True,
                            check=True)
    assert json.loads(chosen.stdout)["ORT_DISABLE_TELEMETRY"] == "0"


def test_the_trace_reading_flags_remote_hosts_and_every_dns_query(tmp_path):
    trace = tmp_path / "trace"
    lines = [
        '9 connect(8, {sa_family=AF_UNIX, sun_path="/var/run/nscd/socket"}, 110) = 0',
        '9 connect(8, {sa_family=AF_UNIX, sun_path="/var/run/nscd/socket"}, 110) = -1 ENOENT (No such file)',
        '9 connect(8, {sa_family=AF_INET, sin_port=htons(53), sin_addr=inet_addr("127.0.0.53")}, 16) = 0',
        '9 sendto(8, "\\274\\0\\1\\0", 50, MSG_NOSIGNAL, NULL, 0) = 50',  # on the resolver's socket above
        '9 connect(9, {sa_family=AF_INET6, sin6_port=htons(443), '
        'inet_pton(AF_INET6, "2603:1030::1", &sin6_addr)}, 28) = 0',
        '9 sendmsg(7, {msg_name={sa_family=AF_INET, sin_port=htons(7400), '
        'sin_addr=inet_addr("239.255.0.1")}}, 0) = 60',
        '9 connect(5, {sa_family=AF_UNIX, sun_path="/run/systemd/resolve/io.systemd.Resolve"}, 110) = 0',
        '9 connect(6, {sa_family=AF_INET, sin_port=htons(7447), sin_addr=inet_addr("127.0.0.1")}, 16) = 0',
        '9 sendto(4, "x", 1, 0, {sa_family=AF_INET6, sin6_port=htons(9), '
        'inet_pton(AF_INET6, "::1", &sin6_addr)}, 28) = 1',
        '9 connect(3, {sa_family=AF_UNIX, sun_path="/tmp/zenoh.sock"}, 110) = 0',
    ]
    trace.write_text("\n".join(lines) + "\n")
    assert off_loopback(trace) == [lines[0], lines[2], lines[4], lines[5], lines[6]]


def test_simulate_with_onnxruntime_sends_nothing_off_loopback_in_a_minute(tmp_path):
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    config = tmp_path / "sim.toml"
    config.write_text(f'duration_s = 30.0\n[planning]\nengine = "onnxruntime"\n'
                      f'[telemetry]\nswarm = "quiet"\nlisten = []\nconnect = ["{endpoint}"]\n')
    trace, out = tmp_path / "simulate.strace", tmp_path / "out"
    received: list = []
    watch = TelemetryConfig(swarm="quiet", listen=(endpoint,), connect=())  # the run connects to it
    start_s = time.monotonic()
    with SwarmSubscriber(watch, callback=received.append):  # the run's own traffic, which strace must see
        run = _traced(trace, "simulate", "--config", str(config), "--out", str(out), "--no-gif", "--record",
                      str(out / "run.mcap"), "--live", "127.0.0.1:0", "--speedup", "0.5", "--quiet",
                      cwd=tmp_path)
    elapsed_s = time.monotonic() - start_s
    assert run.returncode == 0, run.stderr[-3000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["inference_engine"] == "onnxruntime" and set(summary["planners"]) == {"learned", "expert"}
    assert elapsed_s >= PACED_S  # the pace guarantees it: ONNX Runtime's session lived past its 10 s delay
    addresses, calls = destinations(trace)
    assert received and calls > 0 and addresses <= {"127.0.0.1", "::1"}  # strace saw the telemetry go out
    assert off_loopback(trace) == []


def test_place_sends_nothing_off_loopback(tmp_path):
    trace = tmp_path / "place.strace"
    run = _traced(trace, "place", "--task", "fp", "--building", str(BUILDING), "--out", str(tmp_path / "out"),
                  "--quiet", cwd=tmp_path)
    assert run.returncode == 0, run.stderr[-3000:]
    assert (tmp_path / "out" / "placement.json").exists()
    assert off_loopback(trace) == []


def test_evaluate_sends_nothing_off_loopback(tmp_path):
    trace = tmp_path / "evaluate.strace"
    run = _traced(trace, "evaluate", "--task", "agp", "--checkpoint", str(CHECKPOINTS / "agp.pt"), "--n", "2",
                  "--seed", "41", "--out", str(tmp_path / "out"), "--quiet", cwd=tmp_path)
    assert run.returncode == 0, run.stderr[-3000:]
    assert any((tmp_path / "out").iterdir())
    assert off_loopback(trace) == []
