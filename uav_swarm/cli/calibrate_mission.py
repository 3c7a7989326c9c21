r"""``uav-swarm calibrate-mission``: choose a checkpoint's peak settings for its mission's QoS.

Example::

    uav-swarm calibrate-mission --task agp --out results/agp/operating-points \\
        --write-checkpoint uav_swarm/checkpoints/agp.pt

Scores a grid of peak settings on the checkpoint's validation split (regenerated from the seeds of
its training dataset and cached in ``--out``, so a killed run resumes), chooses the mission point
(:mod:`learning.mission_calibration`: the highest QoS with correspondence and precision at least the
paper's figures, or the balanced point's where those are lower, each less a margin of ``--margin-z``
standard errors, and among those the point that promises the most of the paper's columns) and writes
``calibration.json`` and ``front.md`` (QoS against precision, with the columns each point promises)
into ``--out``. With ``--write-checkpoint`` the checkpoint is
written there (atomically) carrying both operating points; ``evaluate``, ``place`` and the planner
then run the mission point unless asked for ``--operating-point balanced``.
"""

from __future__ import annotations

import argparse
from typing import Any

from uav_swarm.cli.learn import task_choices

__all__ = ["register", "run", "PAPER_ROWS"]

PAPER_ROWS: dict[str, dict[str, float]] = {
    "wifi-s1": {"corr": 0.75, "precision": 0.75, "qos": 1.00},
    "wifi-s2": {"corr": 0.89, "precision": 0.72, "qos": 0.93},
    "agp": {"corr": 0.91, "precision": 0.82, "qos": 0.97},
    "fp": {"corr": 0.86, "precision": 0.78, "qos": 0.90},
}
"""The paper's correspondence, precision and QoS of each task (its results table)."""

def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``calibrate-mission`` subcommand."""
    from uav_swarm.cli.conventions import number, output_flag

    grid = "learning.mission_calibration:MissionGrid."
    parser = subparsers.add_parser(
        "calibrate-mission", help="choose a checkpoint's peak settings for the mission's QoS (validation)",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add = parser.add_argument
    add("--task", required=True, choices=task_choices(), metavar="TASK",
        help="the checkpoint's task: %(choices)s")
    add("--checkpoint", help="the network (default: uav_swarm/checkpoints/<task>.pt)")
    add("--n", type=number(int, ge=1), help="at most this many validation scenes (default: all of the split)")
    output_flag(parser, "--out", "folder", required=True,
                help="folder for calibration.json, front.md and the cached scenes")
    output_flag(parser, "--write-checkpoint", "file",
                help="write the checkpoint with both operating points here (default: not written; it may be "
                     "--checkpoint itself)")
    margin = add("--margin-z", type=number(float, ge=0.0),
                 help="margin of the validation figures, in standard errors of a validation-against-held-out "
                      "difference (0: none)")
    margin.default_from = "learning.mission_calibration:MARGIN_Z"
    for name, what, kind in (("thresholds", "threshold_abs", float), ("contrasts", "min_contrast", float),
                             ("distances-px", "min_distance_px", int),
                             ("regions", "region (any, filled: inside the building, empty: outside)", str)):
        action = add(f"--{name}", type=kind, nargs="+", help=f"{what} values tried")
        action.config_field = grid + name.replace("-", "_")
    parser.set_defaults(func=run)


def _pct(row: dict[str, Any], key: str) -> str:
    return f"{100 * row[key]:.1f}"


def front_table(report: dict[str, Any]) -> str:
    """The front of QoS against precision, the balanced and mission points marked, as markdown."""
    from learning.mission_calibration import margins, promised_columns

    lines = [f"{report['task']}: {report['n_validation']} validation scenes; floors corr "
             f"{_pct(report['floors'], 'corr')} %, precision {_pct(report['floors'], 'precision')} % "
             f"(paper {_pct(report['paper'], 'corr')} / {_pct(report['paper'], 'precision')}); margin "
             f"{report['margin_z']} standard errors", "",
             "| point | threshold_abs | min_contrast | min_distance_px | region | corr % | precision % "
             "| QoS % | QoS rel. % | margins corr / precision / QoS rel., points | promises |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    named = [("balanced", report["balanced"]), ("mission", report["mission"])]
    for name, row in named + [("front", row) for row in report["front"]]:
        margin = margins(row, report["margin_z"])
        promises = ", ".join(promised_columns(row, report["paper"], report["margin_z"])) or "none"
        lines.append(f"| {name} | {row['threshold_abs']} | {row['min_contrast']} | {row['min_distance_px']} "
                     f"| {row.get('region', 'any')} | {_pct(row, 'corr')} | {_pct(row, 'precision')} "
                     f"| {_pct(row, 'qos')} "
                     f"| {_pct(row, 'qos_relative')} | {' / '.join(_pct(margin, k) for k in margin)} "
                     f"| {promises} |")
    return "\n".join(lines) + "\n"


def _write_checkpoint(source: str, target: str, report: dict[str, Any]) -> None:
    import torch

    from learning.checkpoint import save_checkpoint
    from learning.peaks import PeakConfig

    payload = torch.load(source, map_location="cpu", weights_only=True)
    mission = report["mission"]
    fields = PeakConfig().to_dict()
    payload["peak_config_mission"] = {key: mission[key] for key in fields}
    kept = ("corr", "precision", "qos", "qos_relative", "margins", "promises")
    payload["mission_calibration"] = {
        "rule": "corr and precision less their margins >= min(paper, balanced point less its margins); "
                "then the most promised columns, then the highest validation QoS",
        "n_validation": report["n_validation"], "paper": report["paper"], "margin_z": report["margin_z"],
        "floors": report["floors"], "balanced": {k: report["balanced"][k] for k in kept},
        "mission": {k: mission[k] for k in kept}}
    save_checkpoint(target, payload)


def run(args: argparse.Namespace) -> int:
    """Calibrate, write the report (and the checkpoint); bad input exits with code 2, nothing written."""
    import sys
    from pathlib import Path

    from learning.checkpoint import CheckpointError, load_checkpoint
    from learning.mission_calibration import MissionGrid, calibrate_mission
    from typed_config import ConfigError
    from typed_config.files import write_json_atomic, write_text_atomic
    from uav_swarm.missions.registry import build_task
    from uav_swarm.planning.planner import default_checkpoint

    try:
        if args.task not in PAPER_ROWS:
            raise ConfigError(f"--task {args.task}: the paper has no row for it; allowed "
                              f"{sorted(PAPER_ROWS)}")
        grids = ("thresholds", "contrasts", "distances_px", "regions")
        given = {name: tuple(getattr(args, name)) for name in grids if getattr(args, name) is not None}
        grid = MissionGrid(**given)
        path = args.checkpoint or str(default_checkpoint(args.task))
        ckpt = load_checkpoint(path, task_name=args.task)
        task = build_task(args.task, ckpt.task_config)
    except (ConfigError, CheckpointError) as exc:
        print(f"uav-swarm calibrate-mission: {exc}", file=sys.stderr)
        return 2
    out = Path(args.out)
    report = calibrate_mission(ckpt, task, PAPER_ROWS[args.task], out / "validation-scenes", n=args.n,
                               grid=grid, **({} if args.margin_z is None else {"margin_z": args.margin_z}))
    write_json_atomic(out / "calibration.json", report)
    table = front_table(report)
    write_text_atomic(out / "front.md", table)
    print(table, end="")
    if args.write_checkpoint:
        _write_checkpoint(path, str(args.write_checkpoint), report)
        print(f"wrote {args.write_checkpoint} with the balanced and mission points")
    return 0
