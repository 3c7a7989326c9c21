"""Refinement of learned placements against the expert, per mission, on the same held-out scenes.

For each task the shipped network (``uav_swarm/checkpoints/<task>.pt``, one thread, batch 1, the
precision ``"auto"`` picks) proposes positions for ``--n`` scenes drawn from a seed training never
used; the mission's refiner (``[refine]`` of ``configs/tasks/<task>.toml``) turns them into a
placement that obeys the mission's rules (AGP, FP: every witness seen), and the expert solves the
same scene from scratch. Printed per task: median and p95 times of the refinement alone, of the whole
refined pipeline (network, peaks, refinement) and of the expert; the expert / refinement ratios
(issue 15's goal: >= 10x at the median); placements' size against the expert's (goal for AGP and FP:
<= 1.05x) and QoS relative to the expert's (goal: 100 % for AGP and FP, >= 99 % for Wi-Fi).

Usage: python benchmarks/learning/refine.py [--n-buildings 200] [--n-crowds 60]
       [--tasks agp fp wifi-s1 wifi-s2]
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np
import torch

from learning.checkpoint import load_checkpoint
from learning.inference import utility_maps
from learning.peaks import find_peaks
from learning.precision import cpu_flags, resolve_precision
from uav_swarm.missions.registry import build_refiner, build_task, load_settings
from uav_swarm.planning.planner import default_checkpoint

SEED = 20261201
"""Scene seed: not a dataset seed of any shipped checkpoint (their sample seeds come from 1 and 2)."""


def _run(task_name: str, n: int) -> dict[str, float]:
    settings = load_settings(task_name, f"configs/tasks/{task_name}.toml")
    checkpoint = load_checkpoint(default_checkpoint(task_name))
    task = build_task(task_name, checkpoint.task_config)
    refiner = build_refiner(task, settings.refine)
    precision = resolve_precision("auto", next(checkpoint.model.parameters()).device)
    rng = np.random.default_rng(SEED)
    refine_ms, pipeline_ms, expert_ms, sizes, qos = [], [], [], np.zeros(2), np.zeros(2)
    utility_maps(checkpoint.model, task.observe(task.sample(rng))[None], precision)  # warm-up
    for _ in range(n):
        scene = task.sample(rng)
        start = time.perf_counter()
        utility = utility_maps(checkpoint.model, task.observe(scene)[None], precision)[0]
        proposals = find_peaks(utility, checkpoint.peak_config)
        middle = time.perf_counter()
        refined = refiner.refine(scene, proposals)
        end = time.perf_counter()
        expert = refiner.solve(scene)
        expert_ms.append((time.perf_counter() - end) * 1e3)
        refine_ms.append((end - middle) * 1e3)
        pipeline_ms.append((end - start) * 1e3)
        sizes += [len(refined), len(expert)]
        qos += [task.qos(scene, refined)["qos"], task.qos(scene, expert)["qos"]]
    med = {name: float(np.median(v)) for name, v in
           (("refine", refine_ms), ("pipeline", pipeline_ms), ("expert", expert_ms))}
    p95 = {name: float(np.percentile(v, 95)) for name, v in
           (("refine", refine_ms), ("pipeline", pipeline_ms), ("expert", expert_ms))}
    return {"n": n, "precision": precision, **{f"{k}_median_ms": v for k, v in med.items()},
            **{f"{k}_p95_ms": v for k, v in p95.items()},
            "expert_over_refine": med["expert"] / med["refine"],
            "expert_over_pipeline": med["expert"] / med["pipeline"],
            "size_vs_expert": sizes[0] / sizes[1], "qos_relative": qos[0] / qos[1]}


def main() -> None:
    """Run the benchmark and print one row per task."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n-buildings", type=int, default=200, help="scenes per monitoring task")
    parser.add_argument("--n-crowds", type=int, default=60, help="scenes per Wi-Fi task")
    parser.add_argument("--tasks", nargs="+", default=["agp", "fp", "wifi-s1", "wifi-s2"])
    args = parser.parse_args()
    torch.set_num_threads(1)
    flags = sorted(cpu_flags() & {"avx512_bf16", "amx_bf16", "amx_tile"})
    print(f"CPU: {platform.processor() or platform.machine()}, bfloat16 flags: {flags or 'none'}; "
          "torch threads 1")
    print("| task | scenes | refinement alone, median / p95 ms "
          "| network + peaks + refinement, median / p95 ms "
          "| expert, median / p95 ms | expert / refinement | expert / whole pipeline "
          "| placement size vs expert | QoS rel. to expert |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name in args.tasks:
        n = args.n_buildings if name in ("agp", "fp") else args.n_crowds
        r = _run(name, n)
        print(f"| {name} | {r['n']} | {r['refine_median_ms']:.2f} / {r['refine_p95_ms']:.2f} "
              f"| {r['pipeline_median_ms']:.2f} / {r['pipeline_p95_ms']:.2f} "
              f"| {r['expert_median_ms']:.1f} / {r['expert_p95_ms']:.1f} | {r['expert_over_refine']:.1f}x "
              f"| {r['expert_over_pipeline']:.1f}x | {r['size_vs_expert']:.3f}x "
              f"| {100 * r['qos_relative']:.1f} % |")


if __name__ == "__main__":
    main()
