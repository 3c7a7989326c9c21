"""What ``simulate --live`` costs: wall time of the flown run without a live view and with one client.

The learned planner (the shipped checkpoint) flies the default sequence (``SimulateConfig()``: 10 UAVs,
seed 0, replanning every 10 steps, every step streamed) for ``--duration-s`` simulated seconds,
``--rounds`` times each way, after one untimed warm-up run; each round runs every kind once, in an
order rotated from round to round (so that a changing machine load hits all alike):

- ``plain``: no live view, no recording;
- ``layout``: ``simulate --live``: the SDK's WebSocket server on 127.0.0.1 (at most 25 steps streamed
  per wall-clock second, its default) and one client in another process that speaks the Foxglove
  protocol and subscribes to what the committed layout shows (``/scene``, ``/pedestrians``, ``/tf``,
  ``/qos``, ``/plan``: what the Foxglove app asks for with it), reading everything;
- ``all``: the same with the client subscribed to every channel as it is advertised (the per-UAV
  states and fixes too);
- ``all-every``: the same, every step streamed (``max_rate_hz=None``): what the rate limit saves;
- ``stalled-every``: every step streamed to a client subscribed to everything that reads nothing.

The run starts once the client has subscribed to the scene (``wait_for_client_s``; not timed). Printed:
the median wall time of each and its ratio to ``plain``; the ratio of the CPU time of the run's own
process (all its threads, the server's included; not the client's process); what each reading client
received, and how long the server took to stop.

Usage: python benchmarks/bridge/live_view.py [--duration-s 60] [--rounds 5]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import socket
import struct
import subprocess
import sys
import time
from typing import Any

LAYOUT_TOPICS = ("/scene", "/pedestrians", "/tf", "/qos", "/plan")


VARIANTS = {"layout": ("layout", 25.0), "all": ("all", 25.0), "all-every": ("all", None),
            "stalled-every": ("stalled", None)}
"""Each live variant: what its client does, and the live view's ``max_rate_hz``."""


def _client(port: int, kind: str) -> None:
    """A Foxglove-protocol client: subscribe (to the layout's topics or all); read all (or nothing).

    It runs in its own process (``--client PORT KIND``, only the standard library and ``websockets``
    imported) and prints what it received, as JSON, when the server closes the connection.
    """
    read = kind != "stalled"
    from websockets.exceptions import ConnectionClosed
    from websockets.sync.client import connect

    for _ in range(600):
        sock = socket.socket()
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096 if not read else 1 << 20)
        try:
            sock.connect(("127.0.0.1", port))
            break
        except ConnectionRefusedError:
            sock.close()
            time.sleep(0.1)
    ws = connect(f"ws://127.0.0.1:{port}", sock=sock, subprotocols=["foxglove.sdk.v1"], max_size=None,
                 compression=None, proxy=None, ping_interval=None, legacy=True)
    messages, size, subscribed = 0, 0, 0
    try:
        while True:
            frame = ws.recv()
            if isinstance(frame, str):
                op = json.loads(frame)
                if op["op"] == "advertise":
                    wanted = [c for c in op["channels"] if kind != "layout" or c["topic"] in LAYOUT_TOPICS]
                    subscriptions = [{"id": subscribed + i, "channelId": c["id"]}
                                     for i, c in enumerate(wanted, start=1)]
                    subscribed += len(subscriptions)
                    ws.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))
                    if not read and any(c["topic"] == "/scene" for c in op["channels"]):
                        time.sleep(3600)  # reads nothing more: the buffers fill, then the server drops
                continue
            assert struct.unpack_from("<B", frame)[0] == 1
            messages, size = messages + 1, size + len(frame)
    except ConnectionClosed:
        print(json.dumps([messages, size]), flush=True)


