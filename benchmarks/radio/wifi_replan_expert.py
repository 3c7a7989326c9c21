"""The strategy-2 expert as the crowd walks: fresh solves against replans warm-started with a move cost.

For each seed a crowd of the task's scenarios (the test seed namespace, warmed up as the task's scenes
are) walks ``--duration-s`` seconds; every ``--every-s`` seconds the expert places the UAVs for it, once
solving afresh each time (``[task.expert.replan] warm_start = false``, the behaviour before) and once
warm-started from its last placement with a move cost (the default). Per replan: the metres the UAVs
would travel from the last placement (least-total-distance pairs, 50 m per UAV added or removed), the
targets that jump more than 5 m, the users served at that instant (QoS S2 of the crowd, the task's
radio) and the replan's wall time.

Usage: python benchmarks/radio/wifi_replan_expert.py --config configs/tasks/wifi-s2-80211.toml
       [--seeds 20261207 20261208] [--duration-s 30] [--every-s 1] [--out results.jsonl]
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment

from learning.data import sample_seed
from typed_config import load_toml
from uav_swarm.missions.wifi.replan_expert import travel_m
from uav_swarm.missions.wifi.task import WifiConfig, WifiTask
from uav_swarm.missions.wifi.warm_start import replan_expert, served_users
from uav_swarm.world.crowd import CrowdSim
from uav_swarm.world.scenario import random_scenario

JUMP_M = 5.0


def jumps(previous_m: np.ndarray, new_m: np.ndarray) -> int:
    """Targets of ``new_m`` more than 5 m from their least-distance partner, plus the unpaired."""
    if len(previous_m) == 0 or len(new_m) == 0:
        return max(len(previous_m), len(new_m))
    distance = np.linalg.norm(previous_m[:, None, :] - new_m[None, :, :], axis=2)
    rows, cols = linear_sum_assignment(distance)
    return int(np.count_nonzero(distance[rows, cols] > JUMP_M) + abs(len(previous_m) - len(new_m)))


def run(config: WifiConfig, seed: int, duration_s: float, every_s: float, warm: bool) -> dict[str, object]:
    """One walking crowd placed every ``every_s`` seconds by the fresh or the warm expert."""
    replan = config.expert.replan.replace(warm_start=warm)
    task = WifiTask(config.replace(expert=config.expert.replace(replan=replan)))
    rng = np.random.default_rng(sample_seed(seed, "test", 0))
    crowd = CrowdSim(random_scenario(rng, config.scenario), config.crowd, rng)
    crowd.step(int(round(float(rng.uniform(config.warmup_min_s, config.warmup_max_s)) / config.crowd.dt_s)))
    expert = replan_expert(task)
    last = np.zeros((0, 2))
    rows = []
    for step in range(int(duration_s / every_s) + 1):
        users = np.array(crowd.positions_m, np.float64)
        start = time.perf_counter()
        placement = expert.place(users, np.array(crowd.velocities_m_s, np.float64))
        wall_s = time.perf_counter() - start
        rows.append({"t_s": step * every_s, "wall_s": wall_s, "uavs": len(placement),
                     "qos": served_users(task, users, placement) / max(len(users), 1),
                     "travel_m": travel_m(last, placement, 50.0) if step else 0.0,
                     "jumps": jumps(last, placement) if step else 0})
        last = placement
        crowd.step(int(round(every_s / config.crowd.dt_s)))
    later = rows[1:]
    return {"seed": seed, "warm": warm, "users": len(crowd.positions_m),
            "qos": float(np.mean([r["qos"] for r in rows])),
            "travel_m_per_replan": float(np.mean([r["travel_m"] for r in later])),
            "jumps_per_replan": float(np.mean([r["jumps"] for r in later])),
            "median_replan_s": float(np.median([r["wall_s"] for r in later])),
            "p95_replan_s": float(np.percentile([r["wall_s"] for r in later], 95)),
            "fresh_taken": expert.fresh_taken, "rows": rows}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", type=Path, default=Path("configs/tasks/wifi-s2-80211.toml"))
    parser.add_argument("--seeds", type=int, nargs="+", default=[20261207, 20261208])
    parser.add_argument("--duration-s", type=float, default=30.0)
    parser.add_argument("--every-s", type=float, default=1.0)
    parser.add_argument("--modes", nargs="+", choices=["fresh", "warm"], default=["fresh", "warm"])
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    config = load_toml(WifiConfig, args.config, section="task")
    print(f"{args.config}: load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}", flush=True)
    for seed in args.seeds:
        for mode in args.modes:
            result = run(config, seed, args.duration_s, args.every_s, mode == "warm")
            r: dict[str, Any] = result
            print(f"seed {seed} {mode:5s} users {r['users']} QoS {r['qos']:.3f} "
                  f"travel {r['travel_m_per_replan']:.1f} m/replan jumps {r['jumps_per_replan']:.2f} "
                  f"replan median {1000 * r['median_replan_s']:.0f} ms p95 {1000 * r['p95_replan_s']:.0f} ms "
                  f"fresh solves taken {r['fresh_taken']}", flush=True)
            if args.out:
                with args.out.open("a") as handle:
                    handle.write(json.dumps(result) + "\n")
    print(f"load average at the end {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
