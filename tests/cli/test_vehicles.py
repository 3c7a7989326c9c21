"""``uav-swarm vehicles`` and ``fly --simulated``: a simulated fleet a user starts, flown by ``fly``."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bridge.config import BridgeConfig
from bridge.link.mavlink import MavlinkLink
from typed_config import load_toml
from uav_swarm.cli import main

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize(("argv", "message"), [
    (["--autopilot", "px4", "--param", "WPNAV_SPEED=500"], "WPNAV_SPEED is not among the px4 parameters"),
    (["--autopilot", "ardupilot", "--param", "WPNAV_SPEED=fast"], "give NAME=VALUE with a number"),
    (["--autopilot", "ardupilot", "--n", "11"], "argument --n: 11 is out of range"),
    (["--autopilot", "ardupilot", "--command-loss", "1"], "argument --command-loss: 1 is out of range"),
    (["--autopilot", "ardupilot", "--bridge-config", "{far}"], "endpoints on 127.0.0.1"),
    (["--autopilot", "ardupilot", "--bridge-config", "{far}", "--n", "3"], "--n 3: "),
], ids=["foreign-param", "bad-value", "too-many", "all-lost", "off-loopback", "more-than-configured"])
def test_a_fleet_that_cannot_start_is_refused_in_one_line_nothing_written(tmp_path, capsys, argv, message):
    far = tmp_path / "far.toml"
    far.write_text('[[vehicles]]\nsystem_id = 1\nurl = "udpin:192.168.1.20:14550"\n')
    argv = [a.replace("{far}", str(far)) for a in argv]
    assert main(["vehicles", *argv, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert message in err[-1]
    assert not (tmp_path / "out").exists()


def test_vehicles_serve_their_bridge_config_until_ctrl_c(tmp_path):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
    argv = [sys.executable, "-m", "uav_swarm", "vehicles", "--autopilot", "ardupilot", "--n", "2",
            "--out", str(tmp_path / "fleet")]
    process = subprocess.Popen(argv, env=env, cwd=str(tmp_path), stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    config = tmp_path / "fleet" / "bridge.toml"
    heard: set[int] = set()
    try:
        deadline = time.monotonic() + 120.0
        while time.monotonic() < deadline and not config.exists() and process.poll() is None:
            time.sleep(0.1)
        bridge = load_toml(BridgeConfig, config)
        links = [MavlinkLink(v.url) for v in bridge.vehicles]
        for link in links:
            link.add_listener(lambda msg: heard.add(msg.get_srcSystem()), {"HEARTBEAT"})
        while time.monotonic() < deadline and heard != {1, 2}:
            time.sleep(0.1)
        for link in links:
            link.close()
    finally:
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=60)
    assert heard == {1, 2}
    assert process.returncode == 0, err
    assert f"fly them: uav-swarm fly --bridge-config {config}" in out and "vehicles stopped" in out
    assert [v.url.startswith("udpin:127.0.0.1:") for v in bridge.vehicles] == [True, True]


@pytest.mark.parametrize("autopilot", ["px4", "ardupilot"])
def test_fly_simulated_launches_its_own_fleet_flies_it_home_and_exits_0(tmp_path, capsys, caplog, autopilot):
    out = tmp_path / "out"
    argv = ["fly", "--simulated", autopilot, "--n-uavs", "2", "--duration-s", "10", "--speedup", "2",
            "--no-telemetry", "--out", str(out)]
    assert main(argv) == 0
    summary = json.loads((out / "summary.json").read_text())
    # the fleet's bridge config, made for this flight, is kept beside the summary that names it
    assert summary["config"]["bridge_config"] == "bridge.toml" and "bridge.toml" in summary["files"]
    assert len(load_toml(BridgeConfig, out / "bridge.toml").vehicles) == 2
    loop_end_s = max(float(row.split(",")[0]) for row in (out / "track.csv").read_text().splitlines()[1:])
    returns = [e["time_s"] for e in summary["events"] if e["event"] == "rtl"]
    assert len(returns) == 2 and min(returns) > loop_end_s  # flown home after the loop, on its clock
    fences = [r.getMessage() for r in caplog.records if "own geofence is off" in r.getMessage()]
    assert len(fences) <= 1 and all(f.startswith("vehicles 1, 2: their own") for f in fences)
    assert [v["status"] for v in summary["vehicles"]] == ["ended", "ended"]
    assert summary["separation"]["closest_m"] >= summary["separation"]["min_separation_m"]
    assert any(e["event"] == "live" for e in summary["events"])
    assert "closest pair" in capsys.readouterr().out


def test_fly_against_vehicles_never_heard_says_not_found_and_writes_nothing(tmp_path, capsys):
    from bridge.simulated.fleet import fleet_bridge_config

    config = tmp_path / "bridge.toml"
    config.write_text(fleet_bridge_config(2))  # nothing serves these ports
    out = tmp_path / "out"
    argv = ["fly", "--bridge-config", str(config), "--wait-ready-s", "1", "--no-telemetry", "--out", str(out)]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert "no vehicle could be launched (vehicles 1, 2: not found)" in err and "lost" not in err
    assert not out.exists()


def test_fly_with_no_vehicle_running_names_each_one_then_sums_up_and_points_at_simulated(
        tmp_path, capfd, caplog):
    """TCP ports nobody listens on: each vehicle named with the reason once, one summary, no pymavlink
    prints, no "flying without it", and the error points at --simulated."""
    from ports import free_tcp_port

    config = tmp_path / "bridge.toml"
    config.write_text("".join(f'[[vehicles]]\nsystem_id = {sid}\nurl = "tcp:127.0.0.1:{free_tcp_port()}"\n'
                              for sid in (1, 2)))
    out = tmp_path / "out"
    argv = ["fly", "--bridge-config", str(config), "--wait-ready-s", "5", "--no-telemetry", "--out", str(out)]
    assert main(argv) == 1
    printed, err = capfd.readouterr()
    warnings = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    named = [w for w in warnings if "cannot connect to tcp:127.0.0.1:" in w]
    assert [w.split(":")[0] for w in named] == ["vehicle 1", "vehicle 2"]
    assert all(w.endswith("Connection refused: is it running?") for w in named)
    summary = r"2 of 2 vehicles not heard after 3 s \(1, 2\): waiting up to [0-2] s more for them"
    assert [w for w in warnings if re.fullmatch(summary, w)] == [warnings[warnings.index(named[-1]) + 1]]
    assert not any("flying without it" in w for w in warnings)
    assert "sleeping" not in printed + err
    last = err.strip().splitlines()[-1]
    assert "--simulated ardupilot" in last
    assert f"start them first (SITL or real autopilots, or simulated ones in another terminal: uav-swarm " \
           f"vehicles --bridge-config {config})" in last  # what to start, named
    assert last.startswith("uav-swarm fly: no vehicle could be launched")  # no exception class first
    assert not out.exists()


def test_fly_with_its_live_view_port_taken_sends_nothing_to_a_vehicle(tmp_path, capsys):
    """The live view's port is checked before any link opens: exit 2, not one datagram to the vehicle."""
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as vehicle, \
            socket.socket(socket.AF_INET, socket.SOCK_STREAM) as taken:
        vehicle.bind(("127.0.0.1", 0))
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        config = tmp_path / "bridge.toml"
        vehicle_port, live_port = vehicle.getsockname()[1], taken.getsockname()[1]
        config.write_text(f'[[vehicles]]\nsystem_id = 1\nurl = "udpout:127.0.0.1:{vehicle_port}"\n')
        out = tmp_path / "out"
        argv = ["fly", "--bridge-config", str(config), "--live", str(live_port), "--no-telemetry",
                "--out", str(out)]
        assert main(argv) == 2
        vehicle.settimeout(1.5)  # a link would have sent its first heartbeat within a second
        with pytest.raises(TimeoutError):
            vehicle.recv(1024)
    assert "the live view cannot listen there" in capsys.readouterr().err.strip().splitlines()[-1]
    assert not out.exists()


@pytest.mark.parametrize("config", [None, "n_uavs = 2\n"], ids=["no-arguments", "config-without-vehicles"])
def test_fly_naming_no_vehicles_is_refused_in_one_line_naming_what_to_start(config, tmp_path, monkeypatch,
                                                                            capsys):
    """A usage error: no line about waiting first, one line that names --simulated and uav-swarm vehicles."""
    monkeypatch.chdir(tmp_path)
    argv = ["fly"]
    if config is not None:
        (tmp_path / "fly.toml").write_text(config)
        argv += ["--config", "fly.toml"]
    assert main(argv) == 2
    printed = capsys.readouterr()
    assert printed.out == ""  # no "loading the planner ... waiting up to" line
    (line,) = printed.err.strip().splitlines()
    assert line.startswith("uav-swarm fly: no vehicles to fly"), line
    assert "--simulated ardupilot|px4" in line and "uav-swarm vehicles --autopilot ardupilot" in line, line
    assert "out/vehicles/bridge.toml" in line and ("fly.toml sets no bridge_config" in line) == bool(config)
    assert sorted(p.name for p in tmp_path.iterdir()) == (["fly.toml"] if config else [])
