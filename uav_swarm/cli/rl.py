"""``uav-swarm rl-train | rl-compare``: MAPPO on ``uav_swarm_v0`` and the baseline table.

Examples::

    uav-swarm rl-train --out runs/mappo --max-minutes 55
    uav-swarm rl-compare --policy runs/mappo/policy.pt --episodes 20 --out runs/marl-compare

``rl-train`` needs the ``marl`` extra (``pip install uav-swarm[marl]``: TorchRL). Settings come
from ``--config`` (a TOML file of :class:`uav_swarm.marl.mappo.MappoConfig` fields) and the flags.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

from uav_swarm.cli.conventions import config_flag, number, run_folder_flag

__all__ = ["register", "run_train", "run_compare"]


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``rl-train`` and ``rl-compare`` subcommands."""
    train = subparsers.add_parser("rl-train", help="train MAPPO (TorchRL) on uav_swarm_v0",
                                  description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    run_folder_flag(train, "--out", resumed_by="resume", required=True, help="output folder")
    train.add_argument("--config", type=Path, help="MappoConfig TOML (default: none, the defaults below)")
    train.add_argument("--resume", action="store_true", help="continue from OUT/checkpoint.pt")
    for flag in ("seed", "num-envs", "total-frames", "frames-per-batch", "max-minutes", "max-cycles",
                 "strategy", "n-uavs", "lr", "torch-threads"):
        config_flag(train, f"--{flag}", f"uav_swarm.marl.mappo:MappoConfig.{flag.replace('-', '_')}")
    train.set_defaults(func=run_train)

    compare = subparsers.add_parser("rl-compare",
                                    help="random, MAPPO, learned and expert on the same episodes",
                                    description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    run_folder_flag(compare, "--out", required=True,
                         help="output folder (comparison.json, comparison.md)")
    compare.add_argument("--policy", type=Path,
                         help="MAPPO policy.pt (written by rl-train; default: none, needed for mappo)")
    compare.add_argument("--controllers", nargs="+", default=["random", "mappo", "learned", "expert"],
                         choices=("random", "mappo", "learned", "expert"), help="controllers to score")
    compare.add_argument("--episodes", type=number(int, ge=1), default=20, help="episodes")
    compare.add_argument("--seed", type=number(int, ge=0), default=100_000, help="first episode's seed")
    compare.add_argument("--duration-s", type=number(float, gt=0.0), default=60.0, help="seconds per episode")
    compare.add_argument("--n-uavs", type=number(int, ge=1, le=10), default=10, help="UAVs")
    compare.add_argument("--checkpoint", type=Path,
                         help="learned planner checkpoint (default: the shipped one for the task)")
    compare.set_defaults(func=run_compare)


def run_train(args: argparse.Namespace) -> int:
    """Train MAPPO; print the summary."""
    from typed_config import load_with_overrides
    from uav_swarm.marl.mappo import MappoConfig, train_mappo

    names = ("seed", "num_envs", "total_frames", "frames_per_batch", "max_minutes", "max_cycles", "strategy",
             "n_uavs", "lr", "torch_threads")
    overrides = {name: getattr(args, name) for name in names if getattr(args, name) is not None}
    config = load_with_overrides(MappoConfig, args.config, overrides)
    summary = train_mappo(config, args.out, resume=args.resume, progress=True)
    print(f"MAPPO: {summary['frames']} world-steps in {summary['elapsed_s'] / 60:.1f} min; mean team reward "
          f"{summary['final_mean_reward']:.3f} (last 10 batches) against {summary['random_reward']:.3f} for "
          f"random actions; wrote {args.out}")
    return 0


def run_compare(args: argparse.Namespace) -> int:
    """Score the controllers; write ``comparison.json`` and ``comparison.md``; print the table."""
    from typed_config.files import write_json_atomic, write_text_atomic
    from uav_swarm.marl.compare import compare_controllers

    try:
        scores = compare_controllers(args.controllers, episodes=args.episodes, seed=args.seed,
                                     duration_s=args.duration_s, n_uavs=args.n_uavs, mappo_policy=args.policy,
                                     checkpoint=args.checkpoint, progress=True)
    except ValueError as exc:
        print(f"uav-swarm rl-compare: {exc}", file=sys.stderr)
        return 2
    lines = ["| controller | QoS S1 % | QoS S2 % | mean throughput (Mbps) | decision time per step (ms) | "
             "per replan (ms) |", "|---|---|---|---|---|---|"]
    for s in scores:
        replan = f"{s.replan_ms:.1f}" if s.replan_ms is not None else "-"
        lines.append(f"| {s.controller} | {100 * s.mean_qos_s1:.1f} | {100 * s.mean_qos_s2:.1f} | "
                     f"{s.mean_throughput_mbps:.2f} | {s.decision_ms_per_step:.3f} | {replan} |")
    table = "\n".join(lines) + "\n"
    args.out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(args.out / "comparison.md", table)
    write_json_atomic(args.out / "comparison.json", {
        "episodes": args.episodes, "seed": args.seed, "duration_s": args.duration_s, "n_uavs": args.n_uavs,
        "policy": str(args.policy) if args.policy else None,
        "scores": [dataclasses.asdict(s) for s in scores]})
    print(table, end="")
    print(json.dumps({"wrote": str(args.out)}))
    return 0
