import json
import time

import pytest
from lossy_relay import free_udp_port
from pymavlink.dialects.v20 import common as mavlink

from bridge.missions.files import load_plan, load_wpl
from bridge.simulated.peer import SimVehicle, endpoint_pair
from uav_swarm.cli import main


def _config(tmp_path, ports):
    lines = ["[home]", "lat_deg = 47.3977418", "lon_deg = 8.5455938", "alt_m = 488.0", ""]
    for sid, port in ports.items():
        lines += ["[[vehicles]]", f"system_id = {sid}", f'url = "udpin:127.0.0.1:{port}"', ""]
    path = tmp_path / "bridge.toml"
    path.write_text("\n".join(lines))
    return path


def test_export_writes_one_file_per_vehicle(tmp_path, capsys):
    config = _config(tmp_path, {1: 1, 2: 2})
    plans = tmp_path / "plans.json"
    plans.write_text(json.dumps({"1": [[10, 20]], "2": [[0, 0], [-30, 40, 50]]}))
    out = tmp_path / "missions"
    assert (
        main(
            [
                "mission",
                "export",
                "--config",
                str(config),
                "--plans",
                str(plans),
                "--out",
                str(out),
                "--autopilot",
                "ardupilot",
            ]
        )
        == 0
    )
    assert len(load_plan(out / "vehicle_1.plan").items) == 4  # home, takeoff, waypoint, loiter
    assert load_plan(out / "vehicle_2.plan").autopilot == mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
    assert (
        main(
            [
                "mission",
                "export",
                "--config",
                str(config),
                "--target",
                "1:5,5",
                "--out",
                str(out),
                "--format",
                "waypoints",
            ]
        )
        == 0
    )
    assert [i.command for i in load_wpl(out / "vehicle_1.waypoints")] == [
        mavlink.MAV_CMD_NAV_TAKEOFF,
        mavlink.MAV_CMD_NAV_WAYPOINT,
        mavlink.MAV_CMD_NAV_LOITER_UNLIM,
    ]
    assert "vehicle_1.waypoints" in capsys.readouterr().out


def test_export_refuses_points_outside_the_geofence_naming_the_vehicle(tmp_path, capsys):
    config = _config(tmp_path, {1: 1, 2: 2})
    targets = ["--target", "1:10,0", "--target", "2:9000,0"]
    assert main(["mission", "export", "--config", str(config), *targets, "--out", str(tmp_path / "o")]) == 2
    assert "vehicle 2: target: x_m = 9000.00 is outside the geofence" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_upload_download_clear_against_vehicles(tmp_path, capsys):
    ports = {3: free_udp_port(), 4: free_udp_port()}
    vehicles = [
        SimVehicle(endpoint_pair("udpin", port)[0], sid, telemetry_period_s=0.2)
        for sid, port in ports.items()
    ]
    config = _config(tmp_path, ports)
    try:
        assert (
            main(
                ["mission", "upload", "--config", str(config), "--target", "3:10,20", "--target", "4:-5,8,40"]
            )
            == 0
        )
        assert "vehicle 4: uploaded 3 items" in capsys.readouterr().out
        assert [len(v.mission) for v in vehicles] == [3, 3]
        out = tmp_path / "down"
        assert main(["mission", "download", "--config", str(config), "--out", str(out)]) == 0
        assert tuple(vehicles[1].mission) == load_plan(out / "vehicle_4.plan").items
        vehicles[1].mission = []
        assert main(["mission", "upload", "--config", str(config), "--from-dir", str(out)]) == 0
        assert tuple(vehicles[1].mission) == load_plan(out / "vehicle_4.plan").items
        assert main(["mission", "clear", "--config", str(config), "--vehicle", "3"]) == 0
        assert vehicles[0].mission == [] and vehicles[1].mission != []
    finally:
        for v in vehicles:
            v.close()


@pytest.mark.parametrize(("args", "message"), [
    (["--target", "0:10,10"], "vehicle id 0 is out of range: allowed 1-255 (0 is MAVLink's broadcast id)"),
    (["--target", "256:10,10"], "vehicle id 256 is out of range"),
    (["--target", "1:10,10", "--target", "1:20,20"], "vehicle 1 already has a target"),
    (["--waypoint", "1:5,5"], "vehicle 1 has no --target"),
])
def test_malformed_targets_are_refused_at_once(tmp_path, capsys, args, message):
    config = _config(tmp_path, {1: free_udp_port()})
    assert main(["mission", "export", "--config", str(config), *args, "--out", str(tmp_path / "o")]) == 2
    assert message in capsys.readouterr().err and not (tmp_path / "o").exists()


