import time

import pytest
from lossy_relay import free_udp_port
from pymavlink.dialects.v20 import common as mavlink

from bridge.geo import Home, enu_to_geodetic
from bridge.geofence import GeofenceConfig
from bridge.link.mavlink import MavlinkLink
from bridge.link.vehicle_state import VehicleState, VehicleStateTracker
from bridge.missions.items import MissionConfig, build_mission
from bridge.missions.protocol import MissionClient
from bridge.simulated.peer import SimVehicle, endpoint_pair

HOME = Home()


def _wait(predicate, timeout_s=3.0):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.02)
    raise AssertionError("condition not reached")


def test_state_ingest_gives_typed_state_with_enu_position():
    lat_deg, lon_deg, alt_m = enu_to_geodetic(HOME, 120.0, -45.0, 30.0)
    vehicle_url, gcs_url = endpoint_pair("udpin", free_udp_port())
    tracker = VehicleStateTracker(HOME)
    seen = []
    tracker.add_listener(seen.append)
    with (
        SimVehicle(
            vehicle_url,
            6,
            autopilot=mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
            custom_mode=3,  # AUTO
            lat_deg=lat_deg,
            lon_deg=lon_deg,
            alt_m=alt_m,
        ) as vehicle,
        MavlinkLink(gcs_url) as link,
    ):
        link.add_listener(tracker.update)
        before_s = time.time()
        state = _wait(
            lambda: (
                (s := tracker.state(6))
                and s.mission_seq_current is not None
                and s.heartbeat_time_s is not None
                and s.battery_voltage_v is not None
                and s.x_m is not None
                and s
            )
        )
        assert isinstance(state, VehicleState) and state.system_id == 6
        assert state.autopilot == mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
        assert state.vehicle_type == mavlink.MAV_TYPE_QUADROTOR
        assert state.armed is True and state.mode == "AUTO"
        assert (state.x_m, state.y_m, state.z_m) == pytest.approx((120.0, -45.0, 30.0), abs=0.02)
        assert (state.lat_deg, state.lon_deg) == pytest.approx((lat_deg, lon_deg), abs=1e-7)
        # GLOBAL_POSITION_INT vx=1 m/s North, vy=2 m/s East, vz=-0.5 m/s Down -> ENU (2, 1, 0.5)
        assert (state.vx_m_s, state.vy_m_s, state.vz_m_s) == pytest.approx((2.0, 1.0, 0.5))
        assert state.heading_deg == pytest.approx(90.0)
        assert state.battery_remaining_pct in (75.0, 76.0)
        assert state.battery_voltage_v in (pytest.approx(15.9), pytest.approx(15.8))
        assert (
            state.heartbeat_time_s >= before_s - 1.0 and state.updated_time_s >= state.heartbeat_time_s - 1.0
        )
        mission = build_mission([(10.0, 10.0)], HOME, MissionConfig(), GeofenceConfig(), state.autopilot)
        client = MissionClient(link, 6)
        client.upload(mission.items)
        client.set_current(3)
        state = _wait(lambda: (s := tracker.state(6)) and s.last_reached_seq == 2 and s)
        assert state.mission_seq_current == 3 and state.mission_total == len(mission.items)
        link.send(
            lambda mav: mav.command_int_send(  # guided: the vehicle switches mode
                target_system=6,
                target_component=1,
                frame=mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                command=mavlink.MAV_CMD_DO_REPOSITION,
                current=0,
                autocontinue=0,
                param1=-1.0,
                param2=1.0,
                param3=0.0,
                param4=0.0,
                x=vehicle.mission[1].x,
                y=vehicle.mission[1].y,
                z=20.0,
            )
        )
        assert _wait(lambda: tracker.state(6).mode == "GUIDED")
    assert seen and all(s.system_id == 6 for s in seen)
    assert tracker.states().keys() == {6}
    assert tracker.state(6).to_dict()["system_id"] == 6
