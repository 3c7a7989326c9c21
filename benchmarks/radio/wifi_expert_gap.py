"""Optimality gap of the Wi-Fi expert against the exact MILP (HiGHS) on small scenes.

Scenes: clusters of users (Gaussian, 6 m spread) in a small square; the reference is
``uav_swarm.missions.wifi.exact.exact_placement`` over a regular candidate grid, solved to proven
optimality (scenes whose MILP hits the time limit are reported and left out). Gap =
(exact served - expert served) / exact served; negative when the expert, whose positions are not
bound to the grid, serves more. Also prints both solve times.

Usage: python benchmarks/radio/wifi_expert_gap.py [--scenes 8] [--time-limit-s 30]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from uav_swarm.missions.wifi.exact import exact_placement
from uav_swarm.missions.wifi.expert import WifiExpertConfig, place_uavs
from uav_swarm.missions.wifi.rules import assign_users, candidate_grid
from uav_swarm.missions.wifi.task import WifiConfig, coverage_rules

# strategy: (side_m, grid_step_m, clusters, cluster size range, max UAVs)
SETTINGS = {1: (120.0, 5.0, 4, (25, 60), 3), 2: (60.0, 6.0, 2, (32, 45), 2)}


def clustered_users(seed: int, side_m: float, n_clusters: int, sizes: tuple[int, int]) -> np.ndarray:
    """Users in ``n_clusters`` Gaussian clusters inside the square, from ``seed``."""
    rng = np.random.default_rng(seed)
    centres = rng.uniform(10.0, side_m - 10.0, size=(n_clusters, 2))
    users = [c + rng.normal(0.0, 6.0, size=(int(rng.integers(*sizes)), 2)) for c in centres]
    return np.clip(np.concatenate(users), 0.0, side_m)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=8)
    parser.add_argument("--time-limit-s", type=float, default=30.0)
    args = parser.parse_args()
    for strategy, (side, step, clusters, sizes, max_uavs) in SETTINGS.items():
        config = WifiConfig(strategy=strategy, expert=WifiExpertConfig(max_uavs=max_uavs))
        rules = coverage_rules(config)
        candidates = candidate_grid(side, side, step)[0]
        gaps, exact_s, expert_s, unsolved = [], [], [], 0
        for seed in range(args.scenes):
            users = clustered_users(seed, side, clusters, sizes)
            exact = exact_placement(users, rules, candidates, time_limit_s=args.time_limit_s)
            start = time.perf_counter()
            expert = place_uavs(users, rules, side, side, config.expert)
            expert_s.append(time.perf_counter() - start)
            if not exact.optimal:
                unsolved += 1
                continue
            exact_s.append(exact.solve_s)
            served = assign_users(users, expert, rules.radius_m).n_served
            gaps.append((exact.n_served - served) / exact.n_served)
        gap = np.array(gaps)
        print(f"strategy {strategy}: {len(gap)} scenes solved exactly ({unsolved} hit the time limit); "
              f"{clusters} clusters of {sizes[0]}-{sizes[1] - 1} users, {side:g} m square, {max_uavs} UAVs, "
              f"MILP grid {step:g} m")
        if len(gap):
            print(f"  gap: mean {100 * gap.mean():.2f} %, worst {100 * gap.max():.2f} %, "
                  f"zero or better on {int(np.sum(gap <= 0))}/{len(gap)} (goal <= 2 %)")
            print(f"  time: exact median {np.median(exact_s):.2f} s, expert median "
                  f"{1e3 * np.median(expert_s):.1f} ms")


if __name__ == "__main__":
    main()
