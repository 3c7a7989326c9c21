"""Placement time: the shipped utility network (raster -> CNN -> peaks) against the task's expert.

For each task with a shipped checkpoint (``uav_swarm/checkpoints/<task>.pt``) draws ``--n`` fresh
scenes and times, on the same scene, the expert's placement (Wi-Fi: the greedy + local-search
optimiser on the crowd; AGP/FP: visibility matrix + exact set cover with HiGHS) against the
learned placement (observation raster, one batch-1 forward pass, peak extraction). Reference: the
expert. Prints medians, p95 and the ratio expert / learned.

Usage: python benchmarks/learning/learned_vs_expert.py [--n 30] [--seed 0] [--threads 1]
"""

from __future__ import annotations

import argparse
import platform
import time
from importlib import resources

import numpy as np
import torch

from learning.checkpoint import load_checkpoint
from learning.data import sample_seed
from learning.inference import predict_positions
from uav_swarm.missions.monitoring.guards import solve_guards
from uav_swarm.missions.registry import build_task

TASKS = ("wifi-s1", "wifi-s2", "agp", "fp")


def expert_seconds(task, scene) -> float:
    """Wall time of the expert on one scene, recomputed from the scene's raw data."""
    start = time.perf_counter()
    if task.name.startswith("wifi"):
        task.expert_placement_m(np.asarray(scene.users_m))
    else:
        solve_guards(task.problem(scene.polygon))
    return time.perf_counter() - start


def learned_seconds(task, scene, ckpt) -> float:
    """Wall time of observation + network + peaks on one scene."""
    start = time.perf_counter()
    predict_positions(ckpt.model, task.observe(scene), 10, ckpt.peak_config)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=30)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    print(f"python {platform.python_version()}, torch {torch.__version__}, {platform.machine()}, "
          f"{args.threads} torch thread(s), {args.n} scenes per task")
    header = ("task", "expert p50 ms", "p95", "learned p50 ms", "p95", "expert/learned")
    print("{:8} {:>14} {:>8} {:>15} {:>7} {:>15}".format(*header))
    for name in TASKS:
        path = resources.files("uav_swarm") / "checkpoints" / f"{name}.pt"
        if not path.is_file():
            print(f"{name:8} no shipped checkpoint")
            continue
        ckpt = load_checkpoint(path, task_name=name)
        task = build_task(name, ckpt.task_config)
        scenes = [task.sample(np.random.default_rng(sample_seed(args.seed, "val", i))) for i in range(args.n)]
        learned_seconds(task, scenes[0], ckpt)  # warm-up
        experts = np.array([expert_seconds(task, s) for s in scenes]) * 1e3
        learned = np.array([learned_seconds(task, s, ckpt) for s in scenes]) * 1e3
        ratio = np.median(experts) / np.median(learned)
        print(f"{name:8} {np.median(experts):14.1f} {np.percentile(experts, 95):8.1f} "
              f"{np.median(learned):15.2f} {np.percentile(learned, 95):7.2f} {ratio:14.0f}x")


if __name__ == "__main__":
    main()