def test_waypoints_come_in_order_before_the_target(tmp_path):
    config = _config(tmp_path, {1: free_udp_port()})
    out = tmp_path / "o"
    assert main(["mission", "export", "--config", str(config), "--waypoint", "1:5,5",
                 "--waypoint", "1:6,7,25", "--target", "1:10,20", "--out", str(out)]) == 0
    items = load_plan(out / "vehicle_1.plan").items
    waypoint = mavlink.MAV_CMD_NAV_WAYPOINT
    assert [i.command for i in items] == [mavlink.MAV_CMD_NAV_TAKEOFF, waypoint, waypoint, waypoint,
                                          mavlink.MAV_CMD_NAV_LOITER_UNLIM]  # target: waypoint + loiter
    assert items[2].z == pytest.approx(25.0) and items[3].x == items[4].x


@pytest.mark.parametrize(("target", "message"), [
    ("7:10,10", "vehicle(s) [7] are not in the bridge config; configured vehicle ids: [1, 2]"),
    ("1:9000,0", "outside the geofence"),
])
def test_upload_refuses_bad_plans_before_waiting_for_any_vehicle(tmp_path, capsys, target, message):
    config = _config(tmp_path, {1: free_udp_port(), 2: free_udp_port()})  # nobody listens: waiting times out
    start = time.monotonic()
    assert main(["mission", "upload", "--config", str(config), "--target", target]) == 2
    assert time.monotonic() - start < 2.0
    assert message in capsys.readouterr().err


@pytest.mark.parametrize(("content", "message"), [
    ('[[10, 20]]', "plans.json: a JSON array; expected an object {\"ID\": [[x_m, y_m]"),
    ('{"1": [[10, 20]], "x": [[1, 2]]}', "plans.json: key 'x' is not a vehicle id (1-255)"),
    ('{"1": [[10, "20"]]}', 'plans.json: vehicle 1: [[10, "20"]] is not a list of points'),
    ('{"1": []}', "plans.json: vehicle 1: [] is not a list of points"),
    ('{"1": [[10, 20]', "plans.json: not valid JSON"),
    ('{"1": [[10, 20]], "7": [[5, 5]]}', "vehicle(s) [7] are not in the bridge config; configured"),
], ids=["list", "key", "string-coordinate", "no-point", "truncated", "unknown-vehicle"])
def test_export_refuses_a_malformed_plans_file_naming_it_and_writes_nothing(tmp_path, capsys, content,
                                                                            message):
    config = _config(tmp_path, {1: free_udp_port()})
    plans = tmp_path / "plans.json"
    plans.write_text(content)
    out = tmp_path / "o"
    argv = ["mission", "export", "--config", str(config), "--plans", str(plans), "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not out.exists()


def test_export_refuses_a_target_for_a_vehicle_the_config_lacks(tmp_path, capsys):
    config = _config(tmp_path, {1: free_udp_port(), 2: free_udp_port()})
    out = tmp_path / "o"
    assert main(["mission", "export", "--config", str(config), "--target", "1:5,5", "--target", "9:5,5",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "vehicle(s) [9] are not in the bridge config; configured vehicle ids: [1, 2]" in err
    assert not out.exists()


def test_export_refuses_targets_closer_than_the_minimum_separation_and_writes_nothing(tmp_path, capsys):
    config = _config(tmp_path, {1: free_udp_port(), 2: free_udp_port(), 3: free_udp_port()})
    out = tmp_path / "o"
    targets = ["--target", "1:5,5", "--target", "2:8,9", "--target", "3:40,5"]  # 1 and 2: 5 m apart
    assert main(["mission", "export", "--config", str(config), *targets, "--min-separation-m", "6",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "the targets of vehicles 1 and 2 are 5.00 m apart: allowed >= --min-separation-m = 6 m" in err
    assert not out.exists()
    assert main(["mission", "export", "--config", str(config), *targets[:4], "--target", "3:8,9,31",
                 "--out", str(out)]) == 2  # over 2's target, 1 m above its cruise altitude (30 m)
    assert "the targets of vehicles 2 and 3 are 1.00 m apart" in capsys.readouterr().err
    layered = [*targets[:4], "--target", "3:8,9,40"]  # over 2's target, 10 m above it: 3-D apart
    assert main(["mission", "export", "--config", str(config), *layered, "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["vehicle_1.plan", "vehicle_2.plan", "vehicle_3.plan"]
