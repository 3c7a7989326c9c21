"""Without the ros2 extra, a command asking for ROS 2 says so in one line and exits 2, having done nothing."""

from __future__ import annotations

import sys

import pytest

from uav_swarm.cli import main

EXTRA = "pip install 'uav-swarm[ros2]'"


@pytest.fixture
def no_rclpy(monkeypatch):
    monkeypatch.setitem(sys.modules, "rclpy", None)  # ``import rclpy`` fails as when it is not installed


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def test_simulate_names_the_extra_and_writes_nothing(no_rclpy, tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["simulate", "--ros2", "--out", str(out), "--duration-s", "1", "--n-uavs", "2", "--planner",
                 "expert", "--no-expert", "--no-telemetry", "--no-gif", "--quiet"])
    assert code == 2 and _one_line(capsys) == f"uav-swarm simulate: ROS 2 is not installed: {EXTRA}"
    assert not out.exists()


def test_fly_names_the_extra_before_any_vehicle_is_contacted(no_rclpy, tmp_path, capsys):
    bridge = tmp_path / "bridge.toml"
    bridge.write_text('[[vehicles]]\nsystem_id = 1\nurl = "udpout:127.0.0.1:9"\n')
    out = tmp_path / "out"
    code = main(["fly", "--ros2", "--bridge-config", str(bridge), "--out", str(out), "--no-telemetry",
                 "--planner", "expert"])
    assert code == 2 and _one_line(capsys) == f"uav-swarm fly: ROS 2 is not installed: {EXTRA}"
    assert not out.exists()


def test_telemetry_ros2_names_the_extra(no_rclpy, capsys):
    code = main(["telemetry", "ros2", "--connect", "tcp/127.0.0.1:9", "--count", "1"])
    assert code == 2 and _one_line(capsys) == f"uav-swarm telemetry: ROS 2 is not installed: {EXTRA}"
