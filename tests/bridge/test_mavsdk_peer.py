"""MAVSDK (an independent implementation, configured as autopilots) receives exactly what we send."""

import numpy as np
import pytest
from lossy_relay import LossyRelay, free_udp_port
from mavsdk_vehicles import MavsdkVehicle, quiet_mavsdk_logs
from pymavlink.dialects.v20 import common as mavlink

from bridge.config import BridgeConfig, VehicleEndpoint
from bridge.flight.fleet import Fleet
from bridge.missions.items import MissionConfig

N_VEHICLES = 4


@pytest.mark.parametrize("drop", [0.0, 0.2], ids=["direct", "lossy-20pct"])
def test_mavsdk_vehicles_receive_what_we_send(drop):
    quiet_mavsdk_logs()
    rng = np.random.default_rng(99)
    gcs_ports = [free_udp_port() for _ in range(N_VEHICLES)]
    relays = (
        [LossyRelay(p, rng.spawn(1)[0], drop=drop, duplicate=0.1, reorder=0.1) for p in gcs_ports]
        if drop
        else []
    )
    vehicle_ports = [r.vehicle_port for r in relays] if relays else gcs_ports
    system_ids = [11 + 3 * i for i in range(N_VEHICLES)]
    vehicles = [
        MavsdkVehicle(sid, f"udpout://127.0.0.1:{port}")
        for sid, port in zip(system_ids, vehicle_ports, strict=True)
    ]
    config = BridgeConfig(
        mission=MissionConfig(loiter_time_s=20.0, return_to_launch=True, acceptance_radius_m=3.5),
        max_home_offset_m=0.0,  # MAVSDK's mission server reports no position: no home to compare with
        vehicles=tuple(
            VehicleEndpoint(system_id=sid, url=f"udpin:127.0.0.1:{port}")
            for sid, port in zip(system_ids, gcs_ports, strict=True)
        ),
    )
    plans = {sid: [(15.0 * i, -12.5 * i, 28.0), (-40.0 + i, 75.0, 41.5)] for i, sid in enumerate(system_ids)}
    try:
        with Fleet(config) as fleet:
            autopilots = fleet.wait_for_vehicles(timeout_s=10.0)
            assert set(autopilots) == set(system_ids)
            missions = fleet.upload_plans(plans, verify=True)
            for vehicle in vehicles:
                received = vehicle.wait_missions(1, timeout_s=5.0)
                assert received, f"MAVSDK vehicle {vehicle.system_id} received nothing"
                sent = missions[vehicle.system_id].items
                assert received[-1] == sent  # every field: seq, frame, command, current, params, x, y, z
                commands = [item.command for item in received[-1]]
                assert commands == [
                    mavlink.MAV_CMD_NAV_TAKEOFF,
                    mavlink.MAV_CMD_NAV_WAYPOINT,
                    mavlink.MAV_CMD_NAV_WAYPOINT,
                    mavlink.MAV_CMD_NAV_LOITER_TIME,
                    mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH,
                ]
                assert [item.frame for item in received[-1][:4]] == [
                    mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
                ] * 4
            # the others' missions differ: each vehicle got its own
            assert len({missions[sid].items[1].x for sid in system_ids}) == N_VEHICLES
    finally:
        for closable in (*vehicles, *relays):
            closable.close()
    if relays:
        assert sum(r.counts["dropped"] for r in relays) > 0
