"""Exact Art Gallery / Fortress expert: visibility-matrix and set-cover times per polygon.

Draws ``--n`` random buildings (the default ``PolygonConfig``: 64 px raster, 6-20 vertices),
builds both discretised instances and solves them exactly, timing the visibility matrix and
the set cover separately. The reference is a plain ``scipy.optimize.milp`` on the unreduced
instance (count only, no tie-break) on the first ``--n-reference`` polygons, and the goal
median of 0.5 s per polygon. Also prints the distribution of optimal guard counts.

Usage: python benchmarks/learning/expert_solve.py [--n 50] [--n-reference 10] [--seed 0]
"""

from __future__ import annotations

import argparse
import time
from collections import Counter

import numpy as np
from scipy.optimize import Bounds, LinearConstraint, milp
from scipy.sparse import csr_array

from uav_swarm.missions.monitoring.guards import art_gallery_problem, fortress_problem, solve_guards
from uav_swarm.missions.monitoring.polygons import PolygonConfig, random_polygon
from uav_swarm.missions.monitoring.setcover import InfeasibleCoverError

GOAL_S = 0.5


def plain_milp_s(visibility: np.ndarray) -> tuple[float, int]:
    """Seconds and optimum of HiGHS on the unreduced cover matrix (witnesses x candidates)."""
    cover = csr_array(visibility.T.astype(np.float64))
    start = time.perf_counter()
    result = milp(np.ones(cover.shape[1]), integrality=np.ones(cover.shape[1]), bounds=Bounds(0, 1),
                  constraints=[LinearConstraint(cover, lb=1, ub=np.inf)])
    return time.perf_counter() - start, int(round(result.fun))


def stats(values: list[float]) -> str:
    a = np.asarray(values)
    median, p95, top = np.median(a) * 1e3, np.percentile(a, 95) * 1e3, a.max() * 1e3
    return f"median {median:7.1f} ms   p95 {p95:7.1f} ms   max {top:7.1f} ms"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=50)
    parser.add_argument("--n-reference", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    config = PolygonConfig()
    builders = {"AGP": art_gallery_problem, "FP": fortress_problem}
    times = {name: {"visibility": [], "cover": [], "total": [], "reference": [], "ours_on_ref": []}
             for name in builders}
    counts = {name: Counter() for name in builders}
    shapes = {name: [] for name in builders}
    infeasible = Counter()
    for i in range(args.n):
        polygon = random_polygon(np.random.default_rng([args.seed, i]), config)
        for name, build in builders.items():
            start = time.perf_counter()
            problem = build(polygon)
            built = time.perf_counter()
            try:
                chosen = solve_guards(problem)
            except InfeasibleCoverError:
                infeasible[name] += 1
                continue
            done = time.perf_counter()
            t = times[name]
            t["visibility"].append(built - start)
            t["cover"].append(done - built)
            t["total"].append(done - start)
            counts[name][len(chosen)] += 1
            shapes[name].append(problem.visibility.size)
            if i < args.n_reference:
                seconds, optimum = plain_milp_s(problem.visibility)
                if optimum != len(chosen):
                    raise SystemExit(f"{name} polygon {i}: reference optimum {optimum} != ours {len(chosen)}")
                t["reference"].append(seconds)
                t["ours_on_ref"].append(done - built)
    print(f"{args.n} polygons, PolygonConfig defaults ({config.min_vertices}-{config.max_vertices} vertices, "
          f"{config.size_px} px, margin {config.margin_px} px), seed {args.seed}")
    for name, t in times.items():
        pairs = np.median(shapes[name])
        print(f"\n{name}: {len(t['total'])} solved, {infeasible[name]} infeasible on the pixel grid")
        print(f"  visibility matrix  {stats(t['visibility'])}   (median {pairs / 1e6:.2f} M pairs, "
              f"{pairs / np.median(t['visibility']) / 1e6:.1f} M pairs/s)")
        print(f"  set cover (2 MILP) {stats(t['cover'])}")
        print(f"  expert total       {stats(t['total'])}")
        print(f"  goal median {GOAL_S:.1f} s: median / goal = {np.median(t['total']) / GOAL_S:.2f}")
        if t["reference"]:
            ratio = np.median(t["reference"]) / np.median(t["ours_on_ref"])
            print(f"  reference: plain milp, unreduced matrix, count only (first {len(t['reference'])}): "
                  f"{stats(t['reference'])}")
            print(f"  reference / ours (reduced, count + tie-break) = {ratio:.1f}x")
        total = sum(counts[name].values())
        dist = "  ".join(f"{k}: {v} ({100 * v / total:.0f} %)" for k, v in sorted(counts[name].items()))
        print(f"  optimal guard counts: {dist}")


if __name__ == "__main__":
    main()
