import time
from pathlib import Path

import pytest
from lossy_relay import free_tcp_port, free_udp_port
from pymavlink.dialects.v20 import common as mavlink

import typed_config
from bridge import errors
from bridge.config import BridgeConfig, ProtocolConfig, VehicleEndpoint
from bridge.flight.fleet import Fleet, FleetError
from bridge.geofence import GeofenceConfig
from bridge.simulated.peer import TRANSPORTS, SimVehicle, endpoint_pair

CONFIGS = Path(__file__).resolve().parents[2] / "configs" / "bridge"


def _fleet_setup(n, overrides=None):
    vehicles, endpoints = [], []
    for i in range(n):
        transport = TRANSPORTS[i % len(TRANSPORTS)]
        port = free_tcp_port() if transport == "tcp" else free_udp_port()
        vehicle_url, gcs_url = endpoint_pair(transport, port)
        kwargs = (overrides or {}).get(i + 1, {})
        vehicles.append(SimVehicle(vehicle_url, i + 1, telemetry_period_s=0.3, **kwargs))
        endpoints.append(VehicleEndpoint(system_id=i + 1, url=gcs_url))
    return vehicles, endpoints


def test_ten_vehicles_concurrently_over_mixed_transports():
    vehicles, endpoints = _fleet_setup(
        10, {i: {"autopilot": mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA} for i in (2, 5, 8)}
    )
    plans = {v.system_id: [(5.0 * v.system_id, 40.0 - v.system_id)] for v in vehicles}
    try:
        with Fleet(BridgeConfig(vehicles=tuple(endpoints))) as fleet:
            autopilots = fleet.wait_for_vehicles(timeout_s=10.0)
            assert [autopilots[i] for i in (2, 5, 8)] == [mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA] * 3
            start_s = time.monotonic()
            missions = fleet.upload_plans(plans)
            elapsed_s = time.monotonic() - start_s
            for v in vehicles:
                assert tuple(v.mission) == missions[v.system_id].items
                assert missions[v.system_id].has_home_placeholder == (v.system_id in (2, 5, 8))
            downloaded = fleet.download()
            assert {sid: m.items for sid, m in downloaded.items()} == {
                sid: m.items for sid, m in missions.items()
            }
            fleet.reposition(4, 10.0, 10.0, 30.0)
            assert vehicles[3].reposition_target is not None
            fleet.clear([1, 2])
            assert vehicles[0].mission == [] and vehicles[1].mission == [] and vehicles[2].mission != []
            states = fleet.states()
            assert set(states) == set(range(1, 11)) and all(s.battery_remaining_pct for s in states.values())
    finally:
        for v in vehicles:
            v.close()
    assert elapsed_s < 3.0  # concurrent: far below 10 sequential verified uploads on a loaded machine


def test_geofence_refusal_sends_nothing_to_any_vehicle():
    vehicles, endpoints = _fleet_setup(2)
    try:
        with Fleet(BridgeConfig(vehicles=tuple(endpoints), geofence=GeofenceConfig(x_max_m=100.0))) as fleet:
            fleet.wait_for_vehicles(timeout_s=10.0)
            with pytest.raises(errors.GeofenceError, match=r"vehicle 2: target: x_m = 150.00 is outside"):
                fleet.upload_plans({1: [(50.0, 0.0)], 2: [(150.0, 0.0)]})
            time.sleep(0.3)
            assert [v.uploads for v in vehicles] == [0, 0]
    finally:
        for v in vehicles:
            v.close()


def test_one_failing_vehicle_is_reported_by_name_and_others_succeed():
    vehicles, endpoints = _fleet_setup(3, {2: {"refuse_code": mavlink.MAV_MISSION_NO_SPACE, "refuse_seq": 0}})
    protocol = ProtocolConfig(handshake_timeout_s=0.3, item_timeout_s=0.1, max_retries=2)
    try:
        with Fleet(BridgeConfig(vehicles=tuple(endpoints), protocol=protocol)) as fleet:
            fleet.wait_for_vehicles(timeout_s=10.0)
            with pytest.raises(FleetError) as info:
                fleet.upload_plans({sid: [(10.0, 10.0)] for sid in (1, 2, 3)})
            with pytest.raises(KeyError, match="vehicle 99 is not configured"):
                fleet.client(99)
    finally:
        for v in vehicles:
            v.close()
    assert set(info.value.errors) == {2} and set(info.value.results) == {1, 3}
    exc = info.value.errors[2]
    assert isinstance(exc, errors.MissionNoSpaceError) and (exc.system_id, exc.seq) == (2, 0)
    assert vehicles[0].uploads == 1 and vehicles[2].uploads == 1


