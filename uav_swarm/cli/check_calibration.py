r"""``uav-swarm calibrate-check``: choose the Wi-Fi rule check's settings on the validation split.

Example::

    uav-swarm calibrate-check --task wifi-s1 --config configs/tasks/wifi-s1.toml \
        --checkpoint uav_swarm/checkpoints/wifi-s1.pt --data runs/wifi-s1/data10000 \
        --out runs/wifi-s1/calibration.json
"""

from __future__ import annotations

import argparse

from uav_swarm.cli.conventions import number, output_flag

__all__ = ["register", "run"]

_THRESHOLDS = (0.05, 0.1, 0.15, 0.2, 0.25, 0.3)
_SLACKS = (0, 2, 4, 6, 8)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``calibrate-check`` subcommand."""
    parser = subparsers.add_parser(
        "calibrate-check",
        help="score the rule check's settings on the validation split and choose them (Wi-Fi)",
        description=__doc__)
    parser.add_argument("--task", required=True, choices=("wifi-s1", "wifi-s2"), help="the Wi-Fi task")
    parser.add_argument("--config", help="task settings TOML (its [task] table is used; default: none)")
    parser.add_argument("--checkpoint", required=True, help="a .pt file trained on --data")
    parser.add_argument("--data", required=True, help="the dataset the checkpoint was trained on")
    parser.add_argument("--thresholds", type=number(float, ge=0.0), nargs="+", default=list(_THRESHOLDS),
                        help="peak thresholds tried (default: %(default)s)")
    parser.add_argument("--slacks", type=number(int, ge=0), nargs="+", default=list(_SLACKS),
                        help="slacks (users) tried (default: %(default)s)")
    parser.add_argument("--qos-floor", type=number(float, gt=0.0, le=1.5), default=0.99,
                        help="least QoS relative to the expert's of a chosen point (default: %(default)s)")
    parser.add_argument("--n", type=number(int, ge=1),
                        help="at most this many validation scenes (default: all)")
    output_flag(parser, "--out", "file", required=True, help="JSON report to write")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Score the grid, print it, write the report; bad input exits with code 2 and writes nothing."""
    import sys
    from pathlib import Path

    from learning.check_calibration import calibrate_check
    from learning.checkpoint import CheckpointError
    from learning.data import DatasetError
    from typed_config import ConfigError
    from typed_config.files import write_json_atomic
    from uav_swarm.missions.registry import build_rule_check, make_task

    task = make_task(args.task, args.config)
    grid = [{"threshold_abs": t, "slack_users": s} for t in args.thresholds for s in args.slacks]
    try:
        for settings in grid:  # every point valid before any work
            build_rule_check(task, settings)
        report = calibrate_check(args.checkpoint, task, args.data, lambda s: build_rule_check(task, s), grid,
                                 qos_floor=args.qos_floor, n=args.n)
    except (ValueError, TypeError, ConfigError, CheckpointError, DatasetError) as exc:
        print(f"uav-swarm calibrate-check: {exc}", file=sys.stderr)
        return 2
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    write_json_atomic(args.out, report)
    print(f"{args.task}: {report['n_validation']} validation scenes, "
          f"expert QoS {100 * report['expert_qos']:.1f} %")
    print("| threshold | slack | corr % | precision % | QoS rel. % |\n|---|---|---|---|---|")
    base = report["unchecked"]
    print(f"| {base['threshold_abs']} (no check) | - | {100 * base['corr']:.1f} | "
          f"{100 * base['precision']:.1f} | {100 * base['qos_relative']:.1f} |")
    for row in report["rows"]:
        mark = " **chosen**" if row is report["chosen"] else ""
        print(f"| {row['threshold_abs']} | {row['slack_users']} | {100 * row['corr']:.1f} | "
              f"{100 * row['precision']:.1f} | {100 * row['qos_relative']:.1f} |{mark}")
    chosen = report["chosen"]
    print(f"[rule_check]\nthreshold_abs = {chosen['threshold_abs']}\nslack_users = {chosen['slack_users']}")
    return 0
