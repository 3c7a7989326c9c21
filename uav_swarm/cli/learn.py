"""``uav-swarm dataset | train | evaluate``: learning placement from demonstration.

Examples::

    uav-swarm dataset --task wifi-s1 --n 5000 --seed 1 --out runs/s1/data
    uav-swarm train --task wifi-s1 --data runs/s1/data --out runs/s1/train --config configs/tasks/wifi-s1.toml
    uav-swarm evaluate --task wifi-s1 --checkpoint runs/s1/train/best.pt --n 800 --seed 1 --out runs/s1/eval

Test scenes never repeat training scenes: ``dataset`` draws from the ``train`` seed
namespace by default and ``evaluate`` from the ``test`` namespace, and
``evaluate`` checks the test seeds against the checkpoint's training dataset.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

__all__ = ["register", "run"]


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``dataset``, ``train`` and ``evaluate`` subcommands."""
    from learning.data import SPLITS

    def common(parser: argparse.ArgumentParser) -> None:
        parser.add_argument("--task", required=True, help="wifi-s1, wifi-s2, agp or fp")
        parser.add_argument("--config", help="task settings TOML (tables task, targets, model, train, peaks, "
                            "refine)")
        parser.add_argument("--out", required=True, help="output folder")
        parser.set_defaults(func=run)

    def generation(parser: argparse.ArgumentParser) -> None:
        parser.add_argument("--n", type=int, required=True, help="number of scenes")
        parser.add_argument("--seed", type=int, required=True, help="dataset seed (>= 0)")
        parser.add_argument("--executor", choices=("local", "ray"), default="local", help="where to compute")
        parser.add_argument("--address", help="Ray cluster address (with --executor ray)")
        parser.add_argument("--workers", type=int, help="local worker processes (default: all CPUs)")

    dataset = subparsers.add_parser("dataset", help="generate expert demonstrations into shards (resumable)")
    common(dataset)
    generation(dataset)
    dataset.add_argument("--split", choices=sorted(SPLITS), default="train", help="seed namespace")
    dataset.add_argument("--shard-size", type=int, default=256, help="scenes per shard file")

    train = subparsers.add_parser("train", help="train the utility network on a dataset")
    common(train)
    train.add_argument("--data", required=True, help="dataset folder")
    train.add_argument("--epochs", type=int, help="override [train] epochs")
    train.add_argument("--batch-size", type=int, help="override [train] batch_size")
    train.add_argument("--lr", type=float, help="override [train] lr")
    train.add_argument("--max-steps", type=int, help="override [train] max_steps")
    train.add_argument("--device", choices=("auto", "cpu", "cuda"), help="override [train] device")
    train.add_argument("--torch-threads", type=int, help="override [train] torch_threads (1 on a busy CPU)")
    train.add_argument("--precision", choices=("auto", "float32", "bfloat16"),
                       help="override [train] precision ('auto': bfloat16 where native)")
    train.add_argument("--patience", type=int, help="override [train] patience (epochs without a better "
                       "validation score before stopping; 0: off)")
    train.add_argument("--arch", choices=("paper", "unet"), help="override [model] arch")
    train.add_argument("--peak-head", action="store_true", default=None,
                       help="override [model] peak_head: add the peak head and its focal loss")
    train.add_argument("--focal-weight", type=float, help="override [train] focal_weight")
    train.add_argument("--resume", help="checkpoint to continue from")
    train.add_argument("--init", help="checkpoint whose weights start a new run (fine-tuning)")

    evaluate = subparsers.add_parser("evaluate", help="evaluate a checkpoint on fresh test scenes")
    common(evaluate)
    generation(evaluate)
    evaluate.add_argument("--checkpoint", required=True, help="a .pt file trained on this task")
    evaluate.add_argument("--data", help="test dataset folder (default: OUT/test-data, generated if needed)")
    evaluate.add_argument("--examples", type=int, default=6, help="scenes drawn in examples.png")
    evaluate.add_argument("--precision", choices=("auto", "float32", "bfloat16"), default="auto",
                          help="network precision (default: %(default)s, bfloat16 where native)")
    evaluate.add_argument("--tta", action="store_true",
                          help="test-time augmentation: average the utility maps of the 8 grid symmetries")
    evaluate.add_argument("--refine", action="store_true",
                          help="also refine the learned placements (AGP, FP: repaired to full coverage; "
                          "Wi-Fi: local search on the crowd); time learned, refined and expert side by side")
    evaluate.add_argument("--operating-point", choices=("mission", "balanced"),
                          help="the checkpoint's peak settings: chosen for the mission's QoS or for corr "
                          "+ precision (default: mission where the checkpoint has it, else balanced); a "
                          "[peaks] table of --config applies over them")
    evaluate.add_argument("--rule-check", action="store_true",
                          help="Wi-Fi: keep only the learned UAVs the deployment rule justifies on the "
                          "density raster, peaks at the check's threshold ([rule_check] of --config)")


