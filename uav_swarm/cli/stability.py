r"""``uav-swarm expert-stability``: how far an expert agrees with itself (the ceiling of learning from it).

Example::

    uav-swarm expert-stability --task wifi-s2 --config configs/tasks/wifi-s2.toml --probe jitter \
        --scale-m 0.05 --n 200 --seed 3 --out runs/expert-stability/wifi-s2-jitter.json
"""

from __future__ import annotations

import argparse

from uav_swarm.cli.conventions import number, output_flag
from uav_swarm.cli.learn import task_choices

__all__ = ["register", "run"]


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``expert-stability`` subcommand."""
    parser = subparsers.add_parser(
        "expert-stability",
        help="the expert's agreement with itself under grid symmetries or sub-pixel jitter",
        description=__doc__)
    parser.add_argument("--task", required=True, choices=task_choices(), metavar="TASK",
                            help="the task: %(choices)s")
    parser.add_argument("--config", help="task settings TOML (its [task] table is used; default: none)")
    parser.add_argument("--probe", choices=("symmetry", "jitter"), default="symmetry",
                        help="moved scenes: by a grid symmetry, or by a normal jitter (Wi-Fi crowds)")
    parser.add_argument("--scale-m", type=number(float, gt=0.0), default=0.05, dest="scale",
                        help="jitter standard deviation, metres")
    parser.add_argument("--n", type=number(int, ge=1), default=200, help="scenes")
    parser.add_argument("--seed", type=number(int, ge=0), default=3, help="scene seed, test namespace")
    output_flag(parser, "--out", "file", required=True, help="JSON report to write")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Measure and write the report; a probe the task lacks, or a bad number, exits with code 2."""
    import sys
    from pathlib import Path

    from learning.expert_stability import expert_stability
    from typed_config.files import write_json_atomic
    from uav_swarm.missions.registry import make_task

    task = make_task(args.task, args.config)
    try:
        report = expert_stability(task, args.n, args.seed, args.probe, args.scale)
    except ValueError as exc:
        print(f"uav-swarm expert-stability: {exc}", file=sys.stderr)
        return 2
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    write_json_atomic(args.out, report)
    print(f"{args.task}, {args.probe}: corr {100 * report['corr']:.1f} %, precision "
          f"{100 * report['precision']:.1f} %, same count {100 * report['same_count']:.1f} %, QoS "
          f"{100 * report['qos']:.1f} % (the other placement: {100 * report['qos_other']:.1f} %) "
          f"over {args.n} scenes")
    return 0
