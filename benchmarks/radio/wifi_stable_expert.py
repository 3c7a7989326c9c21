"""The stable strategy-2 expert against today's experts: self-agreement under 5 cm of jitter, and QoS.

On ``--n`` held-out crowds (``test`` seed namespace of ``--seed``, as ``uav-swarm expert-stability``
draws them), each expert places up to 10 UAVs on the crowd and on the crowd with every pedestrian
moved by N(0, 5 cm) (generator ``(seed, i)``, as ``expert-stability --probe jitter``); the two
placements are scored against each other by the paper's matching rule (corr, precision, same count),
and the QoS of the first is judged on the crowd (strategy 2). Use one ``--out`` file per setting of
``--copies`` and ``--jitter-m``: the table pools the rows of a file. Radios: the paper's (search against
stable) and admission control (capacitated against stable). Each (radio, expert, scene) row is appended
to ``--out`` (JSON lines) as it is measured, and a rerun skips the rows already there (resumable).

Usage: python benchmarks/radio/wifi_stable_expert.py --n 50 --seed 20261207 --out results/stable.jsonl
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

from learning.data import sample_seed
from learning.metrics import MATCH_FRACTION, score_sample
from uav_swarm.missions.registry import build_task
from uav_swarm.missions.wifi.stable_expert import StableExpertConfig

RADIOS = {"paper": ({}, ("search", "stable")),
          "admission": ({"radio": {"station_limit": "auto"}}, ("capacitated", "stable"))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=50)
    parser.add_argument("--seed", type=int, default=20261207)
    parser.add_argument("--radios", nargs="+", choices=tuple(RADIOS), default=list(RADIOS))
    parser.add_argument("--copies", type=int, default=StableExpertConfig().copies, help="the stable expert's")
    parser.add_argument("--jitter-m", type=float, default=StableExpertConfig().jitter_m,
                        help="the stable expert's")
    parser.add_argument("--out", required=True, help="JSON lines, appended (a rerun resumes)")
    args = parser.parse_args()
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    done = set()
    if out.is_file():
        for line in out.read_text().splitlines():
            row = json.loads(line)
            done.add((row["radio"], row["expert"], row["scene"], row["stable"]["copies"],
                      row["stable"]["jitter_m"]))
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs; "
          f"load average at start {os.getloadavg()}", flush=True)
    for radio in args.radios:
        extra, experts = RADIOS[radio]
        stable = {"copies": args.copies, "jitter_m": args.jitter_m}
        tasks = {m: build_task("wifi-s2", {"strategy": 2, **extra, "expert": {"method": m, "stable": stable}})
                 for m in experts}
        for i in range(args.n):
            for method, task in tasks.items():
                if (radio, method, i, args.copies, args.jitter_m) in done:
                    continue
                scene = task.sample(np.random.default_rng(sample_seed(args.seed, "test", i)))
                moved = task.jitter_scene(scene, np.random.default_rng((args.seed, i)), 0.05)  # type: ignore[attr-defined]
                start = time.perf_counter()
                placement = task.expert(scene)
                solve_ms = (time.perf_counter() - start) * 1e3
                other = task.expert(moved)
                score = score_sample(placement, other, MATCH_FRACTION * task.mission_dimension_px)
                row = {"radio": radio, "expert": method, "scene": i, "seed": args.seed, "corr": score.corr,
                       "precision": score.precision, "same_count": len(placement) == len(other),
                       "qos": task.qos(scene, placement)["qos"], "solve_ms": solve_ms,
                       "load": os.getloadavg()[0], "stable": stable}
                with out.open("a") as f:
                    f.write(json.dumps(row) + "\n")
    summarise(out)


def summarise(path: Path) -> None:
    """Print the table of the rows in ``path``: per radio and expert, means over the scenes measured."""
    rows = [json.loads(line) for line in path.read_text().splitlines()]
    print("| radio | expert | scenes | jitter 5 cm corr % | precision % | same count % | QoS S2 % "
          "| QoS / reference | median solve ms | load (1 min) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for radio, (_, experts) in RADIOS.items():
        common = set.intersection(*({r["scene"] for r in rows if (r["radio"], r["expert"]) == (radio, m)}
                                    for m in experts))
        if not common:
            continue
        picked = {m: [r for r in rows if (r["radio"], r["expert"]) == (radio, m) and r["scene"] in common]
                  for m in experts}
        reference = float(np.mean([r["qos"] for r in picked[experts[0]]]))
        for method, mine in picked.items():
            qos = float(np.mean([r["qos"] for r in mine]))
            loads = [r["load"] for r in mine]
            print(f"| {radio} | {method} | {len(mine)} | {100 * np.mean([r['corr'] for r in mine]):.1f} "
                  f"| {100 * np.mean([r['precision'] for r in mine]):.1f} "
                  f"| {100 * np.mean([r['same_count'] for r in mine]):.1f} | {100 * qos:.1f} "
                  f"| {qos / reference:.3f} | {np.median([r['solve_ms'] for r in mine]):.0f} "
                  f"| {min(loads):.1f}-{max(loads):.1f} |")


if __name__ == "__main__":
    main()
