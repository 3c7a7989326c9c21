"""What the flying swarm delivers: planning in motion against the snapshot planner (issue 25's table).

For each seed and strategy, a ``uav-swarm simulate`` sequence (10 UAVs, ``--duration`` seconds,
replanning every second) is flown by each planner (learned, expert) in each mode (motion, the
default; snapshot, the behaviour before planning in motion) through the public API
(``run_sequence``, ``make_planner``); strategy 2 uses ``configs/simulate/wifi-s2-refined.toml``, under
each radio of ``--radios``: ``admission`` (the default of ``simulate``: 40 stations per UAV, the
capacitated expert and the ``wifi-s2-ac`` network) and ``paper`` (``station_limit = "off"``: the group
expert and the ``wifi-s2`` network). Every row is judged on the UAVs' real positions with the radio it flew
under (the row's ``association``):

- flown QoS: the strategy's QoS averaged over every step;
- static reference: every 10 s the expert's placement of that instant's crowd judged as if reached
  (strategy 2 under admission control: the capacitated expert; on the paper's radio the better of the
  group and the search expert), the same crowd for every row of a seed;
- flown / static, target jumps (> 5 m) per replan, metres flown per UAV-minute, median replan latency.

Usage: python benchmarks/learning/planning_in_motion.py [--seeds 0 1 2 3 4] [--strategies 1 2]
       [--duration 180]
       [--planners learned expert] [--modes motion snapshot] [--radios admission paper] [--json out.json]
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
from uav_swarm.missions.wifi.task import WifiConfig
from uav_swarm.planning.planner import make_planner
from uav_swarm.runs.service import static_reference
from uav_swarm.runs.simulate import run_sequence, sequence_crowds
from uav_swarm.runs.simulate_config import SimulateConfig
from uav_swarm.runs.summary import summarise_run

REPO = Path(__file__).resolve().parents[2]


def sequence_config(strategy: int, seed: int, duration_s: float, radio: str = "admission") -> SimulateConfig:
    """The sequence a user would fly for ``strategy`` (strategy 2: the shipped refined config, ``radio``)."""
    config = (load_toml(SimulateConfig, REPO / "configs" / "simulate" / "wifi-s2-refined.toml")
              if strategy == 2 else SimulateConfig(task=WifiConfig()))  # the paper's radio, as measured
    if strategy == 2 and radio == "paper":
        paper = config.task.radio.replace(station_limit="off")
        config = config.replace(task=config.task.replace(radio=paper))
    return config.replace(seed=seed, duration_s=duration_s, gif=False, publish_telemetry=False,
                          compare_expert=False)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    parser.add_argument("--strategies", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--planners", nargs="+", default=["learned", "expert"])
    parser.add_argument("--modes", nargs="+", default=["motion", "snapshot"])
    parser.add_argument("--duration", type=float, default=180.0)
    parser.add_argument("--radios", nargs="+", choices=["admission", "paper"], default=["admission", "paper"],
                        help="strategy 2's radios (strategy 1 always flies the paper's)")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs; "
          f"load average at start {os.getloadavg()}")
    rows = []
    cases = [(strategy, radio) for strategy in args.strategies
             for radio in (args.radios if strategy == 2 else ["paper"])]
    for strategy, radio in cases:
        for seed in args.seeds:
            config = sequence_config(strategy, seed, args.duration, radio)
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
                           "kind": planner_kind, "mode": mode, "radio": radio,
                           "wall_s": time.perf_counter() - start}
                    rows.append(row)
                    print(f"S{strategy} {radio:9s} seed {seed} {planner_kind:7s} {mode:8s} "
                          f"flown {row['flown_qos']:.3f} "
                          f"static {row['static_reference_qos']:.3f} ratio {row['flown_over_static']:.3f} "
                          f"jumps {row['target_jumps_per_replan']:.2f} "
                          f"m/UAV-min {row['metres_per_uav_minute']:.0f} "
                          f"latency {row['median_latency_ms']:.1f} ms", flush=True)
    print(f"\nload average at end {os.getloadavg()}\n")
    print("| strategy | radio | planner | mode | flown QoS | static ref. | flown / static "
          "| jumps > 5 m / replan | m per UAV-minute | median replan (ms) | S2 on the paper's radio |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for strategy, radio in cases:
        for planner_kind in args.planners:
            for mode in args.modes:
                key = (strategy, radio, planner_kind, mode)
                sel = [r for r in rows if (r["strategy"], r["radio"], r["kind"], r["mode"]) == key]
                paper = [r["mean_qos_s2_paper_radio"] for r in sel if "mean_qos_s2_paper_radio" in r]
                paper_text = f"{np.mean(paper):.1%}" if paper else "-"
                mean = {k: float(np.mean([r[k] for r in sel])) for k in (
                    "flown_qos", "static_reference_qos", "flown_over_static", "target_jumps_per_replan",
                    "metres_per_uav_minute", "median_latency_ms")}
                print(f"| S{strategy} | {radio} | {planner_kind} | {mode} | {mean['flown_qos']:.1%} | "
                      f"{mean['static_reference_qos']:.1%} | {mean['flown_over_static']:.1%} | "
                      f"{mean['target_jumps_per_replan']:.2f} | {mean['metres_per_uav_minute']:.0f} | "
                      f"{mean['median_latency_ms']:.1f} | {paper_text} |")
    if args.json is not None:
        args.json.write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
