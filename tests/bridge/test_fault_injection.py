"""Uploads through a lossy, duplicating, reordering loopback relay still complete and verify."""

import numpy as np
import pytest
from lossy_relay import LossyRelay, free_udp_port
from pymavlink.dialects.v20 import common as mavlink
from sim_vehicle import SimVehicle

from bridge.config import BridgeConfig, VehicleEndpoint
from bridge.fleet import Fleet

N_VEHICLES = 10


@pytest.mark.parametrize("drop", [0.1, 0.2])
def test_fleet_upload_through_lossy_relays(drop):
    rng = np.random.default_rng(1234)
    gcs_ports = [free_udp_port() for _ in range(N_VEHICLES)]
    relays = [LossyRelay(port, rng.spawn(1)[0], drop=drop, duplicate=0.1, reorder=0.1) for port in gcs_ports]
    autopilots = [mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, mavlink.MAV_AUTOPILOT_PX4]
    vehicles = [
        SimVehicle(
            f"udpout:127.0.0.1:{relay.vehicle_port}",
            i + 1,
            autopilot=autopilots[i % 2],
            telemetry_period_s=0.3,
        )
        for i, relay in enumerate(relays)
    ]
    config = BridgeConfig(
        vehicles=tuple(
            VehicleEndpoint(system_id=i + 1, url=f"udpin:127.0.0.1:{port}")
            for i, port in enumerate(gcs_ports)
        )
    )
    plans = {i + 1: [(10.0 * i, -5.0 * i), (20.0 + i, 30.0 - i, 25.0 + i)] for i in range(N_VEHICLES)}
    try:
        with Fleet(config) as fleet:
            fleet.wait_for_vehicles(timeout_s=10.0)
            missions = fleet.upload_plans(plans, verify=True)  # download-and-compare on every vehicle
            for vehicle in vehicles:
                assert tuple(vehicle.mission) == missions[vehicle.system_id].items
                placeholder = vehicle.autopilot == mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
                assert len(vehicle.mission) == (5 if placeholder else 4)  # takeoff, 2 waypoints, loiter
    finally:
        for closable in (*vehicles, *relays):
            closable.close()
    dropped = sum(r.counts["dropped"] for r in relays)
    total = sum(r.counts["in"] for r in relays)
    assert dropped / total == pytest.approx(drop, abs=0.05)
    assert sum(r.counts["duplicated"] for r in relays) > 0 and sum(r.counts["reordered"] for r in relays) > 0
