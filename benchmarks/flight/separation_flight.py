"""Does the flying swarm keep its distance? An independent judge of separation in flight.

For each seed and strategy a user's loop is flown through the public API alone: ``parallel_env`` in
waypoint mode, ``make_planner`` with the shipped configs (strategy 1: ``SimulateConfig()``; strategy 2:
``configs/simulate/wifi-s2-refined.toml``, admission control and planning in motion), replanning every
``replan_every`` steps for ``--duration`` seconds. The judge is scipy's ``pdist`` on ``env.uav_positions_m``
at every step after the first replan (3-D with the config's altitude layers), nothing of the project's
separation code: the closest pair, the conflicts (a pair entering below the minimum), the share of steps
with a pair under the minimum and under 3 m, and the flown QoS.

Usage: python benchmarks/flight/separation_flight.py [--seeds 21 22 23] [--strategies 1 2] [--duration 120]
       [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np
from scipy.spatial.distance import pdist, squareform

from typed_config import load_toml
from uav_swarm.env import parallel_env
from uav_swarm.missions.wifi.task import WifiConfig
from uav_swarm.planning.planner import make_planner
from uav_swarm.runs.simulate_config import SimulateConfig

REPO = Path(__file__).resolve().parents[2]


def shipped_config(strategy: int, seed: int, duration_s: float) -> SimulateConfig:
    """The sequence a user flies for ``strategy`` with the shipped configs."""
    config = (load_toml(SimulateConfig, REPO / "configs" / "simulate" / "wifi-s2-refined.toml")
              if strategy == 2 else SimulateConfig(task=WifiConfig()))  # the paper's radio, as measured
    return config.replace(seed=seed, duration_s=duration_s, gif=False, publish_telemetry=False,
                          compare_expert=False)


def judge(config: SimulateConfig) -> dict[str, float | int | list[int] | None]:
    """Fly ``config``'s sequence with its planner and judge the UAVs' real positions at every step."""
    env = parallel_env(config=config.env_config())
    env.reset(seed=config.seed)
    planner = make_planner(config.planner, config.n_uavs, config.task, checkpoint=config.checkpoint or None,
                           config=config.planning, uav_config=config.uav)
    planner.reset()
    altitudes = config.uav.alt_m + config.uav.layer_step_m * np.arange(config.n_uavs)
    minimum = config.uav.min_separation_m
    agents = list(env.possible_agents)
    targets = np.array(env.uav_positions_m)
    closest, closest_pair, closest_t_s = np.inf, None, None
    below_before = np.zeros((config.n_uavs, config.n_uavs), dtype=bool)
    conflicts = steps_below = steps_below_3m = 0
    target_gap = np.inf
    qos = []
    for step in range(config.n_steps):
        if step % config.replan_every == 0:
            targets = planner.plan(env.pedestrian_positions_m, env.uav_positions_m,
                                   env.pedestrian_velocities_m_s).targets_m
            target_gap = min(target_gap, float(pdist(np.column_stack([targets, altitudes])).min()))
        env.step(dict(zip(agents, targets, strict=True)))
        distances = squareform(pdist(np.column_stack([np.asarray(env.uav_positions_m), altitudes])))
        np.fill_diagonal(distances, np.inf)
        below = distances < minimum
        conflicts += int(np.count_nonzero(np.triu(below & ~below_before)))
        below_before = below
        steps_below += int(below.any())
        steps_below_3m += int((distances < 3.0).any())
        if distances.min() < closest:
            i, j = np.unravel_index(int(np.argmin(distances)), distances.shape)
            closest, closest_pair = float(distances[i, j]), [int(i), int(j)]
            closest_t_s = round((step + 1) * env.dt_s, 2)
        qos.append(env.coverage.qos_s1 if config.task.strategy == 1 else env.coverage.qos_s2)
    return {"min_separation_m": minimum, "closest_m": round(closest, 3), "closest_pair": closest_pair,
            "closest_t_s": closest_t_s, "conflicts": conflicts, "steps": config.n_steps,
            "steps_below_min": steps_below, "steps_below_3m": steps_below_3m,
            "closest_targets_m": round(target_gap, 3), "mean_qos": round(float(np.mean(qos)), 4)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[21, 22, 23])
    parser.add_argument("--strategies", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--duration", type=float, default=120.0)
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    rows = []
    for strategy in args.strategies:
        for seed in args.seeds:
            started = time.perf_counter()
            row = {"strategy": strategy, "seed": seed, **judge(shipped_config(strategy, seed, args.duration))}
            row["wall_s"] = round(time.perf_counter() - started, 1)
            rows.append(row)
            print(json.dumps(row), flush=True)
    report = {"machine": platform.processor() or platform.machine(), "cpus": os.cpu_count(),
              "load_average": os.getloadavg(), "duration_s": args.duration, "rows": rows}
    if args.json is not None:
        args.json.write_text(json.dumps(report, indent=2) + "\n")
    print(f"load average {os.getloadavg()}")


if __name__ == "__main__":
    main()
