"""What limits a monitoring network's QoS: the expert's guards moved by a pixel, and the learned misses.

    python benchmarks/radio/qos_localization.py --task agp --n 300 --seed 20261214 --results RUN/results.json

Part 1 (``--n`` fresh buildings of the ``test`` namespace of ``--seed``): the exact expert's guards, each
moved by a seeded N(0, σ) in x and y (generator ``(seed, scene, σ index)``, kept inside the raster), judged
by the task's exact QoS (the share of buildings fully seen, AGP; fully guarded from outside, FP). The
paper's matching rule counts a guard as found within 6.4 px, so this says how much QoS a placement keeps
whose every guard is "correct" by that rule but off by σ.

Part 2 (``--results``, a ``results.json`` of ``uav-swarm evaluate``): the learned placements split by
what the rule saw: scenes whose every guard was found and nothing extra proposed (corr = precision = 1),
and the rest; for each, the share of scenes and their QoS, and the distances of the matched pairs.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment

from learning.data import sample_seed
from uav_swarm.missions.registry import make_task


def _matched_distances(expert: np.ndarray, predicted: np.ndarray, eps_px: float) -> np.ndarray:
    """Distances of the least-total-distance pairs within ``eps_px`` (the paper's rule)."""
    if len(expert) == 0 or len(predicted) == 0:
        return np.zeros(0)
    distance = np.sqrt(((expert[:, None, :] - predicted[None, :, :]) ** 2).sum(-1))  # (k, m)
    rows, cols = linear_sum_assignment(distance)
    pairs = distance[rows, cols]
    return pairs[pairs <= eps_px]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", choices=("agp", "fp"), required=True)
    parser.add_argument("--config", help="task settings TOML (default: configs/tasks/<task>.toml)")
    parser.add_argument("--n", type=int, default=300, help="fresh buildings for part 1 (0: skip it)")
    parser.add_argument("--seed", type=int, default=20261214)
    parser.add_argument("--sigmas-px", type=float, nargs="+", default=[0.0, 0.5, 1.0, 2.0, 3.0])
    parser.add_argument("--results", help="results.json of uav-swarm evaluate, for part 2")
    args = parser.parse_args()
    if args.n < 0 or any(s < 0 for s in args.sigmas_px):
        parser.error("--n and --sigmas-px must be >= 0")
    root = Path(__file__).resolve().parents[2]
    task = make_task(args.task, args.config or root / "configs" / "tasks" / f"{args.task}.toml")
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs; load average "
          f"before {os.getloadavg()}", flush=True)
    if args.n:
        start = time.perf_counter()
        size = np.array(task.shape[::-1], dtype=np.float64) - 1.0  # (x, y) upper bounds, pixels
        qos = np.zeros((args.n, len(args.sigmas_px)))
        for i in range(args.n):
            scene = task.sample(np.random.default_rng(sample_seed(args.seed, "test", i)))
            expert = task.expert(scene)  # (k, 2) pixels
            for j, sigma in enumerate(args.sigmas_px):
                rng = np.random.default_rng((args.seed, i, j))
                moved = np.clip(expert + rng.normal(0.0, sigma, expert.shape), 0.0, size)
                qos[i, j] = task.qos(scene, moved)["qos"]
        spent_s = time.perf_counter() - start
        print(f"\npart 1: {args.n} buildings of seed {args.seed} (test), {spent_s:.0f} s; "
              f"load average after {os.getloadavg()}\n")
        print("| every expert guard moved by N(0, σ) px | QoS % (share of buildings fully seen) |")
        print("|---|---|")
        for j, sigma in enumerate(args.sigmas_px):
            print(f"| σ = {sigma:g} | {100 * qos[:, j].mean():.1f} |")
    if args.results:
        run = json.loads(Path(args.results).read_text(encoding="utf-8"))
        eps_px = float(run["eps_px"])
        groups: dict[str, list[dict]] = {"every guard found, none extra": [], "the rest": []}
        for s in run["samples"]:
            exact = s["n_matched"] == s["n_expert"] == s["n_predicted"]
            groups["every guard found, none extra" if exact else "the rest"].append(s)
        print(f"\npart 2: {len(run['samples'])} scenes of {args.results}\n")
        print("| learned placements | scenes % | QoS % | matched-pair distance px: median / p90 |")
        print("|---|---|---|---|")
        for name, samples in groups.items():
            if not samples:
                continue
            distances = np.concatenate([_matched_distances(np.array(s["expert"]).reshape(-1, 2),
                                                           np.array(s["predicted"]).reshape(-1, 2), eps_px)
                                        for s in samples])
            spread = (f"{np.median(distances):.2f} / {np.percentile(distances, 90):.2f}" if len(distances)
                      else "-")
            print(f"| {name} | {100 * len(samples) / len(run['samples']):.1f} | "
                  f"{100 * np.mean([s['qos']['qos'] for s in samples]):.1f} | {spread} |")


if __name__ == "__main__":
    main()
