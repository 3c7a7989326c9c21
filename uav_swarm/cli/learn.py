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

from uav_swarm.cli.conventions import LazyChoices, config_flag, number, output_flag, run_folder_flag

__all__ = ["register", "run", "task_names", "task_choices"]


def task_names() -> tuple[str, ...]:
    """The shipped tasks (the choices of ``--task`` its help lists), read from the registry's source."""
    from uav_swarm.cli.field_source import read_keys

    return read_keys("uav_swarm.missions.registry", "TASKS")


def is_task(name: object) -> bool:
    """Whether ``name`` is a registered task (the registry imported: tasks may be registered at run time)."""
    from uav_swarm.missions.registry import TASKS

    return name in TASKS


def task_choices() -> LazyChoices:
    """``--task``'s choices: listed from source (``--help`` imports nothing), checked against the registry."""
    return LazyChoices(task_names, allowed=is_task)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``dataset``, ``train`` and ``evaluate`` subcommands."""
    from uav_swarm.cli.field_source import read_keys

    splits = LazyChoices(lambda: sorted(read_keys("learning.data", "SPLITS")))  # no numpy for --help

    train_cfg, model_cfg = "learning.train:TrainConfig.", "learning.model:ModelConfig."

    def common(parser: argparse.ArgumentParser, *, resumes_in_out: bool = False) -> None:
        """--task, --config and --out (a run's folder, refused when it holds files, unless resumed in)."""
        parser.add_argument("--task", required=True, choices=task_choices(), metavar="TASK",
                            help="the task: %(choices)s")
        parser.add_argument("--config", help="task settings TOML (tables task, targets, model, train, peaks, "
                            "refine, rule_check; default: none, the task's defaults)")
        if resumes_in_out:
            output_flag(parser, "--out", "folder", required=True, help="output folder")
        else:
            run_folder_flag(parser, "--out", resumed_by="resume_from", required=True, help="output folder")
        parser.set_defaults(func=run)

    def generation(parser: argparse.ArgumentParser) -> None:
        parser.add_argument("--n", type=number(int, ge=1), required=True, help="number of scenes")
        parser.add_argument("--seed", type=number(int, ge=0), required=True, help="dataset seed")
        parser.add_argument("--executor", choices=("local", "ray"), default="local", help="where to compute")
        parser.add_argument("--address", help="Ray cluster address (with --executor ray; default: a local "
                            "instance)")
        parser.add_argument("--workers", type=number(int, ge=1),
                            help="local worker processes (default: all CPUs)")

    dataset = subparsers.add_parser(
        "dataset", help="generate expert demonstrations into shards (resumable)",
        description="Generate expert demonstrations (scene, expert placement) into shard files in --out. "
        "Run the same command again after a kill to finish it.\n\n" + __doc__)
    common(dataset, resumes_in_out=True)  # resumable: the same command again finishes it
    generation(dataset)
    dataset.add_argument("--split", choices=splits, default="train", metavar="SPLIT",
                         help="seed namespace: %(choices)s")
    dataset.add_argument("--shard-size", type=number(int, ge=1), default=256, help="scenes per shard file")

    train = subparsers.add_parser(
        "train", help="train the utility network on a dataset",
        description="Train the utility network on a dataset of expert demonstrations; writes checkpoint.pt, "
        "best.pt and history.json into --out. The flags replace the values of --config's [train] and [model] "
        "tables.\n\n" + __doc__)
    common(train)
    train.add_argument("--data", required=True, help="dataset folder")
    config_flag(train, "--epochs", train_cfg + "epochs", key="[train] epochs")
    config_flag(train, "--batch-size", train_cfg + "batch_size", key="[train] batch_size")
    config_flag(train, "--lr", train_cfg + "lr", key="[train] lr")
    config_flag(train, "--schedule", train_cfg + "schedule", choices=("constant", "cosine", "step"),
                key="[train] schedule")
    config_flag(train, "--max-steps", train_cfg + "max_steps", key="[train] max_steps")
    config_flag(train, "--device", train_cfg + "device", choices=("auto", "cpu", "cuda"),
                key="[train] device")
    config_flag(train, "--torch-threads", train_cfg + "torch_threads", key="[train] torch_threads")
    config_flag(train, "--precision", train_cfg + "precision", choices=("auto", "float32", "bfloat16"),
                key="[train] precision")
    config_flag(train, "--patience", train_cfg + "patience", key="[train] patience")
    config_flag(train, "--arch", model_cfg + "arch", choices=("paper", "unet"), key="[model] arch")
    config_flag(train, "--width", model_cfg + "width", key="[model] width",
                help="channels of the first block; with --init, the init network is grown to it, computing "
                "the same map (learning.grow)")
    config_flag(train, "--depth", model_cfg + "depth", key="[model] depth",
                help="number of 2x poolings; with --init, the init network is grown to it, computing the "
                "same map (learning.grow)")
    train.add_argument("--peak-head", action="store_true", default=None,
                       help="add the peak head and its focal loss ([model] peak_head)")
    config_flag(train, "--focal-weight", train_cfg + "focal_weight", key="[train] focal_weight")
    train.add_argument("--resume-from", metavar="CHECKPOINT",
                       help="continue the run of this checkpoint (default: a new run)")
    train.add_argument("--init", metavar="CHECKPOINT",
                       help="start a new run from this checkpoint's weights, fine-tuning (default: none)")

    evaluate = subparsers.add_parser(
        "evaluate", help="evaluate a checkpoint on fresh test scenes",
        description="Evaluate a checkpoint on test scenes it never saw (the test seed namespace): corr, "
        "precision, QoS against the expert and timing; writes summary.json, summary.md and examples.png "
        "into --out.\n\n" + __doc__)
    common(evaluate)
    generation(evaluate)
    evaluate.add_argument("--checkpoint", required=True, help="a .pt file trained on this task")
    evaluate.add_argument("--data", help="test dataset folder (default: OUT/test-data, generated if needed)")
    evaluate.add_argument("--examples", type=number(int, ge=0), default=6,
                          help="scenes drawn in examples.png")
    evaluate.add_argument("--precision", choices=("auto", "float32", "bfloat16"), default="auto",
                          help="network precision ('auto': bfloat16 where native)")
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
    train_fields = ("epochs", "batch_size", "lr", "schedule", "max_steps", "device", "torch_threads",
                    "precision", "patience", "focal_weight")
    train_cfg = settings.train.replace(**_overrides(args, train_fields))
    shape = () if args.init else ("width", "depth")  # with --init they grow the init network instead
    model_cfg = settings.model.replace(**_overrides(args, ("arch", "peak_head", *shape)))
    grow = (args.width, args.depth) if args.init and (args.width or args.depth) else None
    try:
        result = train(args.data, args.out, model_config=model_cfg, target_config=settings.targets,
                       train_config=train_cfg, peak_config=settings.peaks, resume=args.resume_from,
                       init=args.init, grow=grow)
    except KeyboardInterrupt:  # the checkpoints of the finished epochs stay (written at each epoch's end)
        last = args.out / "checkpoint.pt"
        kept = (f"{last} holds the last finished epoch: continue with --resume-from {last}" if last.is_file()
                else "no epoch had finished: nothing written")
        print(f"uav-swarm train: interrupted (Ctrl-C): {kept}", file=sys.stderr)
        return 130
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
        except TypeError:
            print(f"uav-swarm evaluate: --rule-check: task {args.task!r} has no rule check; allowed with "
                  "--task wifi-s1 or wifi-s2", file=sys.stderr)
            return 2
    # peaks: the checkpoint's operating point, the [peaks] values of --config over it
    peaks = load_settings(args.task, args.config).peaks_given if args.config is not None else {}
    summary = evaluate(args.checkpoint, factory, args.n, args.seed, args.out, data_dir=args.data,
                       peak_overrides=peaks, peaks_source=f"config file {args.config}",
                       operating_point=args.operating_point, n_examples=args.examples, executor=args.executor,
                       workers=args.workers, address=args.address, precision=args.precision, tta=args.tta,
                       refiner=refiner, check=check)
    print(markdown_table(args.task, summary), end="")
    cut = summary.get("interrupted")
    if cut is not None:
        print(f"uav-swarm evaluate: interrupted (Ctrl-C) after {cut['scenes_scored']} of {cut['of']} scenes: "
              f"the table and the files in {args.out} cover those scenes", file=sys.stderr)
        return 130
    return 0


def run(args: argparse.Namespace) -> int:
    """Run ``dataset``, ``train`` or ``evaluate``; bad data, checkpoints or growth exit with code 2."""
    from learning.checkpoint import CheckpointError
    from learning.data import DatasetError
    from learning.grow import GrowError

    command = {"dataset": _dataset, "train": _train, "evaluate": _evaluate}[args.command]
    try:
        return command(args)
    except (CheckpointError, DatasetError, GrowError) as exc:
        print(f"uav-swarm {args.command}: {exc}", file=sys.stderr)
        return 2
