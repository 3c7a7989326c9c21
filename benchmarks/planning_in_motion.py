"""What the flying swarm delivers: planning in motion against the snapshot planner (issue 25's table).

For each seed and strategy, a ``uav-swarm simulate`` sequence (10 UAVs, ``--duration`` seconds,
replanning every second) is flown by each planner (learned, expert) in each mode (motion, the
default; snapshot, the behaviour before planning in motion) through the public API
(``run_sequence``, ``make_planner``); strategy 2 uses ``configs/simulate/wifi-s2-refined.toml``.
Every row is judged on the UAVs' real positions with the paper's radio model:

- flown QoS: the strategy's QoS averaged over every step;
- static reference: every 10 s the expert's placement of that instant's crowd judged as if reached
  (strategy 2: the better of the group and the search expert), the same crowd for every row of a seed;
- flown / static, target jumps (> 5 m) per replan, metres flown per UAV-minute, median replan latency.

Usage: python benchmarks/planning_in_motion.py [--seeds 0 1 2 3 4] [--strategies 1 2] [--duration 180]
       [--planners learned expert] [--modes motion snapshot] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

from typed_config import load_toml
from uav_swarm.planning.planner import make_planner
from uav_swarm.runs.service import static_reference
from uav_swarm.runs.simulate import run_sequence, sequence_crowds, summarise_run
from uav_swarm.runs.simulate_config import SimulateConfig

REPO = Path(__file__).resolve().parents[1]


def sequence_config(strategy: int, seed: int, duration_s: float) -> SimulateConfig:
    """The sequence a user would fly for ``strategy`` (strategy 2: the shipped refined config)."""
    config = (load_toml(SimulateConfig, REPO / "configs" / "simulate" / "wifi-s2-refined.toml")
              if strategy == 2 else SimulateConfig())
    return config.replace(seed=seed, duration_s=duration_s, gif=False, publish_telemetry=False,
                          compare_expert=False)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    parser.add_argument("--strategies", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--planners", nargs="+", default=["learned", "expert"])
    parser.add_argument("--modes", nargs="+", default=["motion", "snapshot"])
    parser.add_argument("--duration", type=float, default=180.0)
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs; "
          f"load average at start {os.getloadavg()}")
    rows = []
    for strategy in args.strategies:
        for seed in args.seeds:
            config = sequence_config(strategy, seed, args.duration)
            reference = static_reference(sequence_crowds(config, config.static_every_s), config.task,
                                         config.n_uavs, config.static_every_s)
            for planner_kind in args.planners:
                for mode in args.modes:
                    run_config = config.replace(planning=config.planning.replace(mode=mode))
                    planner = make_planner(planner_kind, run_config.n_uavs, run_config.task,
                                           checkpoint=run_config.checkpoint or None,
                                           config=run_config.planning, uav_config=run_config.uav)
                    start = time.perf_counter()
                    run = run_sequence(run_config, planner, planner_kind)
                    row = {**summarise_run(run, run_config, reference), "strategy": strategy, "seed": seed,
                           "kind": planner_kind, "mode": mode, "wall_s": time.perf_counter() - start}
                    rows.append(row)
                    print(f"S{strategy} seed {seed} {planner_kind:7s} {mode:8s} flown {row['flown_qos']:.3f} "
                          f"static {row['static_reference_qos']:.3f} ratio {row['flown_over_static']:.3f} "
                          f"jumps {row['target_jumps_per_replan']:.2f} "
                          f"m/UAV-min {row['metres_per_uav_minute']:.0f} "
                          f"latency {row['median_latency_ms']:.1f} ms", flush=True)
    print(f"\nload average at end {os.getloadavg()}\n")
    print("| strategy | planner | mode | flown QoS | static ref. | flown / static | jumps > 5 m / replan "
          "| m per UAV-minute | median replan (ms) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for strategy in args.strategies:
        for planner_kind in args.planners:
            for mode in args.modes:
                key = (strategy, planner_kind, mode)
                sel = [r for r in rows if (r["strategy"], r["kind"], r["mode"]) == key]
                mean = {k: float(np.mean([r[k] for r in sel])) for k in (
                    "flown_qos", "static_reference_qos", "flown_over_static", "target_jumps_per_replan",
                    "metres_per_uav_minute", "median_latency_ms")}
                print(f"| S{strategy} | {planner_kind} | {mode} | {mean['flown_qos']:.1%} | "
                      f"{mean['static_reference_qos']:.1%} | {mean['flown_over_static']:.1%} | "
                      f"{mean['target_jumps_per_replan']:.2f} | {mean['metres_per_uav_minute']:.0f} | "
                      f"{mean['median_latency_ms']:.1f} |")
    if args.json is not None:
        args.json.write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
