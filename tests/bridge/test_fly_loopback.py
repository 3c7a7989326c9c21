"""``uav-swarm fly`` under strace: a fleet of simulated vehicles flown on loopback, and nothing else reached.

The vehicles (:class:`bridge.simulated.ardupilot.ArduCopter`, real MAVLink sockets) live in this process;
``fly`` runs in its own, under ``strace -f`` with no telemetry setting of its own, and sends its Zenoh
telemetry to a subscriber here: every address it reaches is 127.0.0.1, and it asks no name resolver.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from lossy_relay import free_tcp_port, free_udp_port
from peer_fleet import bridge_toml, close_all
from traffic import destinations, off_loopback, strace_prefix

import uav_swarm
from bridge.simulated.ardupilot import FAILSAFE_ON, RTL, ArduCopter
from bridge.simulated.fleet import launch_home
from bridge.simulated.peer import endpoint_pair
from bridge.telemetry import SwarmSubscriber
from bridge.telemetry.config import TelemetryConfig

REPO = Path(__file__).resolve().parents[2]
FAST = {"handshake_timeout_s": 0.3, "item_timeout_s": 0.1, "max_retries": 3}


def test_fly_reaches_its_vehicles_and_telemetry_on_loopback_only(tmp_path):
    vehicles, urls = [], []
    for i in range(2):
        vehicle_url, gcs_url = endpoint_pair("udpin", free_udp_port())
        vehicles.append(ArduCopter(vehicle_url, i + 1, home=launch_home(i), params=FAILSAFE_ON))
        urls.append(gcs_url)
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    config = tmp_path / "fly.toml"
    config.write_text(f'[telemetry]\nswarm = "quietfly"\nlisten = []\nconnect = ["{endpoint}"]\n')
    env = {k: v for k, v in os.environ.items() if k not in uav_swarm.TELEMETRY_OFF}
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    trace, received = tmp_path / "fly.strace", []
    try:
        with SwarmSubscriber(TelemetryConfig(swarm="quietfly", listen=(endpoint,), connect=()),
                             callback=received.append):
            run = subprocess.run(
                strace_prefix(trace) + [sys.executable, "-m", "uav_swarm", "fly", "--bridge-config",
                                        str(bridge_toml(tmp_path / "bridge.toml", urls, FAST)), "--config",
                                        str(config), "--out", str(tmp_path / "out"), "--duration-s", "8",
                                        "--speedup", "2", "--quiet"],
                env=env, capture_output=True, text=True, timeout=600)
        assert run.returncode == 0, run.stderr[-3000:]
        assert all(vehicle.custom_mode == RTL for vehicle in vehicles)  # flown and sent home
    finally:
        close_all(vehicles)
    addresses, calls = destinations(trace)
    assert received and calls > 0 and addresses <= {"127.0.0.1", "::1"}
    assert off_loopback(trace) == []
