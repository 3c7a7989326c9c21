"""Cost of admission control in an environment step: ``uav_swarm_v0`` with and without a station limit.

The same seeded episode (10 UAVs hovering over the crowd, 1,000-odd pedestrians: 12-14 groups of 70-80) is
stepped with the paper's association and with admission control (``station_limit = "auto"``), alternating
rounds in one process; the ratio of the median step times is printed (issue 33's goal: within 1.5x).

Usage: python benchmarks/radio/admission_step.py [--steps 300] [--rounds 5]
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

from uav_swarm.env import parallel_env

SCENARIO = {"n_groups_min": 12, "n_groups_max": 14, "group_size_min": 70, "group_size_max": 80}


def step_ms(station_limit: str | None, steps: int) -> tuple[float, int]:
    """Median wall time of one step (ms) and the crowd size."""
    radio = {"propagation": "paper"} | ({} if station_limit is None else {"station_limit": station_limit})
    env = parallel_env(n_uavs=10, strategy=2, max_cycles=steps + 1, scenario=SCENARIO, radio=radio)
    env.reset(seed=3)
    rng = np.random.default_rng(0)
    peds = env.pedestrian_positions_m
    hover = {agent: peds[rng.integers(len(peds))] for agent in env.possible_agents}  # over the crowd
    times = []
    for _ in range(steps):
        start = time.perf_counter()
        env.step(hover)
        times.append(time.perf_counter() - start)
    return 1e3 * float(np.median(times)), len(peds)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs; "
          f"load average at start {os.getloadavg()}")
    paper, admission = [], []
    for _ in range(args.rounds):
        ms, n = step_ms(None, args.steps)
        paper.append(ms)
        admission.append(step_ms("auto", args.steps)[0])
    ratio = np.median(admission) / np.median(paper)
    print(f"{n} pedestrians, 10 UAVs: step median {np.median(paper):.3f} ms (paper's association), "
          f"{np.median(admission):.3f} ms (admission control): ratio {ratio:.2f}")
    print(f"load average at end {os.getloadavg()}")


if __name__ == "__main__":
    main()
