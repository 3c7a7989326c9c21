"""Choosing a placement check's settings on the validation split of its checkpoint's training data.

A placement check (:class:`learning.task.PlacementCheck`, e.g. the Wi-Fi rule check) trades
correspondence, precision and QoS against each other through its settings: a lower peak threshold
finds more of the expert's UAVs (and covers more users), the check removes the false ones, and
its slack decides how strictly. :func:`calibrate_check` scores every point of a grid on the
validation scenes the checkpoint never trained on (the split ``train`` made with the checkpoint's
own ``seed`` and ``val_fraction``), with QoS judged on the regenerated crowds, and chooses by one
rule: the highest correspondence + precision among the points whose QoS is at least ``qos_floor``
of the expert's (the users' service comes first); when no point reaches the floor, the point with
the highest QoS. The checkpoint's own peaks without any check are scored beside them.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from learning.checkpoint import checkpoint_label, load_checkpoint
from learning.data import load_arrays
from learning.inference import utility_maps
from learning.metrics import MATCH_FRACTION, aggregate, score_sample
from learning.peaks import PeakConfig, find_peaks
from learning.precision import resolve_precision
from learning.task import PlacementCheck, Task
from learning.train import TrainConfig, split_indices

__all__ = ["calibrate_check"]


def calibrate_check(
    checkpoint: str | Path,
    task: Task,
    data_dir: str | Path,
    build: Callable[[Mapping[str, Any]], PlacementCheck],
    grid: Sequence[Mapping[str, Any]],
    *,
    qos_floor: float = 0.99,
    n: int | None = None,
    precision: str = "auto",
) -> dict[str, Any]:
    """Score ``grid`` on the validation split and choose a point (see the module docstring).

    Args:
        checkpoint: The trained network.
        task: Its task (scenes are regenerated from the dataset's seeds for QoS).
        data_dir: The dataset the checkpoint was trained on.
        build: Makes the check of one grid point's settings.
        grid: The settings tried.
        qos_floor: Least QoS relative to the expert's for a point to be chosen by corr + precision.
        n: At most this many validation scenes (default: all).
        precision: Network precision (``"auto"``: bfloat16 where native).

    Returns:
        ``{"task", "checkpoint", "n_validation", "qos_floor", "expert_qos", "unchecked", "rows",
        "chosen"}``; each row holds its settings, ``corr``, ``precision``, ``n_predicted``, ``qos`` and
        ``qos_relative``.

    Raises:
        ValueError: The dataset is another task's (or config's), or ``grid`` is empty.
        learning.checkpoint.CheckpointError: The checkpoint does not fit the task.
    """
    if not grid:
        raise ValueError("the grid of settings is empty")
    manifest, arrays = load_arrays(data_dir)
    if manifest["task"] != task.name or manifest["task_config"] != task.config.to_dict():
        raise ValueError(f"{data_dir} holds {manifest['task']!r} scenes of another config than this "
                         f"{task.name!r} task (its [task] table must be the one the data was made with)")
    ckpt = load_checkpoint(checkpoint, task_name=task.name, task_config=task.config,
                           input_shape=(task.channels, *task.shape))
    _, val = split_indices(len(arrays["inputs"]), TrainConfig.from_dict(ckpt.payload["train_config"]))
    val = val[:n] if n is not None else val
    resolved = resolve_precision(precision, next(ckpt.model.parameters()).device)
    utilities = utility_maps(ckpt.model, arrays["inputs"][val], resolved)
    observations = arrays["inputs"][val]
    scenes = [task.sample(np.random.default_rng(int(arrays["seeds"][i]))) for i in val]
    experts = [arrays["positions"][i][arrays["mask"][i]] for i in val]
    expert_qos = float(np.mean([task.qos(s, e)["qos"] for s, e in zip(scenes, experts, strict=True)]))
    eps_px = MATCH_FRACTION * task.mission_dimension_px

    def score(peaks: PeakConfig, check: PlacementCheck | None) -> dict[str, float]:
        predicted = [find_peaks(u, peaks, raster=x) for u, x in zip(utilities, observations, strict=True)]
        if check is not None:
            predicted = [check(x, p) for x, p in zip(observations, predicted, strict=True)]
        summary = aggregate(score_sample(e, p, eps_px) for e, p in zip(experts, predicted, strict=True))
        qos = float(np.mean([task.qos(s, p)["qos"] for s, p in zip(scenes, predicted, strict=True)]))
        return {"corr": summary["corr"], "precision": summary["precision"],
                "n_predicted": summary["n_predicted"], "qos": qos,
                "qos_relative": qos / expert_qos if expert_qos > 0 else 1.0}

    rows = []
    for settings in grid:
        check = build(settings)
        rows.append({**check.settings(), **score(ckpt.peak_config.replace(threshold_abs=check.threshold_abs),
                                                   check)})
    eligible = [row for row in rows if row["qos_relative"] >= qos_floor]
    if eligible:
        chosen = max(eligible, key=lambda row: row["corr"] + row["precision"])
    else:
        chosen = max(rows, key=lambda row: row["qos_relative"])
    return {"task": task.name, "checkpoint": checkpoint_label(checkpoint), "n_validation": len(val),
            "qos_floor": qos_floor, "expert_qos": expert_qos,
            "unchecked": {**ckpt.peak_config.to_dict(), **score(ckpt.peak_config, None)},
            "rows": rows, "chosen": chosen}
