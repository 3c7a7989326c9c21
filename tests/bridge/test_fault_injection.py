"""Uploads through a lossy, duplicating, reordering loopback relay still complete and verify.

With scripted faults, a PX4-like vehicle's "busy" answers to a duplicated MISSION_COUNT do
not stop or restart the transfer that goes on.
"""

import numpy as np
import pytest
from lossy_relay import TO_GCS, TO_VEHICLE, LossyRelay, free_udp_port, message_id
from pymavlink.dialects.v20 import common as mavlink

from bridge.config import BridgeConfig, VehicleEndpoint
from bridge.flight.fleet import Fleet
from bridge.simulated.peer import SimVehicle

N_VEHICLES = 10


@pytest.mark.parametrize("drop", [0.1, 0.2])
def test_fleet_upload_through_lossy_relays(drop):
    rng = np.random.default_rng(1234)
    gcs_ports = [free_udp_port() for _ in range(N_VEHICLES)]
    config = BridgeConfig(
        vehicles=tuple(
            VehicleEndpoint(system_id=i + 1, url=f"udpin:127.0.0.1:{port}")
            for i, port in enumerate(gcs_ports)
        )
    )
    plans = {i + 1: [(10.0 * i, -5.0 * i), (20.0 + i, 30.0 - i, 25.0 + i)] for i in range(N_VEHICLES)}
    autopilots = [mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, mavlink.MAV_AUTOPILOT_PX4]
    # The ground station binds its ports before the relays and vehicles open theirs (see tests/ports.py:
    # a port found free must not be left for others to take before the code under test binds it).
    with Fleet(config) as fleet:
        relays = [
            LossyRelay(port, rng.spawn(1)[0], drop=drop, duplicate=0.1, reorder=0.1) for port in gcs_ports
        ]
        vehicles = [
            SimVehicle(
                f"udpout:127.0.0.1:{relay.vehicle_port}",
                i + 1,
                autopilot=autopilots[i % 2],
                telemetry_period_s=0.3,
            )
            for i, relay in enumerate(relays)
        ]
        try:
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


MISSION_COUNT, MISSION_REQUEST_INT = 44, 51


def _upload_through(relay_faults: dict) -> tuple[LossyRelay, SimVehicle, tuple]:
    """Upload to one PX4-like vehicle through a relay with only the given (scripted) faults.

    What the transfer did is judged by the messages it took (counted by the relay), not by its wall
    time, which a busy machine stretches.
    """
    port = free_udp_port()
    config = BridgeConfig(
        max_home_offset_m=0.0, vehicles=(VehicleEndpoint(system_id=1, url=f"udpin:127.0.0.1:{port}"),)
    )
    with Fleet(config) as fleet:  # bound before the relay and the vehicle take ephemeral ports
        relay = LossyRelay(
            port, np.random.default_rng(0), drop=0.0, duplicate=0.0, reorder=0.0, **relay_faults
        )
        vehicle = SimVehicle(f"udpout:127.0.0.1:{relay.vehicle_port}", 1, personality="px4", armed=False)
        try:
            fleet.wait_for_vehicles(timeout_s=10.0)
            mission = fleet.build_missions({1: [(10.0, 5.0), (20.0, 30.0)]})[1]
            fleet.upload({1: mission}, verify=False)
            assert tuple(vehicle.mission) == mission.items
        finally:
            vehicle.close()
            relay.close()
    return relay, vehicle, mission.items


def test_busy_answer_to_a_late_duplicate_count_does_not_stop_the_transfer():
    # the network delivers our MISSION_COUNT again after item 0: PX4 answers MAV_MISSION_ERROR ("Busy")
    # and goes on with the upload, which must go on here too: one MISSION_COUNT, one transfer
    duplicated = []

    def once(direction: int, data: bytes) -> bool:
        if direction == TO_VEHICLE and message_id(data) == MISSION_COUNT and not duplicated:
            duplicated.append(data)
            return True
        return False

    relay, vehicle, _ = _upload_through({"duplicate_late_if": once})
    assert duplicated and relay.messages[TO_VEHICLE, MISSION_COUNT] == 1
    assert vehicle.transfers_started == 1


def test_vehicle_still_asking_keeps_its_transfer_when_we_start_again():
    # the vehicle's requests for item 2 are lost for 1.75 s while it keeps asking (every 0.25 s, as PX4
    # does for 5 s): after 1.5 s of silence we send MISSION_COUNT again, which PX4 answers "Busy"; the
    # transfer it is still in completes when its next request gets through, and is not started again
    lost = []

    def first_requests_for_item_2(direction: int, data: bytes) -> bool:
        request = direction == TO_GCS and message_id(data) == MISSION_REQUEST_INT
        if request and data[10] == 2 and len(lost) < 7:
            lost.append(data)
            return True
        return False

    relay, vehicle, _ = _upload_through({"drop_if": first_requests_for_item_2})
    assert len(lost) == 7
    assert relay.messages[TO_VEHICLE, MISSION_COUNT] == 2  # the first, and one after 1.5 s of silence
    assert vehicle.transfers_started == 1
