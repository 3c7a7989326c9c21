"""ArduPilot as it really answers (SimVehicle's ArduPilot personality), the home check, missions in flight."""

import math
import time

import numpy as np
import pytest
from lossy_relay import free_udp_port
from peer_fleet import close_all
from pymavlink.dialects.v20 import common as mavlink

from bridge import errors
from bridge.config import BridgeConfig, ProtocolConfig, VehicleEndpoint
from bridge.flight.fleet import Fleet, FleetError
from bridge.geo import Home
from bridge.missions.compare import compare_missions
from bridge.missions.items import DEG_E7, MissionConfig, MissionItem, build_mission
from bridge.simulated.peer import SimVehicle, endpoint_pair
from uav_swarm.cli import main

CMAC = Home(lat_deg=-35.363262, lon_deg=149.165237, alt_m=584.0)  # ArduPilot SITL's default home
AT_CMAC = {"lat_deg": CMAC.lat_deg, "lon_deg": CMAC.lon_deg, "alt_m": CMAC.alt_m}
FAST = {"handshake_timeout_s": 0.3, "item_timeout_s": 0.1, "max_retries": 3, "heartbeat_timeout_s": 5.0}


def _vehicles(n, **kwargs):
    ports = [free_udp_port() for _ in range(n)]
    vehicles = [
        SimVehicle(endpoint_pair("udpin", port)[0], i + 1, telemetry_period_s=0.1, **kwargs)
        for i, port in enumerate(ports)
    ]
    endpoints = tuple(
        VehicleEndpoint(system_id=i + 1, url=endpoint_pair("udpin", port)[1]) for i, port in enumerate(ports)
    )
    return vehicles, endpoints



def test_upload_right_after_boot_is_retried_and_verifies_with_exact_positions():
    vehicles, endpoints = _vehicles(2, personality="ardupilot", boot_no_space_s=1.0, **AT_CMAC)
    config = BridgeConfig(home=CMAC, vehicles=endpoints, mission=MissionConfig(loiter_time_s=30.0))
    # at 149 deg East a float32 degree is 1.5e-5 deg (~1.4 m) coarse: degE7 must arrive exact
    plans = {1: [(123.4567, -98.7654), (-45.6789, 67.891, 41.23)], 2: [(0.123, 0.456)]}
    try:
        with Fleet(config) as fleet:
            start_s = time.monotonic()
            missions = fleet.upload_plans(plans)  # verified by download, ArduPilot's changes accepted
            elapsed_s = time.monotonic() - start_s
    finally:
        close_all(vehicles)
    assert 1.0 <= elapsed_s < 6.0
    for vehicle in vehicles:
        assert vehicle.refused_counts >= 1 and vehicle.uploads == 1
        sent = missions[vehicle.system_id].items
        assert vehicle.legacy_requests and len(vehicle.mission) == len(sent)
        for ours, stored in zip(sent[1:], vehicle.mission[1:], strict=True):
            assert (stored.x, stored.y) == (ours.x, ours.y)  # exact degE7, not float32 rounding
        assert vehicle.mission[1].frame == mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT  # stored de-INTed
        assert (vehicle.mission[0].x, vehicle.mission[0].y) == (round(CMAC.lat_deg * DEG_E7),
                                                                round(CMAC.lon_deg * DEG_E7))


def test_no_space_after_the_retry_time_shows_what_the_vehicle_said():
    vehicles, endpoints = _vehicles(1, personality="ardupilot", boot_no_space_s=30.0, **AT_CMAC)
    config = BridgeConfig(home=CMAC, vehicles=endpoints, protocol=ProtocolConfig(busy_retry_s=1.0, **FAST))
    try:
        with Fleet(config) as fleet, pytest.raises(FleetError) as info:
            fleet.upload_plans({1: [(10.0, 10.0)]})
    finally:
        close_all(vehicles)
    exc = info.value.errors[1]
    assert isinstance(exc, errors.MissionNoSpaceError)
    assert 'vehicle says: "Only 0 items are supported"' in str(exc)
    assert "still refused after asking again for 1." in str(exc) and "busy_retry_s = 1.0" in str(exc)
    assert vehicles[0].refused_counts >= 3  # asked again with back-off


def test_a_real_capacity_refusal_is_final_at_once():
    vehicles, endpoints = _vehicles(1, personality="ardupilot", max_items=3, **AT_CMAC)
    config = BridgeConfig(home=CMAC, vehicles=endpoints, protocol=ProtocolConfig(**FAST))
    try:
        with Fleet(config) as fleet:
            fleet.wait_for_vehicles()
            start_s = time.monotonic()
            with pytest.raises(FleetError) as info:
                fleet.upload_plans({1: [(10.0, 10.0), (20.0, 20.0)]})  # home, take-off, 2 waypoints, loiter
            elapsed_s = time.monotonic() - start_s
    finally:
        close_all(vehicles)
    assert 'vehicle says: "Only 3 items are supported"' in str(info.value.errors[1])
    assert vehicles[0].refused_counts == 1 and elapsed_s < 2.0


