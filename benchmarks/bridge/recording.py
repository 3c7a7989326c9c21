"""What ``simulate --record`` costs: wall time of the flown run with and without the MCAP recording.

The learned planner (the shipped checkpoint) flies the default sequence (``SimulateConfig()``:
10 UAVs, seed 0, replanning every 10 steps) for ``--duration-s`` simulated seconds, ``--rounds``
times without and with a recorder (alternating, so that a changing machine load hits both alike),
recording every step (``telemetry_every = 1``, the default). Printed: the median wall time of each,
the recording's cost per recorded step, the file's size per simulated minute and its messages.

Usage: python benchmarks/bridge/recording.py [--duration-s 60] [--rounds 3]
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np

from uav_swarm.planning.planner import make_planner
from uav_swarm.runs.outputs.fanout import RunOutputs
from uav_swarm.runs.outputs.recording import SceneInfo, open_recorder
from uav_swarm.runs.simulate import run_sequence
from uav_swarm.runs.simulate_config import SimulateConfig


def main() -> None:
    """Run the comparison and print it."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--duration-s", type=float, default=60.0, help="simulated seconds per run")
    parser.add_argument("--rounds", type=int, default=3, help="runs of each kind")
    args = parser.parse_args()
    config = SimulateConfig.from_dict({"duration_s": args.duration_s})
    planner = make_planner("learned", config.n_uavs, config.task, config=config.planning)
    scene = SceneInfo(width_m=config.task.scenario.width_m, height_m=config.task.scenario.height_m,
                      coverage_radius_m=config.task.radio.coverage_radius_m)
    plain_s, recorded_s = [], []
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "run.mcap"
        for _ in range(args.rounds):
            start_s = time.perf_counter()
            run = run_sequence(config, planner, "learned")
            plain_s.append(time.perf_counter() - start_s)
            start_s = time.perf_counter()
            with open_recorder(scene, record=path, command="benchmark") as recorder:
                run_sequence(config, planner, "learned", outputs=RunOutputs(recorder=recorder))
            recorded_s.append(time.perf_counter() - start_s)
        size_mb = path.stat().st_size / 1e6
        counts = recorder.counts
    plain, recorded = float(np.median(plain_s)), float(np.median(recorded_s))
    steps = config.n_steps
    print(f"python {platform.python_version()}, {platform.machine()}, load average "
          f"{', '.join(f'{x:.1f}' for x in os.getloadavg())}")
    print(f"{config.n_uavs} UAVs, {run.n_pedestrians} pedestrians, {args.duration_s:g} s simulated "
          f"({steps} steps), {args.rounds} rounds")
    print(f"without recording: {plain:6.2f} s (median; runs {', '.join(f'{t:.2f}' for t in plain_s)})")
    print(f"with recording   : {recorded:6.2f} s (median; runs {', '.join(f'{t:.2f}' for t in recorded_s)})")
    print(f"recording cost   : {1e3 * (recorded - plain) / steps:.3f} ms per recorded step "
          f"({100 * (recorded - plain) / plain:+.0f} %)")
    print(f"file             : {size_mb:.2f} MB, {size_mb * 60 / args.duration_s:.2f} MB per simulated "
          f"minute, {sum(counts.values())} messages on {len(counts)} topics")


if __name__ == "__main__":
    main()