def _timed_live(config: Any, planner: Any, scene: Any, variant: str) -> tuple[float, float, float, tuple]:
    """Wall and CPU time of the run, the server's stop time, and (received, bytes received, logged)."""
    from uav_swarm.runs.outputs.fanout import RunOutputs
    from uav_swarm.runs.outputs.live_view import LiveView
    from uav_swarm.runs.outputs.recording import open_recorder
    from uav_swarm.runs.simulate import run_sequence

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    kind, max_rate_hz = VARIANTS[variant]
    client = subprocess.Popen([sys.executable, __file__, "--client", str(port), kind], stdout=subprocess.PIPE,
                              text=True)
    live = LiveView("127.0.0.1", port, wait_for_client_s=120.0, max_rate_hz=max_rate_hz)
    with open_recorder(scene, live=live, command="benchmark") as recorder:
        start_s, cpu_from_s = time.perf_counter(), time.process_time()
        run_sequence(config, planner, "learned", outputs=RunOutputs(recorder=recorder))
        run_s, cpu_s = time.perf_counter() - start_s, time.process_time() - cpu_from_s
        stop_from_s = time.perf_counter()
    stop_s = time.perf_counter() - stop_from_s
    if kind == "stalled":
        client.kill()
    received = json.loads(client.communicate(timeout=120)[0] or "[0, 0]")
    return run_s, cpu_s, stop_s, (*received, sum(recorder.counts.values()))


def main() -> None:
    """Run the comparison and print it."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--duration-s", type=float, default=60.0, help="simulated seconds per run")
    parser.add_argument("--rounds", type=int, default=5, help="runs of each kind")
    parser.add_argument("--client", nargs=2, metavar=("PORT", "KIND"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.client:
        _client(int(args.client[0]), args.client[1])
        return
    import numpy as np

    from uav_swarm.planning.planner import make_planner
    from uav_swarm.runs.outputs.recording import SceneInfo
    from uav_swarm.runs.simulate import run_sequence
    from uav_swarm.runs.simulate_config import SimulateConfig

    config = SimulateConfig.from_dict({"duration_s": args.duration_s})
    planner = make_planner("learned", config.n_uavs, config.task, config=config.planning)
    scene = SceneInfo(width_m=config.task.scenario.width_m, height_m=config.task.scenario.height_m,
                      coverage_radius_m=config.task.radio.coverage_radius_m)
    times: dict[str, list[float]] = {"plain": [], **{variant: [] for variant in VARIANTS}}
    stops: dict[str, list[float]] = {variant: [] for variant in VARIANTS}
    cpu: dict[str, list[float]] = {kind: [] for kind in times}
    received: dict[str, tuple] = {}
    run = run_sequence(config, planner, "learned")  # warm-up, not timed
    kinds = list(times)
    for round_ in range(args.rounds):
        for kind in kinds[round_ % len(kinds):] + kinds[:round_ % len(kinds)]:  # each round in another order
            if kind == "plain":
                start_s, cpu_from_s = time.perf_counter(), time.process_time()
                run = run_sequence(config, planner, "learned")
                times[kind].append(time.perf_counter() - start_s)
                cpu[kind].append(time.process_time() - cpu_from_s)
                continue
            run_s, cpu_s, stop_s, received[kind] = _timed_live(config, planner, scene, kind)
            times[kind].append(run_s)
            cpu[kind].append(cpu_s)
            stops[kind].append(stop_s)
    median = {kind: float(np.median(t)) for kind, t in times.items()}
    median_cpu = {kind: float(np.median(t)) for kind, t in cpu.items()}
    print(f"python {platform.python_version()}, {platform.machine()}, {os.cpu_count()} CPUs, load average "
          f"{', '.join(f'{x:.1f}' for x in os.getloadavg())}")
    print(f"{config.n_uavs} UAVs, {run.n_pedestrians} pedestrians, {args.duration_s:g} s simulated "
          f"({config.n_steps} steps, all streamed), {args.rounds} rounds")
    for kind in times:
        ratio = "" if kind == "plain" else (f"  ratio {median[kind] / median['plain']:.3f}; CPU of the run's "
                                            f"process {median_cpu[kind] / median_cpu['plain']:.3f}")
        print(f"{kind:<13}: {median[kind]:6.2f} s (median; runs {', '.join(f'{t:.2f}' for t in times[kind])})"
              f"{ratio}")
    for kind in ("layout", "all", "all-every"):
        got, size, logged = received[kind]
        print(f"{kind} client: received {got} of the {logged} messages logged for it, {size / 1e6:.1f} MB "
              f"(last round; the server drops the oldest when a client lags)")
    print(f"server stop: at most {max(stops['all-every']):.2f} s with a reading client, "
          f"{max(stops['stalled-every']):.2f} s with the stalled one")


if __name__ == "__main__":
    main()
