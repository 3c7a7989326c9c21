"""ROS 2 that does not load is said in one line, exit 2, before any heavy work and with nothing written.

Without the ros2 extra the line names it; with another ROS 2 sourced in the shell (its libraries first on
the library path), the line names that ROS's variables.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from uav_swarm.cli import main

REPO = Path(__file__).resolve().parents[2]

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


def test_simulate_and_fly_refuse_before_the_planner_is_built(no_rclpy, tmp_path, monkeypatch, capsys):
    import uav_swarm.runs.fly
    import uav_swarm.runs.simulate

    built: list[str] = []
    # the network's load, the engines' timing
    monkeypatch.setattr(uav_swarm.runs.simulate, "make_planners", lambda kinds, *a, **k: built.extend(kinds))
    monkeypatch.setattr(uav_swarm.runs.fly, "make_planner", lambda kind, *a, **k: built.append(kind))
    assert main(["simulate", "--ros2", "--out", str(tmp_path / "sim"), "--quiet"]) == 2
    bridge = tmp_path / "bridge.toml"
    bridge.write_text('[[vehicles]]\nsystem_id = 1\nurl = "udpout:127.0.0.1:9"\n')
    assert main(["fly", "--ros2", "--bridge-config", str(bridge), "--out", str(tmp_path / "fly")]) == 2
    assert built == [] and capsys.readouterr().err.count(EXTRA) == 2


def _foreign_ros(root: Path) -> dict[str, str]:
    """The environment of a shell with another ROS 2 sourced: its std_srvs library first on the path.

    That library has the name of the wheels' own but not its symbols (it is another package's build).
    """
    lib = root / "opt" / "ros" / "jazzy" / "lib"
    lib.mkdir(parents=True)
    wheels = [Path(p) for p in os.environ.get("LD_LIBRARY_PATH", "").split(os.pathsep) if p]
    donor = next(p / "libstd_msgs__rosidl_generator_py.so" for p in wheels
                 if (p / "libstd_msgs__rosidl_generator_py.so").exists())
    shutil.copy(donor, lib / "libstd_srvs__rosidl_generator_py.so")
    return {**os.environ, "ROS_DISTRO": "jazzy", "AMENT_PREFIX_PATH": str(lib.parent),
            "LD_LIBRARY_PATH": os.pathsep.join([str(lib), *map(str, wheels)]),
            "_ROS_WHEELS_BOOTSTRAP_COMPLETE": "1",  # the wheels' start-up hook keeps this order
            "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)}


def test_another_ros_in_the_shell_is_named_in_one_line_and_nothing_is_written(tmp_path):
    env = _foreign_ros(tmp_path / "foreign")
    out = tmp_path / "out"
    run = subprocess.run([sys.executable, "-m", "uav_swarm", "simulate", "--ros2", "--out", str(out),
                          "--no-telemetry", "--quiet"], env=env, capture_output=True, text=True, timeout=600)
    lines = run.stderr.strip().splitlines()
    assert run.returncode == 2 and len(lines) == 1, run.stderr[-3000:]
    assert lines[0].startswith("uav-swarm simulate: ROS 2 does not load (Could not import "
                               "'rosidl_typesupport_c' for package 'std_srvs'): another ROS 2 is set in this "
                               "shell (ROS_DISTRO=jazzy, AMENT_PREFIX_PATH=")
    assert f"LD_LIBRARY_PATH={tmp_path / 'foreign' / 'opt' / 'ros' / 'jazzy' / 'lib'})" in lines[0]
    assert not out.exists()
