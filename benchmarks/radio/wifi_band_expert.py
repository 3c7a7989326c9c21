"""A strategy-2 expert chosen with a tie band: a canonical layout unless the search beats it clearly.

Strategy 2 on the paper's radio has two experts at the ends of one front: the search expert (more users
served, a layout that flips under 5 cm of jitter) and the group expert at rest (a canonical layout built
from the crowd's walking groups, fewer users). The *band* expert places the search's layout and a
canonical one on the crowd and keeps the search's only when it serves more than ``band`` x the crowd users
more (``--bands``); otherwise the canonical one. Two canonical layouts are judged: ``groups``, the group
expert's, and ``adopted``, the group expert's made valid and improved by the search's local steps
(:func:`uav_swarm.missions.wifi.expert.adopt_placement`: repair, centring, greedy fill of spare UAVs).
The choice flips under jitter only where the QoS gap between the two moves across the band.

On ``--n`` held-out crowds (``test`` seed namespace of ``--seed``) and their copies with every pedestrian
moved by N(0, 5 cm) (generator ``(seed, i)``: the scenes of ``uav-swarm expert-stability --probe jitter``),
the experts are solved once on each; every band is then judged from the same solves: self-agreement by
the paper's matching rule (corr, precision) between the band expert's choice on the crowd and on its copy,
and its QoS S2 on the crowd. One JSON line per crowd is appended to ``--out`` (a rerun skips crowds there).

Usage: python benchmarks/radio/wifi_band_expert.py --n 12 --seed 777001 --out results/band.jsonl
(``--pool`` other runs' files to pool their crowds in the table; the QoS reference is the search's.)
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
from typing import cast

import numpy as np

from learning.data import sample_seed
from learning.metrics import MATCH_FRACTION, score_sample
from uav_swarm.missions.registry import build_task
from uav_swarm.missions.wifi.expert import adopt_placement
from uav_swarm.missions.wifi.task import WifiTask

EXPERTS = ("search", "groups")
CANONICAL = ("groups", "adopted")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=12)
    parser.add_argument("--seed", type=int, default=777001)
    parser.add_argument("--bands", type=float, nargs="+",
                        default=[-1.0, 0.0, 0.02, 0.04, 0.06, 0.08, 0.1, 0.15, 0.2, 1.0],
                        help="shares of the crowd; 1.0 is the group expert, a negative band the search")
    parser.add_argument("--out", required=True, help="JSON lines, appended (a rerun resumes)")
    parser.add_argument("--pool", nargs="*", default=[], help="other runs' --out files, pooled in the table")
    args = parser.parse_args()
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    done = {json.loads(line)["scene"] for line in out.read_text().splitlines()} if out.is_file() else set()
    tasks = {m: cast(WifiTask, build_task("wifi-s2", {"strategy": 2, "expert": {"method": m}}))
             for m in EXPERTS}
    for i in range(args.n):
        if i in done:
            continue
        task = tasks["search"]
        scene = task.sample(np.random.default_rng(sample_seed(args.seed, "test", i)))
        moved = task.jitter_scene(scene, np.random.default_rng((args.seed, i)), 0.05)
        row: dict[str, object] = {"scene": i, "seed": args.seed, "users": len(scene.users_m)}
        placed: dict[str, dict[str, np.ndarray]] = {}
        for method, each in tasks.items():
            # The group expert at rest: no velocities (the crowd of now, not of the next second).
            placed[method] = {"crowd": each.expert_placement_m(scene.users_m),
                              "moved": each.expert_placement_m(moved.users_m)}
        placed["adopted"] = {which: adopt_placement(crowd.users_m, placed["groups"][which], task.rules,
                                                    task.width_m, task.height_m, task.config.expert)
                             for which, crowd in (("crowd", scene), ("moved", moved))}
        for method, both in placed.items():
            on_crowd, on_moved = task.to_pixels(both["crowd"]), task.to_pixels(both["moved"])
            row[method] = {"crowd": on_crowd.tolist(), "moved": on_moved.tolist(),
                           "qos": task.qos(scene, on_crowd)["qos"],
                           "qos_moved": task.qos(moved, on_moved)["qos"]}
        row["load"] = os.getloadavg()[0]
        with out.open("a") as f:
            f.write(json.dumps(row) + "\n")
        print(f"crowd {i}: {row['users']} users, load {row['load']:.1f}", flush=True)
    eps_px = MATCH_FRACTION * tasks["search"].mission_dimension_px
    for canonical in CANONICAL:
        summarise([out, *map(Path, args.pool)], args.bands, eps_px, canonical)


def _choice(row: dict, which: str, band: float, canonical: str) -> tuple[np.ndarray, float]:
    """The band expert's placement on the crowd (``which = "crowd"``) or its copy, and its QoS there."""
    qos_key = "qos" if which == "crowd" else "qos_moved"
    search, other = row["search"], row[canonical]
    pick = search if search[qos_key] - other[qos_key] > band else other
    return np.asarray(pick[which], np.float64).reshape(-1, 2), float(pick[qos_key])


def summarise(paths: list[Path], bands: list[float], eps_px: float, canonical: str) -> None:
    """Print, per band, the mean self-agreement and QoS S2 over the crowds in ``paths``."""
    rows = [json.loads(line) for path in paths for line in path.read_text().splitlines()]
    seeds = sorted({r["seed"] for r in rows})
    loads = [r["load"] for r in rows]
    reference = float(np.mean([r["search"]["qos"] for r in rows]))
    print(f"canonical layout: {canonical}; {len(rows)} crowds of seed(s) {seeds}, "
          f"load average {min(loads):.1f}-{max(loads):.1f}")
    print("| band (share of the crowd) | search chosen % | jitter 5 cm corr % | precision % | QoS S2 % "
          "| QoS / search |")
    print("|---|---|---|---|---|---|")
    for band in bands:
        scores, qos, chosen = [], [], []
        for row in rows:
            a, q = _choice(row, "crowd", band, canonical)
            b, _ = _choice(row, "moved", band, canonical)
            scores.append(score_sample(a, b, eps_px))
            qos.append(q)
            chosen.append(row["search"]["qos"] - row[canonical]["qos"] > band)
        mean_qos = float(np.mean(qos))
        print(f"| {band:g} | {100 * np.mean(chosen):.0f} | {100 * np.mean([s.corr for s in scores]):.1f} "
              f"| {100 * np.mean([s.precision for s in scores]):.1f} | {100 * mean_qos:.1f} "
              f"| {mean_qos / reference:.3f} |")


if __name__ == "__main__":
    main()