def _ardupilot_copy(items, home):
    """The items as ArduPilot Copter reads them back (written out here, independently of SimVehicle)."""
    out = []
    for item in items:
        fields = item.message_fields()
        if item.seq == 0:
            x, y = round(home.lat_deg * DEG_E7), round(home.lon_deg * DEG_E7)
            fields.update(frame=0, x=x, y=y, z=home.alt_m)
        else:
            fields["frame"] = {5: 0, 6: 3}.get(item.frame, item.frame)
            for name in ("param1", "param2", "param3", "param4"):
                fields[name] = 0.0 if math.isnan(fields[name]) else fields[name]
            if item.command == mavlink.MAV_CMD_NAV_WAYPOINT:
                fields["param2"] = 0.0
            if item.command == mavlink.MAV_CMD_NAV_LOITER_TIME:
                fields["param3"] = 1.0
            if item.command == mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH:
                fields["frame"] = 0
        out.append(MissionItem(**fields))
    return out


def test_compare_accepts_ardupilots_changes_and_nothing_else():
    config = MissionConfig(loiter_time_s=20.0, return_to_launch=True)
    ardupilot = mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
    sent = build_mission([(30.0, 40.0)], CMAC, config, BridgeConfig().geofence, ardupilot)
    back = _ardupilot_copy(sent.items, Home(lat_deg=-35.3632, lon_deg=149.1652, alt_m=583.9))
    compare_missions(1, sent.items, back, vehicle_home=True)
    strict = r"item 0: MAV_CMD_NAV_WAYPOINT: frame sent 5, read back 0; x sent .*\(strict comparison\)"
    with pytest.raises(errors.MissionMismatchError, match=strict):
        compare_missions(1, sent.items, back, strict=True, vehicle_home=True)
    with pytest.raises(errors.MissionMismatchError, match="item 0"):
        compare_missions(1, sent.items, back)  # seq 0 is a home only for ArduPilot
    moved = list(back)
    moved[2] = MissionItem(**{**moved[2].message_fields(), "x": moved[2].x + 1})  # 1 cm off
    with pytest.raises(errors.MissionMismatchError, match=r"item 2: MAV_CMD_NAV_WAYPOINT: x sent"):
        compare_missions(1, sent.items, moved, vehicle_home=True)
    higher = list(back)
    higher[3] = MissionItem(**{**higher[3].message_fields(), "z": higher[3].z + 0.5})
    with pytest.raises(errors.MissionMismatchError, match="item 3: MAV_CMD_NAV_LOITER_TIME: z sent 30.0"):
        compare_missions(1, sent.items, higher, vehicle_home=True)


def test_positions_read_back_as_float32_degrees_compare_within_their_rounding():
    sent = build_mission([(30.0, 40.0)], CMAC, MissionConfig(), BridgeConfig().geofence).items
    as_float = [
        MissionItem(**{**i.message_fields(), "x": round(float(np.float32(i.x / DEG_E7)) * DEG_E7),
                       "y": round(float(np.float32(i.y / DEG_E7)) * DEG_E7)})
        for i in sent
    ]
    assert any(a.y != b.y for a, b in zip(sent, as_float, strict=True))  # float32 rounding is visible
    compare_missions(1, sent, as_float, float_positions=range(len(sent)))
    with pytest.raises(errors.MissionMismatchError):
        compare_missions(1, sent, as_float)  # read back as MISSION_ITEM_INT they must be exact


def test_strict_upload_reports_the_mismatch(tmp_path, capsys):
    vehicles, endpoints = _vehicles(1, personality="ardupilot", **AT_CMAC)
    config = _toml(tmp_path, endpoints, home=CMAC)
    try:
        assert main(["mission", "upload", "--config", str(config), "--target", "1:10,20"]) == 0
        assert "vehicle 1: uploaded 4 items in" in capsys.readouterr().out
        assert main(["mission", "upload", "--config", str(config), "--target", "1:10,20", "--strict"]) == 1
    finally:
        close_all(vehicles)
    err = capsys.readouterr().err
    assert "vehicle 1: the mission read back differs in item 0" in err
    assert len(err) < 600  # one readable line, not a dump


def _toml(tmp_path, endpoints, home=None, extra=()):
    lines = [*extra, "[protocol]", "heartbeat_timeout_s = 2.0", "handshake_timeout_s = 0.3", ""]
    if home is not None:
        lines += ["[home]", f"lat_deg = {home.lat_deg}", f"lon_deg = {home.lon_deg}", f"alt_m = {home.alt_m}"]
    for endpoint in endpoints:
        lines += ["[[vehicles]]", f"system_id = {endpoint.system_id}", f'url = "{endpoint.url}"', ""]
    path = tmp_path / "bridge.toml"
    path.write_text("\n".join(lines))
    return path


