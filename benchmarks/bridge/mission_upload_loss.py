"""Mission upload time to 10 vehicles through lossy links: 10 % and 20 % loss, 5 seeds each.

Vehicles: 10 MAVSDK (native binding, >= 4) autopilots with the MissionRawServer plugin,
each behind its own seeded lossy loopback UDP relay (``tests/bridge/lossy_relay.py``: the
given loss each way, 10 % duplicates, 10 % reordering), vehicles and relays in a child
process of their own so that the relays' threads do not share our interpreter. Mission:
the 5 items of ``benchmarks/bridge/mission_upload.py``. Timed: ``Fleet.upload(..., verify=False)``
to all 10 at once (vehicles already discovered), from the first MISSION_COUNT to the last
MISSION_ACK; also counted: whole-transfer restarts (a new MISSION_COUNT after a vehicle
fell silent mid-transfer) and the MISSION_COUNTs that reached the relays.

Run: ``python benchmarks/bridge/mission_upload_loss.py [--seeds 5] [--loss 0.1 0.2]``.
"""

from __future__ import annotations

import argparse
import logging
import multiprocessing as mp
import statistics
import sys
import time
from multiprocessing.connection import Connection
from pathlib import Path

from mission_upload import PLAN_M, free_udp_port, machine_line

from bridge.config import BridgeConfig, VehicleEndpoint
from bridge.flight.fleet import Fleet, FleetError
from bridge.geo import Home
from bridge.geofence import GeofenceConfig
from bridge.missions.items import MissionConfig, build_mission

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests" / "bridge"))
from lossy_relay import TO_VEHICLE  # noqa: E402 - a test helper, found through the path above

N_VEHICLES = 10
MISSION_COUNT = 44


def serve_vehicles(gcs_ports: list[int], loss: float, seed: int, pipe: Connection) -> None:
    """Child process: MAVSDK autopilots 1..n, vehicle i behind a lossy relay to ``gcs_ports[i]``.

    Sends ``"ready"``, then on any message the MISSION_COUNTs its relays forwarded, and stops.
    """
    import numpy as np
    from lossy_relay import LossyRelay
    from mavsdk_vehicles import MavsdkVehicle, quiet_mavsdk_logs

    quiet_mavsdk_logs()
    rng = np.random.default_rng(seed)
    relays = [LossyRelay(port, rng.spawn(1)[0], drop=loss, duplicate=0.1, reorder=0.1) for port in gcs_ports]
    vehicles = [MavsdkVehicle(i + 1, f"udpout://127.0.0.1:{r.vehicle_port}") for i, r in enumerate(relays)]
    pipe.send("ready")
    pipe.recv()
    pipe.send(sum(r.messages[TO_VEHICLE, MISSION_COUNT] for r in relays))
    for closable in (*vehicles, *relays):
        closable.close()


class _Restarts(logging.Handler):
    """Counts the bridge's "transfer attempt" warnings (whole-transfer restarts)."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.count = 0

    def emit(self, record: logging.LogRecord) -> None:
        self.count += "transfer attempt" in record.getMessage()


def run_once(loss: float, seed: int) -> tuple[float, int, int, list[str]]:
    """``(seconds until every upload ended, restarts, MISSION_COUNTs, failures)`` for one seed."""
    gcs_ports = [free_udp_port() for _ in range(N_VEHICLES)]
    config = BridgeConfig(
        max_home_offset_m=0.0,
        vehicles=tuple(
            VehicleEndpoint(system_id=i + 1, url=f"udpin:127.0.0.1:{p}") for i, p in enumerate(gcs_ports)
        ),
    )
    mission = build_mission(PLAN_M, Home(), MissionConfig(), GeofenceConfig())
    restarts = _Restarts()
    ours, theirs = mp.get_context("spawn").Pipe()
    child = mp.get_context("spawn").Process(target=serve_vehicles, args=(gcs_ports, loss, seed, theirs))
    with Fleet(config) as fleet:  # our ports are bound before the relays take ephemeral ones
        child.start()
        try:
            if not ours.poll(60.0) or ours.recv() != "ready":
                raise RuntimeError("vehicles did not start")
            fleet.wait_for_vehicles(timeout_s=20.0)
            logging.getLogger("bridge").addHandler(restarts)
            start_s = time.perf_counter()
            try:
                fleet.upload({sid: mission for sid in range(1, N_VEHICLES + 1)}, verify=False)
                failed = []
            except FleetError as exc:
                failed = [f"{type(e).__name__}: {e}" for _, e in sorted(exc.errors.items())]
            total_s = time.perf_counter() - start_s
        finally:
            logging.getLogger("bridge").removeHandler(restarts)
            ours.send("stop")
            counts = ours.recv() if ours.poll(30.0) else -1
            child.join(timeout=30.0)
    return total_s, restarts.count, counts, failed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5, help="seeds per loss level")
    parser.add_argument("--loss", type=float, nargs="+", default=[0.1, 0.2], help="loss each way")
    args = parser.parse_args()
    print(machine_line())
    print(f"{N_VEHICLES} MAVSDK vehicles, 5-item mission, lossy loopback UDP (10 % duplicated, 10 % late)")
    for loss in args.loss:
        totals = []
        for seed in range(args.seeds):
            total_s, restarts, counts, failed = run_once(loss, seed)
            totals.append(total_s)
            print(
                f"loss {loss:4.0%} seed {seed}: {total_s:6.3f} s for all 10, {len(failed)} failed; "
                f"{restarts} whole-transfer restart(s), {counts} MISSION_COUNT(s) reached the relays"
            )
            for line in failed:
                print(f"    {line}")
        print(f"loss {loss:4.0%}: median {statistics.median(totals):6.3f} s, max {max(totals):6.3f} s")


if __name__ == "__main__":
    main()
