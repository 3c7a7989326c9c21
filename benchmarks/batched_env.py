"""Agent-steps per second of BatchedUAVSwarm against separate uav_swarm_v0 envs and VMAS, in one run.

For each crowd size (default 200 pedestrians per copy, 5 groups of 40, and 516, the default scenario's
mean, 6 groups of 86) and each number of copies N (default 1, 16, 64, 256), with 10 UAVs, it measures (a)
one ``BatchedUAVSwarm(N)``, (b) N separate ``uav_swarm_v0`` parallel envs stepped in a Python loop and (c)
VMAS's ``navigation`` scenario with ``num_envs=N`` and 10 agents on the CPU (continuous actions;
``--no-vmas`` leaves it out, for a machine without the ``bench`` extra). Every step draws fresh uniform random
actions from a seeded generator (velocity actions in [-1, 1]). The three run in interleaved rounds, so a
machine whose load changes during the run affects them alike. The load average before and after is
printed. Goal: batched >= 5x separate at 64 copies, at both crowd sizes.

Usage: python benchmarks/batched_env.py [--pedestrians 200 516] [--copies 1 16 64 256] [--steps 60]
[--rounds 3] [--no-vmas]
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

from uav_swarm.env.batched import BatchedUAVSwarm
from uav_swarm.env.parallel import parallel_env

N_UAVS = 10
GROUPS = {200: 5, 516: 6}  # pedestrians -> groups of equal size


def crowd_of(pedestrians: int) -> dict:
    """Scenario settings that give exactly ``pedestrians`` per copy."""
    groups = GROUPS.get(pedestrians, 10)
    if pedestrians % groups:
        raise SystemExit(f"--pedestrians {pedestrians}: give a multiple of {groups}")
    size = pedestrians // groups
    return {"n_groups_min": groups, "n_groups_max": groups, "group_size_min": size, "group_size_max": size}


def cpu_model() -> str:
    """The CPU model name as lscpu reports it."""
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return platform.processor() or "unknown"
    return next((line.split(":", 1)[1].strip() for line in out.splitlines() if line.startswith("Model name")),
                "unknown")


def batched_stepper(copies: int, pedestrians: int) -> Callable[[], None]:
    envs = BatchedUAVSwarm(copies, n_uavs=N_UAVS, scenario=crowd_of(pedestrians), max_cycles=10**6)
    envs.reset(seed=0)
    assert (envs.crowd.counts() == pedestrians).all()
    rng = np.random.default_rng(0)

    def step() -> None:
        envs.step(rng.uniform(-1.0, 1.0, size=(copies, N_UAVS, 2)))

    return step


def separate_stepper(copies: int, pedestrians: int) -> Callable[[], None]:
    envs = [parallel_env(n_uavs=N_UAVS, scenario=crowd_of(pedestrians), max_cycles=10**6)
            for _ in range(copies)]
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
    import vmas

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
    parser.add_argument("--pedestrians", type=int, nargs="+", default=[200, 516], help="crowd sizes per copy")
    parser.add_argument("--copies", type=int, nargs="+", default=[1, 16, 64, 256], help="numbers of copies")
    parser.add_argument("--steps", type=int, default=60, help="measured steps per environment and size")
    parser.add_argument("--rounds", type=int, default=3, help="interleaved rounds")
    parser.add_argument("--no-vmas", action="store_true", help="leave VMAS out")
    args = parser.parse_args()
    try:
        vmas_version = "left out" if args.no_vmas else __import__("vmas").__version__
    except ImportError:
        raise SystemExit("vmas is not installed: pip install 'uav-swarm[bench]', or pass --no-vmas") from None
    print(f"CPU: {cpu_model()}, {os.cpu_count()} logical CPUs; python {platform.python_version()}, "
          f"numpy {np.__version__}, torch {torch.__version__} ({torch.get_num_threads()} threads), "
          f"vmas {vmas_version}")
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(f"{N_UAVS} UAVs / agents per copy; agent-steps/s (copies x agents x steps / s)")
    print(f"{'peds':>5} {'copies':>6} {'batched':>12} {'separate':>12} {'vmas':>12} {'batched/separate':>17} "
          f"{'batched/vmas':>13} {'batched ms/step':>16}")
    for pedestrians in args.pedestrians:
        for copies in args.copies:
            steppers = {"batched": batched_stepper(copies, pedestrians),
                        "separate": separate_stepper(copies, pedestrians)}
            if not args.no_vmas:
                steppers["vmas"] = vmas_stepper(copies)
            per_step = measure(steppers, args.steps, args.rounds)
            rate = {name: copies * N_UAVS / s for name, s in per_step.items()}
            rate.setdefault("vmas", float("nan"))
            print(f"{pedestrians:5d} {copies:6d} {rate['batched']:12.0f} {rate['separate']:12.0f} "
                  f"{rate['vmas']:12.0f} {rate['batched'] / rate['separate']:16.2f}x "
                  f"{rate['batched'] / rate['vmas']:12.2f}x {per_step['batched'] * 1e3:16.2f}")
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
