"""Cost of the 802.11 radio in an environment step: ``uav_swarm_v0``, the 802.11 model vs the paper's radio.

The same seeded episode (10 UAVs holding their start positions with zero velocity actions, 516 pedestrians:
6 groups of 86) is stepped with ``propagation = "paper"`` and ``"802.11"``, alternating rounds in one
process so that a changing machine load hits both alike; the ratio of the median step times is printed
(goal: within 1.3x). The same for ``BatchedUAVSwarm`` with 64 worlds, and the radio alone
(``coverage_batch``) for 1 and 64 worlds. The 802.11 runs give the UAVs a channel plan (``plan_channels``,
the nine default 20 MHz channels), as a deployment would.

Usage: python benchmarks/radio/radio_step.py [--steps 300] [--rounds 5 (0: the radio alone)]
       [--batched-steps 30]
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from collections.abc import Callable

import numpy as np

from uav_swarm.env import parallel_env
from uav_swarm.env.batched import BatchedUAVSwarm
from uav_swarm.world.comms import RadioConfig
from uav_swarm.world.comms_batch import coverage_batch
from uav_swarm.world.wifi.channels import plan_channels

SCENARIO = {"n_groups_min": 6, "n_groups_max": 6, "group_size_min": 86, "group_size_max": 86}
WIFI = {"propagation": "802.11"}
PAPER = {"propagation": "paper"}


def median_ms(step: Callable[[], object], steps: int) -> float:
    """Median wall time of ``step`` (ms)."""
    times = []
    for _ in range(steps):
        start = time.perf_counter()
        step()
        times.append(time.perf_counter() - start)
    return 1e3 * float(np.median(times))


def env_step_ms(radio: dict[str, str], steps: int) -> tuple[float, int, float]:
    """Median step of one environment (ms), its crowd size and the last QoS S2."""
    env = parallel_env(n_uavs=10, strategy=2, max_cycles=steps + 2, scenario=SCENARIO, radio=radio)
    env.reset(seed=3)
    hold = {agent: np.zeros(2) for agent in env.possible_agents}
    if radio == WIFI:
        env.set_channel_plan(plan_channels(env.uav_positions_m, env.radio, env.uav_altitudes_m))
    env.step(hold)  # first calls (compilation) outside the timing
    qos = float(env.coverage.qos_s2)
    return median_ms(lambda: env.step(hold), steps), len(env.pedestrian_positions_m), qos


def batched_step_ms(radio: dict[str, str], steps: int, worlds: int) -> float:
    """Median step of a batch of ``worlds`` environments (ms)."""
    env = BatchedUAVSwarm(worlds, n_uavs=10, strategy=2, max_cycles=steps + 2, scenario=SCENARIO, radio=radio)
    env.reset(seed=list(range(worlds)))
    hold = np.zeros((worlds, 10, 2))
    if radio == WIFI:
        heights = np.full(10, env.config.uav.alt_m) + env.config.uav.layer_step_m * np.arange(10)
        env.set_channel_plan(plan_channels(env.uav_positions_m, env.radio, heights))
    env.step(hold)
    return median_ms(lambda: env.step(hold), steps)


def radio_alone_ms(worlds: int, steps: int) -> tuple[float, float]:
    """Median ``coverage_batch`` time (ms) of the paper's radio and the 802.11 model, 516 users per world."""
    rng = np.random.default_rng(1)
    users = rng.uniform(0.0, 200.0, (worlds * 516, 2))
    copy = np.repeat(np.arange(worlds), 516)
    uavs = rng.uniform(40.0, 160.0, (worlds, 10, 2))
    heights = np.full(10, 10.0)
    paper_radio, wifi = RadioConfig(), RadioConfig(propagation="802.11")
    plan = plan_channels(uavs, wifi, heights)
    coverage_batch(users, copy, uavs, wifi, altitudes_m=heights, channels=plan)
    coverage_batch(users, copy, uavs, paper_radio)
    paper = median_ms(lambda: coverage_batch(users, copy, uavs, paper_radio), steps)
    model = median_ms(lambda: coverage_batch(users, copy, uavs, wifi, altitudes_m=heights, channels=plan),
                      steps)
    return paper, model


def report_envs(paper: list[float], model: list[float], paper_b: list[float], model_b: list[float], n: int,
                qos: float) -> None:
    """Print the environment rounds' medians and ratios."""
    print(f"{n} pedestrians, 10 UAVs, one env: step median {np.median(paper):.3f} ms (paper's radio), "
          f"{np.median(model):.3f} ms (802.11): ratio {np.median(model) / np.median(paper):.2f} "
          f"(802.11 QoS S2 {qos:.3f})")
    print(f"64 worlds (BatchedUAVSwarm): step median {np.median(paper_b):.2f} ms (paper's radio), "
          f"{np.median(model_b):.2f} ms (802.11): ratio {np.median(model_b) / np.median(paper_b):.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--rounds", type=int, default=5, help="environment rounds (0: the radio alone only)")
    parser.add_argument("--batched-steps", type=int, default=30)
    args = parser.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs; "
          f"load average at start {os.getloadavg()}")
    paper, model, paper_b, model_b = [], [], [], []
    n, qos = 0, 0.0
    for _ in range(args.rounds):
        ms, n, _ = env_step_ms(PAPER, args.steps)
        paper.append(ms)
        ms, _, qos = env_step_ms(WIFI, args.steps)
        model.append(ms)
        paper_b.append(batched_step_ms(PAPER, args.batched_steps, 64))
        model_b.append(batched_step_ms(WIFI, args.batched_steps, 64))
    if args.rounds:
        report_envs(paper, model, paper_b, model_b, n, qos)
    for worlds in (1, 64):
        alone_paper, alone_model = radio_alone_ms(worlds, args.batched_steps * 3)
        print(f"the radio alone, {worlds} world(s) x 516 users: coverage_batch {alone_paper:.3f} ms (paper), "
              f"{alone_model:.3f} ms (802.11)")
    print(f"load average at end {os.getloadavg()}")


if __name__ == "__main__":
    main()