def test_a_vehicle_far_from_the_configured_home_is_refused_unless_its_own_home_is_used(tmp_path, capsys):
    vehicles, endpoints = _vehicles(1, personality="ardupilot", **AT_CMAC)
    try:
        zurich = _toml(tmp_path, endpoints, home=Home())
        assert main(["mission", "upload", "--config", str(zurich), "--target", "1:10,20"]) == 2
        err = capsys.readouterr().err
        assert "uav-swarm mission upload: vehicle 1: its home (lat -35.3632620, lon 149.1652370" in err
        assert "from the mission's home (lat 47.3977418, lon 8.5455938" in err
        assert "max_home_offset_m = 100 m" in err
        assert vehicles[0].uploads == 0
        own = _toml(tmp_path, endpoints, extra=['home = "vehicle"'])
        assert main(["mission", "upload", "--config", str(own), "--target", "1:10,20"]) == 0
    finally:
        close_all(vehicles)
    assert vehicles[0].uploads == 1
    waypoint = vehicles[0].mission[2]  # home, take-off, waypoint: 10 m East, 20 m North of the vehicle
    assert waypoint.x / DEG_E7 == pytest.approx(CMAC.lat_deg + 20 / 111_000, abs=2e-6)
    assert waypoint.x / DEG_E7 - CMAC.lat_deg > 0 and waypoint.y / DEG_E7 - CMAC.lon_deg > 0


def test_the_ardupilot_example_config_starts_at_sitls_default_home():
    from test_fleet import CONFIGS

    import typed_config

    config = typed_config.load_toml(BridgeConfig, CONFIGS / "ardupilot_sitl_10.toml")
    assert config.home == CMAC and config.max_home_offset_m == 100.0 and config.home_source == "config"


def test_a_mission_being_flown_is_neither_cleared_nor_replaced_without_force(tmp_path, capsys):
    vehicles, endpoints = _vehicles(1, personality="ardupilot", **AT_CMAC)
    config = _toml(tmp_path, endpoints, home=CMAC)
    upload = ["mission", "upload", "--config", str(config), "--target", "1:10,20"]
    clear = ["mission", "clear", "--config", str(config)]
    try:
        assert main(upload) == 0
        vehicles[0].custom_mode, vehicles[0].current_seq = 3, 2  # armed, AUTO, flying item 2
        assert main(clear) == 2
        assert "vehicle 1: is flying its mission (armed, mode AUTO, at item 2)" in (
            capsys.readouterr().err
        )
        assert main([*upload[:-1], "1:30,30"]) == 2 and vehicles[0].uploads == 1
        assert main([*clear, "--force"]) == 1  # ArduPilot itself refuses, and the error says why
        err = capsys.readouterr().err
        assert "vehicle 1 refused the transfer: MAV_MISSION_ERROR (1)" in err
        assert "switch the vehicle to another mode" in err and vehicles[0].mission
        assert main([*upload[:-1], "1:30,30", "--force"]) == 0 and vehicles[0].uploads == 2
        vehicles[0].custom_mode = 5  # LOITER
        assert main(clear) == 0 and vehicles[0].mission == []
    finally:
        close_all(vehicles)


def test_ten_vehicles_three_absent_each_named_and_every_other_verified(tmp_path, capsys):
    present, endpoints = _vehicles(7, personality="ardupilot", **AT_CMAC)
    closed_tcp = endpoint_pair("tcp", free_udp_port())[1]  # nothing listens: the connection is refused
    absent = (
        VehicleEndpoint(system_id=8, url=f"udpin:127.0.0.1:{free_udp_port()}"),
        VehicleEndpoint(system_id=9, url=closed_tcp),
        VehicleEndpoint(system_id=10, url=f"udpin:127.0.0.1:{free_udp_port()}"),
    )
    config = BridgeConfig(home=CMAC, vehicles=(*endpoints, *absent), protocol=ProtocolConfig(**FAST))
    plans = {sid: [(5.0 * sid, 10.0)] for sid in range(1, 11)}
    try:
        with Fleet(config) as fleet:
            start_s = time.monotonic()
            with pytest.raises(FleetError) as info:
                fleet.upload_plans(plans)
            elapsed_s = time.monotonic() - start_s
        path = _toml(tmp_path, (*endpoints, *absent), home=CMAC)
        target = [arg for sid in range(1, 11) for arg in ("--target", f"{sid}:{5 * sid},10")]
        assert main(["mission", "upload", "--config", str(path), *target]) == 1
    finally:
        close_all(present)
    assert elapsed_s < 5.0 + 3.0  # each absent one within its own discovery time, not one after another
    assert set(info.value.errors) == {8, 9, 10} and set(info.value.results) == set(range(1, 8))
    assert isinstance(info.value.errors[8], errors.HeartbeatTimeoutError)
    assert isinstance(info.value.errors[9], errors.VehicleUnreachableError)
    for vehicle in present:
        assert vehicle.uploads == 2  # Python, then the CLI
        assert vehicle.mission[2].x == info.value.results[vehicle.system_id].items[2].x
    out, err = capsys.readouterr()
    assert out.count("verified (download and compare) in") == 7
    lines = err.strip().splitlines()
    assert [line.split(": ")[1] for line in lines] == [
        "HeartbeatTimeoutError", "VehicleUnreachableError", "HeartbeatTimeoutError"
    ]
    assert all(f"vehicle {sid}:" in line for sid, line in zip((8, 9, 10), lines, strict=True))
    assert "vehicle 8: vehicle 8" not in err
