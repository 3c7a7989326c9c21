"""Agent-steps per second of BatchedUAVSwarm against separate uav_swarm_v0 envs and VMAS, in one run.

For each number of copies N (default 1, 16, 64, 256), with 10 UAVs and 200 pedestrians per copy (5
groups of 40), it measures (a) one ``BatchedUAVSwarm(N)``, (b) N separate ``uav_swarm_v0`` parallel
envs stepped in a Python loop and (c) VMAS's ``navigation`` scenario with ``num_envs=N`` and 10 agents
on the CPU (continuous actions). Every step draws fresh uniform random actions from a seeded generator
(velocity actions in [-1, 1]). The three run in interleaved rounds, so a machine whose load changes
during the run affects them alike. Goal: batched >= 5x separate at 64 copies.

Usage: python benchmarks/batched_env.py [--copies 1 16 64 256] [--steps 60] [--rounds 3]
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import time
from collections.abc import Callable

import numpy as np
import torch
import vmas

from uav_swarm.env.batched import BatchedUAVSwarm
from uav_swarm.env.parallel import parallel_env

N_UAVS = 10
CROWD = {"n_groups_min": 5, "n_groups_max": 5, "group_size_min": 40, "group_size_max": 40}  # 200 people


def cpu_model() -> str:
    """The CPU model name as lscpu reports it."""
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return platform.processor() or "unknown"
    return next((line.split(":", 1)[1].strip() for line in out.splitlines() if line.startswith("Model name")),
                "unknown")


def batched_stepper(copies: int) -> Callable[[], None]:
    envs = BatchedUAVSwarm(copies, n_uavs=N_UAVS, scenario=CROWD, max_cycles=10**6)
    envs.reset(seed=0)
    assert (envs.crowd.counts() == 200).all()
    rng = np.random.default_rng(0)

    def step() -> None:
        envs.step(rng.uniform(-1.0, 1.0, size=(copies, N_UAVS, 2)))

    return step


def separate_stepper(copies: int) -> Callable[[], None]:
    envs = [parallel_env(n_uavs=N_UAVS, scenario=CROWD, max_cycles=10**6) for _ in range(copies)]
    for k, env in enumerate(envs):
        env.reset(seed=k)
    agents = envs[0].possible_agents
    rng = np.random.default_rng(0)

    def step() -> None:
        actions = rng.uniform(-1.0, 1.0, size=(copies, N_UAVS, 2))
        for env, action in zip(envs, actions, strict=True):
            env.step(dict(zip(agents, action, strict=True)))

    return step


def vmas_stepper(copies: int) -> Callable[[], None]:
    env = vmas.make_env(scenario="navigation", num_envs=copies, device="cpu", n_agents=N_UAVS,
                        continuous_actions=True, seed=0)
    env.reset()
    dims = [space.shape[-1] for space in env.action_space]
    rng = np.random.default_rng(0)

    def step() -> None:
        env.step([torch.from_numpy(rng.uniform(-1.0, 1.0, size=(copies, d)).astype(np.float32))
                  for d in dims])

    return step


def measure(steppers: dict[str, Callable[[], None]], steps: int, rounds: int) -> dict[str, float]:
    """Seconds per step of each stepper: a short warm-up, then interleaved rounds."""
    seconds = dict.fromkeys(steppers, 0.0)
    for step in steppers.values():
        for _ in range(3):
            step()
    per_round = max(1, steps // rounds)
    for _ in range(rounds):
        for name, step in steppers.items():
            start = time.perf_counter()
            for _ in range(per_round):
                step()
            seconds[name] += time.perf_counter() - start
    return {name: s / (per_round * rounds) for name, s in seconds.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--copies", type=int, nargs="+", default=[1, 16, 64, 256], help="numbers of copies")
    parser.add_argument("--steps", type=int, default=60, help="measured steps per environment and size")
    parser.add_argument("--rounds", type=int, default=3, help="interleaved rounds")
    args = parser.parse_args()
    print(f"CPU: {cpu_model()}, {os.cpu_count()} logical CPUs; python {platform.python_version()}, "
          f"numpy {np.__version__}, torch {torch.__version__} ({torch.get_num_threads()} threads), "
          f"vmas {vmas.__version__}")
    print(f"{N_UAVS} UAVs / agents and 200 pedestrians per copy; agent-steps/s (copies x agents x steps / s)")
    print(f"{'copies':>6} {'batched':>12} {'separate':>12} {'vmas':>12} {'batched/separate':>17} "
          f"{'batched/vmas':>13} {'batched ms/step':>16}")
    for copies in args.copies:
        steppers = {"batched": batched_stepper(copies), "separate": separate_stepper(copies),
                    "vmas": vmas_stepper(copies)}
        per_step = measure(steppers, args.steps, args.rounds)
        rate = {name: copies * N_UAVS / s for name, s in per_step.items()}
        print(f"{copies:6d} {rate['batched']:12.0f} {rate['separate']:12.0f} {rate['vmas']:12.0f} "
              f"{rate['batched'] / rate['separate']:16.2f}x {rate['batched'] / rate['vmas']:12.2f}x "
              f"{per_step['batched'] * 1e3:16.2f}")


if __name__ == "__main__":
    main()