def test_silent_fleet_member_fails_discovery_by_name():
    port = free_udp_port()
    config = BridgeConfig(vehicles=(VehicleEndpoint(system_id=42, url=f"udpin:127.0.0.1:{port}"),))
    with Fleet(config) as fleet:
        start_s = time.monotonic()
        with pytest.raises(FleetError) as info:
            fleet.wait_for_vehicles(timeout_s=0.3)
        assert time.monotonic() - start_s < 1.0
    assert isinstance(info.value.errors[42], errors.HeartbeatTimeoutError)


@pytest.mark.parametrize(
    "name, urls",
    [
        ("ardupilot_sitl_10.toml", [f"tcp:127.0.0.1:{5760 + 10 * i}" for i in range(10)]),
        ("px4_sitl_10.toml", [f"udpin:127.0.0.1:{14540 + i}" for i in range(10)]),
    ],
)
def test_example_configs_describe_ten_loopback_vehicles(name, urls):
    config = typed_config.load_toml(BridgeConfig, CONFIGS / name)
    assert [v.url for v in config.vehicles] == urls
    assert [v.system_id for v in config.vehicles] == list(range(1, 11))
    assert config.protocol == ProtocolConfig(heartbeat_timeout_s=10.0)


@pytest.mark.parametrize(
    "data, message",
    [
        ({"vehicles": [{"system_id": 1, "url": "serial:/dev/ttyUSB0"}]}, "use one of"),
        (
            {
                "vehicles": [
                    {"system_id": 1, "url": "udpin:127.0.0.1:1"},
                    {"system_id": 1, "url": "tcp:127.0.0.1:2"},
                ]
            },
            "system ids must be distinct",
        ),
        ({"vehicles": [{"system_id": i, "url": f"tcp:127.0.0.1:{i}"} for i in range(1, 12)]}, "at most 10"),
        ({"protocol": {"max_retries": 50}}, "max_retries = 50 is out of range"),
        ({"signing": {"key_file": "a", "key_env": "B"}}, "not both"),
        ({"vehicle": []}, "unknown key"),
    ],
)
def test_bad_configs_are_refused_with_the_field_named(data, message):
    with pytest.raises(typed_config.ConfigError, match=message):
        BridgeConfig.from_dict(data)


def test_a_vehicle_started_after_the_fleet_is_reached_and_pymavlink_prints_nothing(capfd, caplog):
    """Its TCP port refused at first, it is named with the reason, then tried again until it answers."""
    import logging

    caplog.set_level(logging.INFO)
    vehicle_url, gcs_url = endpoint_pair("tcp", free_tcp_port())
    vehicle = None
    try:
        with Fleet(BridgeConfig(vehicles=(VehicleEndpoint(system_id=1, url=gcs_url),))) as fleet:
            with pytest.raises(errors.VehicleUnreachableError, match="Connection refused"):
                fleet.link(1)
            assert fleet.silence(1) == (f"vehicle 1: cannot connect to {gcs_url}: [Errno 111] Connection "
                                        "refused: is it running?")
            vehicle = SimVehicle(vehicle_url, 1, telemetry_period_s=0.3)
            deadline = time.monotonic() + 10.0
            while time.monotonic() < deadline:
                try:
                    fleet.link(1)
                    break
                except errors.VehicleUnreachableError:
                    time.sleep(0.1)
            assert fleet.wait_for_vehicles(timeout_s=5.0) == {1: vehicle.autopilot}
    finally:
        if vehicle is not None:
            vehicle.close()
    assert f"connected to {gcs_url} (vehicle 1)" in caplog.text
    out, _ = capfd.readouterr()
    assert "sleeping" not in out and "EOF" not in out