def _overrides(args: argparse.Namespace, names: tuple[str, ...]) -> dict[str, Any]:
    """The options among ``names`` given on the command line (same names as the config fields)."""
    return {name: getattr(args, name) for name in names if getattr(args, name) is not None}


def _dataset(args: argparse.Namespace) -> int:
    from learning.data import generate_dataset
    from uav_swarm.missions.registry import make_task, task_factory

    factory = task_factory(make_task(args.task, args.config))
    manifest = generate_dataset(factory, args.n, args.seed, args.out, split=args.split,
                                shard_size=args.shard_size, executor=args.executor, workers=args.workers,
                                address=args.address)
    print(f"{manifest['n']} {args.task} scenes ({args.split}, seed {args.seed}) in {args.out}")
    return 0


def _agrees(given: object, stored: object) -> bool:
    """A settings value agrees with a dataset's: equal, or for a table, every key given agrees."""
    if isinstance(given, dict) and isinstance(stored, dict):
        return all(_agrees(v, stored.get(k)) for k, v in given.items())
    return given == stored


def _train(args: argparse.Namespace) -> int:
    from learning.data import load_manifest
    from learning.train import train
    from uav_swarm.missions.registry import load_settings

    settings = load_settings(args.task, args.config)
    manifest = load_manifest(args.data)
    if manifest["task"] != args.task:
        print(f"uav-swarm: {args.data} holds {manifest['task']!r} scenes, not {args.task!r}", file=sys.stderr)
        return 2
    differ = sorted(k for k, v in settings.task.items() if not _agrees(v, manifest["task_config"].get(k)))
    if differ:
        print(f"uav-swarm: {args.data} was generated with other [task] values for {differ} "
              f"than {args.config}", file=sys.stderr)
        return 2
    train_fields = ("epochs", "batch_size", "lr", "max_steps", "device", "torch_threads", "precision",
                    "patience", "focal_weight")
    train_cfg = settings.train.replace(**_overrides(args, train_fields))
    model_cfg = settings.model.replace(**_overrides(args, ("arch", "peak_head")))
    result = train(args.data, args.out, model_config=model_cfg, target_config=settings.targets,
                   train_config=train_cfg, peak_config=settings.peaks, resume=args.resume, init=args.init)
    last = result.history[-1] if result.history else {}
    print(f"checkpoint: {result.checkpoint} (best: {result.best_checkpoint}); last epoch: "
          + ", ".join(f"{k} {v:.4g}" for k, v in last.items()))
    return 0


def _evaluate(args: argparse.Namespace) -> int:
    from learning.checkpoint import load_checkpoint
    from learning.evaluate import evaluate, markdown_table
    from uav_swarm.missions.registry import (
        TaskFactory,
        build_refiner,
        build_rule_check,
        load_settings,
        make_task,
        task_factory,
    )

    if args.config is not None:  # must describe the task the checkpoint was trained on
        factory = task_factory(make_task(args.task, args.config))
    else:  # the task exactly as trained
        factory = TaskFactory(args.task, load_checkpoint(args.checkpoint, task_name=args.task).task_config)
    refiner = None
    if args.refine:  # the [refine] table of --config; what it leaves out, the strategy's own settings
        table = load_settings(args.task, args.config).refine if args.config is not None else {}
        refiner = build_refiner(factory(), table)
        source = f"[refine] of {args.config}" if table else "the task's own defaults"
        print(f"refinement settings ({source}): {json.dumps(refiner.config.to_dict(), sort_keys=True)}")
    check = None
    if args.rule_check:  # the [rule_check] table of --config, else the defaults
        table = load_settings(args.task, args.config).rule_check if args.config is not None else {}
        try:
            check = build_rule_check(factory(), table)
        except TypeError as exc:
            print(f"uav-swarm evaluate: --rule-check: {exc}", file=sys.stderr)
            return 2
    # peaks: the checkpoint's operating point, the [peaks] values of --config over it
    peaks = load_settings(args.task, args.config).peaks_given if args.config is not None else {}
    summary = evaluate(args.checkpoint, factory, args.n, args.seed, args.out, data_dir=args.data,
                       peak_overrides=peaks, peaks_source=f"config file {args.config}",
                       operating_point=args.operating_point, n_examples=args.examples, executor=args.executor,
                       workers=args.workers, address=args.address, precision=args.precision, tta=args.tta,
                       refiner=refiner, check=check)
    print(markdown_table(args.task, summary), end="")
    return 0


def run(args: argparse.Namespace) -> int:
    """Run ``dataset``, ``train`` or ``evaluate``; dataset and checkpoint problems exit with code 2."""
    from learning.checkpoint import CheckpointError
    from learning.data import DatasetError

    command = {"dataset": _dataset, "train": _train, "evaluate": _evaluate}[args.command]
    try:
        return command(args)
    except (CheckpointError, DatasetError) as exc:
        print(f"uav-swarm {args.command}: {exc}", file=sys.stderr)
        return 2
