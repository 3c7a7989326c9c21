import time

import pytest
from lossy_relay import free_tcp_port, free_udp_port
from pymavlink.dialects.v20 import common as mavlink

from bridge import errors
from bridge.config import ProtocolConfig
from bridge.flight.commands import reposition
from bridge.geo import Home, enu_to_geodetic
from bridge.geofence import GeofenceConfig
from bridge.link.mavlink import MavlinkLink
from bridge.link.signing import SigningKey
from bridge.missions.items import DEG_E7, MissionConfig, build_mission
from bridge.missions.protocol import MissionClient
from bridge.simulated.peer import TRANSPORTS, SimVehicle, endpoint_pair

HOME = Home()
FAST = ProtocolConfig(handshake_timeout_s=0.2, item_timeout_s=0.05, max_retries=2)


def _mission(autopilot=mavlink.MAV_AUTOPILOT_PX4):
    return build_mission(
        [(10.0, 20.0), (-40.0, 60.0, 45.0)], HOME, MissionConfig(), GeofenceConfig(), autopilot
    )


def _pair(transport, system_id=1, link_kwargs=None, **vehicle_kwargs):
    port = free_tcp_port() if transport == "tcp" else free_udp_port()
    vehicle_url, gcs_url = endpoint_pair(transport, port)
    vehicle = SimVehicle(vehicle_url, system_id, **vehicle_kwargs)
    link = MavlinkLink(gcs_url, **(link_kwargs or {}))
    return vehicle, link


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_upload_download_clear_set_current(transport):
    vehicle, link = _pair(transport, system_id=7, autopilot=mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA)
    with vehicle, link:
        heartbeat = link.wait_heartbeat(7, 5.0)
        assert heartbeat.autopilot == mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
        mission = _mission(heartbeat.autopilot)
        client = MissionClient(link, 7)
        client.upload(mission.items)
        assert tuple(vehicle.mission) == mission.items
        assert client.download() == mission.items
        client.set_current(2)
        assert vehicle.current_seq == 2
        client.clear()
        assert vehicle.mission == [] and client.download() == ()


def test_legacy_mission_request_is_answered_with_mission_item_int_exactly():
    home = Home(lat_deg=-35.363262, lon_deg=149.165237, alt_m=584.0)  # float32 degrees: ~1.4 m steps here
    vehicle, link = _pair("udpin", legacy_requests=True)
    with vehicle, link:
        link.wait_heartbeat(1, 5.0)
        points = [(12.345, -67.891), (-40.0, 60.0, 45.0)]
        mission = build_mission(points, home, MissionConfig(), GeofenceConfig())
        MissionClient(link, 1).upload(mission.items)
    assert tuple(vehicle.mission) == mission.items  # every field, degE7 positions exact


RESULT_CODES = [
    code for code in mavlink.enums["MAV_MISSION_RESULT"] if 0 < code < mavlink.MAV_MISSION_RESULT_ENUM_END
]


@pytest.mark.parametrize(
    "code", RESULT_CODES, ids=[mavlink.enums["MAV_MISSION_RESULT"][c].name for c in RESULT_CODES]
)
def test_each_mission_result_code_raises_its_named_exception(code):
    vehicle, link = _pair("udpin", system_id=4, refuse_code=code, refuse_seq=2)
    with vehicle, link:
        link.wait_heartbeat(4, 5.0)
        start_s = time.monotonic()
        with pytest.raises(errors.MissionResultError) as info:
            MissionClient(link, 4, FAST).upload(_mission().items)
    exc = info.value
    assert type(exc) is not errors.MissionResultError and exc.result == code
    assert (exc.system_id, exc.seq) == (4, 2)
    assert type(exc) is type(errors.mission_result_error(code, 4, 2))
    assert f"vehicle 4 refused item 2: {mavlink.enums['MAV_MISSION_RESULT'][code].name}" in str(exc)
    assert time.monotonic() - start_s < 2.0


def test_silent_vehicle_times_out_with_protocol_timing():
    vehicle, link = _pair("udpin", system_id=9, silent=True)
    with vehicle, link:
        link.wait_heartbeat(9, 5.0)
        start_s = time.monotonic()
        with pytest.raises(errors.MissionTimeoutError) as info:
            MissionClient(link, 9).upload(_mission().items)  # spec timing: 1.5 s x (1 + 5 retries)
        elapsed_s = time.monotonic() - start_s
    assert (info.value.system_id, info.value.stage) == (9, "MISSION_REQUEST")
    assert isinstance(info.value, TimeoutError)
    assert 8.9 <= elapsed_s <= 10.5


@pytest.mark.parametrize("operation", ["download", "clear", "set_current"])
def test_silent_vehicle_never_hangs_other_operations(operation):
    vehicle, link = _pair("udpin", system_id=9, silent=True)
    with vehicle, link:
        link.wait_heartbeat(9, 5.0)
        client = MissionClient(link, 9, FAST)
        start_s = time.monotonic()
        with pytest.raises(errors.MissionTimeoutError, match="vehicle 9: no MISSION_"):
            getattr(client, operation)(*((1,) if operation == "set_current" else ()))
        assert time.monotonic() - start_s < 1.0


def test_reposition_is_acknowledged_and_rejections_are_named():
    fence = GeofenceConfig()
    vehicle, link = _pair("udpout", system_id=3)
    with vehicle, link:
        link.wait_heartbeat(3, 5.0)
        reposition(link, 3, HOME, fence, 30.0, -20.0, 40.0)
        lat_deg, lon_deg, _ = enu_to_geodetic(HOME, 30.0, -20.0, 40.0)
        assert vehicle.reposition_target == (round(lat_deg * DEG_E7), round(lon_deg * DEG_E7), 40.0)
        assert vehicle.custom_mode == 4  # switched to GUIDED
        vehicle.command_result = mavlink.MAV_RESULT_DENIED
        with pytest.raises(errors.CommandRejectedError, match="MAV_CMD_DO_REPOSITION: MAV_RESULT_DENIED"):
            reposition(link, 3, HOME, fence, 30.0, -20.0, 40.0)
        with pytest.raises(errors.GeofenceError):
            reposition(link, 3, HOME, fence, 3000.0, 0.0, 40.0)
        vehicle.silent = True
        with pytest.raises(errors.CommandTimeoutError):
            reposition(link, 3, HOME, fence, 30.0, -20.0, 40.0, protocol=FAST)


def test_signed_link_talks_to_signing_vehicle_and_unsigned_one_is_ignored():
    key = SigningKey.from_text("correct horse battery staple")
    vehicle, link = _pair("udpin", system_id=5, link_kwargs={"signing_key": key}, signing_key=key.secret)
    with vehicle, link:
        link.wait_heartbeat(5, 5.0)
        MissionClient(link, 5).upload(_mission().items)
        assert vehicle.uploads == 1
    vehicle, link = _pair("udpin", system_id=5, signing_key=key.secret)
    with vehicle, link:
        link.wait_heartbeat(5, 5.0)  # the vehicle's heartbeats are signed; we accept them
        with pytest.raises(errors.MissionTimeoutError):
            MissionClient(link, 5, FAST).upload(_mission().items)  # our unsigned messages are dropped
        assert vehicle.uploads == 0
    assert "correct" not in repr(key) and "hidden" in repr(key)
