r"""``uav-swarm search``: the (α2, σ2) grid search of the target's wide Gaussian for one task.

Examples::

    uav-swarm dataset --task agp --n 1000 --seed 1 --out runs/agp/data
    uav-swarm search --task agp --data runs/agp/data --out runs/agp/search --alpha2 20:60:20 \
        --sigma2 5:45:20 --epochs 5
    uav-swarm search --task wifi-s1 --n 1000 --seed 1 --data runs/s1/data --out runs/s1/search \
        --epochs 5 --executor ray --address ray://head:10001

The dataset is ``--data``: an existing ``uav-swarm dataset`` folder, or, when ``--n`` is
given, generated (or finished, resumably) there first with ``--seed``. Model, training
and peak settings come from the task's settings (``--config``) with the options given
here replacing them; ``[targets]`` gives α1 and σ1. Outputs in ``--out``: ``search.json``
(resumable: run the same command again after a kill), ``summary.json``, ``summary.md``
and ``heatmap.png``. The default grid, α2 20:60:10 by σ2 5:45:10 px, is the one of the
README's Wi-Fi searches. Without ``--address``, ``--executor ray`` starts a private Ray
instance on 127.0.0.1 (no dashboard, no usage reporting); ``--address`` joins a cluster.
"""

from __future__ import annotations

import argparse
import sys

from uav_swarm.cli.conventions import config_flag, number, output_flag
from uav_swarm.cli.learn import task_choices

__all__ = ["register", "run"]


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``search`` subcommand."""
    grid, train_cfg = "learning.search_grid:SearchConfig.", "learning.train:TrainConfig."
    parser = subparsers.add_parser("search", help="grid search of the target's (alpha2, sigma2) (resumable)",
                                   description=__doc__)
    parser.add_argument("--task", required=True, choices=task_choices(), metavar="TASK",
                            help="the task: %(choices)s")
    parser.add_argument("--config", help="task settings TOML (tables task, targets, model, train, peaks; "
                        "default: none, the task's defaults)")
    parser.add_argument("--data", required=True, help="dataset folder (generated there when --n is given)")
    output_flag(parser, "--out", "folder", required=True, help="search output folder")
    parser.add_argument("--n", type=number(int, ge=1),
                        help="generate (or finish) a dataset of this many scenes in --data (default: none, "
                        "--data exists)")
    parser.add_argument("--seed", type=number(int, ge=0), default=0, help="dataset seed with --n")
    config_flag(parser, "--alpha2", grid + "alpha2", key="")
    config_flag(parser, "--sigma2", grid + "sigma2", key="")
    config_flag(parser, "--epochs", train_cfg + "epochs", help="epochs per trial", key="[train] epochs")
    config_flag(parser, "--max-steps", train_cfg + "max_steps", help="optimiser steps per trial",
                key="[train] max_steps")
    config_flag(parser, "--batch-size", train_cfg + "batch_size", key="[train] batch_size")
    config_flag(parser, "--lr", train_cfg + "lr", key="[train] lr")
    config_flag(parser, "--device", train_cfg + "device", choices=("auto", "cpu", "cuda"),
                key="[train] device")
    config_flag(parser, "--torch-threads", grid + "threads", key="")
    parser.add_argument("--executor", choices=("local", "ray"), default="local", help="where trials run")
    parser.add_argument("--address", help="Ray cluster to join (with --executor ray), e.g. ray://head:10001 "
                                          "or auto; default: a local instance on 127.0.0.1")
    parser.add_argument("--workers", type=number(int, ge=1),
                        help="trials at once (local processes, default CPUs/threads; Ray: default all CPUs)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Generate the dataset if asked, run or resume the search, print the summary."""
    from learning.checkpoint import CheckpointError
    from learning.data import DatasetError, generate_dataset, load_manifest
    from learning.search import SearchError, run_search
    from learning.search_grid import SearchConfig
    from learning.search_report import markdown_summary
    from uav_swarm.missions.registry import load_settings, make_task, task_factory

    given = {"alpha2": args.alpha2, "sigma2": args.sigma2, "threads": args.torch_threads}
    search_config = SearchConfig(**{k: v for k, v in given.items() if v is not None})
    settings = load_settings(args.task, args.config)
    fields = ("epochs", "max_steps", "batch_size", "lr", "device")
    overrides = {f: getattr(args, f) for f in fields if getattr(args, f) is not None}
    train_config = settings.train.replace(**overrides)
    try:
        if args.n is not None:
            generate_dataset(task_factory(make_task(args.task, args.config)), args.n, args.seed, args.data,
                             executor=args.executor, workers=args.workers, address=args.address)
        manifest = load_manifest(args.data)
        if manifest["task"] != args.task:
            print(f"uav-swarm search: {args.data} holds {manifest['task']!r} scenes, not {args.task!r}",
                  file=sys.stderr)
            return 2
        summary = run_search(args.data, args.out, search_config, model_config=settings.model,
                             target_config=settings.targets, train_config=train_config,
                             peak_config=settings.peaks, executor=args.executor, workers=args.workers,
                             address=args.address)
    except (CheckpointError, DatasetError, SearchError, ValueError) as exc:
        print(f"uav-swarm search: {exc}", file=sys.stderr)
        return 2
    print(markdown_summary(summary), end="")
    print(f"heat map: {args.out}/heatmap.png; results: {args.out}/search.json")
    return 0
