"""Mission upload time: our bridge against MAVSDK's own mission-raw upload client, in one run.

Vehicles: MAVSDK (native binding, >= 4) instances configured as autopilots with the
MissionRawServer plugin, each on its own loopback UDP port; one set of vehicles per client
so that both see identical peers. Mission: 5 items (take-off, 3 waypoints, unlimited
loiter) in ``MAV_FRAME_GLOBAL_RELATIVE_ALT_INT``. Timed: from the first MISSION_COUNT to
the last MISSION_ACK (vehicles already discovered; no verification download), for 1 vehicle
and for 10 vehicles at once (ours: ``Fleet.upload(..., verify=False)``, all vehicles from the
calling thread; MAVSDK: the blocking ``MissionRaw.upload_mission`` of every system, one
thread per vehicle; ``upload_mission_async`` is not used: with 10 concurrent calls it
corrupted the heap at exit in MAVSDK 4.1.0 here).
Rounds alternate between the two clients; the median of the rounds is reported. The CPU
model, its vector flags and the load average are printed first: the machine may be shared.

Run: ``python benchmarks/bridge/mission_upload.py [--rounds 30]``; under loss:
``python benchmarks/bridge/mission_upload_loss.py``.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import platform
import socket
import statistics
import time
from concurrent.futures import ThreadPoolExecutor
from multiprocessing.synchronize import Event

import mavsdk
from mavsdk import ComponentType, Configuration, Mavsdk, log_subscribe, log_unsubscribe
from mavsdk.plugins.mission_raw import MissionItem as MavsdkItem
from mavsdk.plugins.mission_raw import MissionRaw
from mavsdk.plugins.mission_raw_server import MissionRawServer

from bridge.config import BridgeConfig, VehicleEndpoint
from bridge.flight.fleet import Fleet
from bridge.geo import Home
from bridge.geofence import GeofenceConfig
from bridge.missions.items import MissionConfig, build_mission

N_FLEET = 10
PLAN_M = [(20.0, 10.0), (60.0, -30.0), (-15.0, 45.0)]
_SHOWN_FLAGS = ("sse4_2", "avx", "avx2", "avx512f", "avx512_bf16", "amx_tile")


def machine_line() -> str:
    """CPU model, core count, vector flags and load average (``/proc`` where there is one)."""
    model, flags = platform.processor() or platform.machine(), set()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as info:
            for line in info:
                key, _, value = line.partition(":")
                if key.strip() == "model name":
                    model = value.strip()
                elif key.strip() == "flags":
                    flags = set(value.split())
                    break
    except OSError:
        pass
    shown = ", ".join(flag for flag in _SHOWN_FLAGS if flag in flags) or "none"
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    return f"CPU: {model}, {os.cpu_count()} cores; flags: {shown}; load average {load}"


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def serve_vehicles(ports: list[int], ready: Event, stop: Event) -> None:
    """Child process: MAVSDK autopilots with system ids 1..n, vehicle i sending to 127.0.0.1:ports[i]."""
    log_subscribe(lambda level, message, file, line: True)
    parts = []
    for i, port in enumerate(ports):
        config = Configuration.create_with_component_type(ComponentType.AUTOPILOT)
        config.system_id, config.component_id = i + 1, 1
        instance = Mavsdk(config)
        instance.add_any_connection(f"udpout://127.0.0.1:{port}")
        parts.append((config, instance, MissionRawServer(instance.server_component())))
    ready.set()
    stop.wait()
    for config, instance, _ in parts:
        instance.destroy()
        config.destroy()


class MavsdkStation:
    """MAVSDK as ground station, one UDP listener per vehicle."""

    def __init__(self, ports: list[int]) -> None:
        self._config = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
        self._mavsdk = Mavsdk(self._config)
        for port in ports:
            self._mavsdk.add_any_connection(f"udpin://127.0.0.1:{port}")
        deadline = time.monotonic() + 20.0
        while time.monotonic() < deadline:
            systems = [s for s in self._mavsdk.get_systems() if s.has_autopilot()]
            if len(systems) == len(ports):
                break
            time.sleep(0.1)
        else:
            raise RuntimeError(f"MAVSDK discovered {len(systems)} of {len(ports)} vehicles")
        self.plugins = {s.get_system_id(): MissionRaw(s) for s in systems}
        self._pool = ThreadPoolExecutor(max_workers=len(ports))

    def upload(self, system_ids: list[int], items: list[MavsdkItem]) -> None:
        """Upload ``items`` to every vehicle of ``system_ids`` at once; returns when all are acknowledged."""
        if len(system_ids) == 1:
            self.plugins[system_ids[0]].upload_mission(items)  # raises MissionRawError on failure
            return
        futures = [self._pool.submit(self.plugins[sid].upload_mission, items) for sid in system_ids]
        for future in futures:
            future.result(timeout=10.0)

    def close(self) -> None:
        """Stop the threads and the MAVSDK instance."""
        self._pool.shutdown()
        self._mavsdk.destroy()
        self._config.destroy()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=30, help="timed rounds per client and fleet size")
    args = parser.parse_args()
    print(machine_line())
    log_subscribe(lambda level, message, file, line: True)  # MAVSDK's console log off

    mission = build_mission(PLAN_M, Home(), MissionConfig(), GeofenceConfig())
    assert len(mission.items) == 5
    mavsdk_items = [MavsdkItem(**item.message_fields()) for item in mission.items]

    ours_ports = [free_udp_port() for _ in range(N_FLEET)]
    theirs_ports = [free_udp_port() for _ in range(N_FLEET)]
    spawn = mp.get_context("spawn")
    stop = spawn.Event()
    children = []
    for ports in (ours_ports, theirs_ports):
        ready = spawn.Event()
        child = spawn.Process(target=serve_vehicles, args=(ports, ready, stop), daemon=True)
        child.start()
        children.append(child)
        if not ready.wait(30.0):
            raise RuntimeError("MAVSDK vehicles did not start")
    config = BridgeConfig(
        vehicles=tuple(
            VehicleEndpoint(system_id=i + 1, url=f"udpin:127.0.0.1:{port}")
            for i, port in enumerate(ours_ports)
        )
    )
    station = MavsdkStation(theirs_ports)
    times_s: dict[tuple[str, int], list[float]] = {}
    try:
        with Fleet(config) as fleet:
            fleet.wait_for_vehicles(timeout_s=20.0)
            for n in (1, N_FLEET):
                ids = list(range(1, n + 1))
                for _ in range(args.rounds):
                    start_s = time.perf_counter()
                    fleet.upload({sid: mission for sid in ids}, verify=False)
                    times_s.setdefault(("ours", n), []).append(time.perf_counter() - start_s)
                    start_s = time.perf_counter()
                    station.upload(ids, mavsdk_items)
                    times_s.setdefault(("mavsdk", n), []).append(time.perf_counter() - start_s)
    finally:
        station.close()
        stop.set()
        for child in children:
            child.join(timeout=10.0)
        log_unsubscribe()

    print(
        f"python {platform.python_version()}, mavsdk {mavsdk.__version__}, {platform.machine()}, "
        f"{args.rounds} rounds, 5-item mission, loopback UDP"
    )
    for n in (1, N_FLEET):
        ours = statistics.median(times_s[("ours", n)]) * 1e3
        theirs = statistics.median(times_s[("mavsdk", n)]) * 1e3
        verdict = "meets" if ours <= theirs else "misses"
        print(
            f"{n:2d} vehicle(s): ours {ours:7.2f} ms, MAVSDK {theirs:7.2f} ms (medians); "
            f"MAVSDK/ours = {theirs / ours:5.2f}x (goal >= 1x: {verdict})"
        )


if __name__ == "__main__":
    main()
