"""Checkpoint files: a trained utility network with everything needed to use and judge it.

A checkpoint (``.pt``, written atomically by :func:`save_checkpoint`) is a dict of
plain values and tensors, readable with ``torch.load(weights_only=True)``:

``format``, ``model_state``, ``model_config``, ``target_config``, ``peak_config``,
``train_config``, ``task_name``, ``task_config``, ``input_shape`` ``[C, h, w]``,
``mission_dimension_px``, ``data`` (the training dataset's seed, split and size),
``epoch``, ``step``, ``history`` (per-epoch losses and validation metrics) and,
for resuming, ``optimizer_state`` and ``scheduler_state``. ``peak_config`` is the balanced operating
point; a checkpoint calibrated for its mission also holds ``peak_config_mission`` and
``mission_calibration`` (how it was chosen; :mod:`learning.operating_points`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch

from learning.model import ModelConfig, UtilityNet, build_model
from learning.peaks import PeakConfig
from learning.targets import TargetConfig
from typed_config import Config, ConfigError
from typed_config.files import atomic_path

__all__ = ["CHECKPOINT_FORMAT", "CheckpointError", "Checkpoint", "save_checkpoint", "load_checkpoint",
           "checkpoint_label"]

CHECKPOINT_FORMAT = "learning-utility/1"
_REQUIRED = ("format", "model_state", "model_config", "target_config", "peak_config", "train_config",
             "task_name", "task_config", "input_shape", "mission_dimension_px", "data", "epoch", "step",
             "history")


class CheckpointError(RuntimeError):
    """A checkpoint is missing, corrupt, or does not fit the task it is used with."""


@dataclass
class Checkpoint:
    """A loaded checkpoint: the model (eval mode, on the requested device) and its metadata."""

    path: Path
    model: UtilityNet
    model_config: ModelConfig
    target_config: TargetConfig
    peak_config: PeakConfig
    task_name: str
    task_config: dict[str, Any]
    input_shape: tuple[int, int, int]
    mission_dimension_px: float
    payload: dict[str, Any]
    mission_peak_config: PeakConfig | None = None
    """The mission operating point's peak settings, None where the checkpoint has none."""


def save_checkpoint(path: str | Path, payload: dict[str, Any]) -> None:
    """Write a checkpoint payload atomically (temporary file in the same folder, then ``os.replace``).

    Raises:
        CheckpointError: The payload lacks a required key.
    """
    missing = [key for key in _REQUIRED if key not in payload]
    if missing:
        raise CheckpointError(f"checkpoint payload lacks {missing}")
    with atomic_path(path) as tmp:
        torch.save(payload, tmp)


def load_checkpoint(
    path: str | Path,
    *,
    task_name: str | None = None,
    task_config: dict[str, Any] | Config | None = None,
    input_shape: tuple[int, int, int] | None = None,
    device: str | torch.device = "cpu",
) -> Checkpoint:
    """Load and validate a checkpoint, and rebuild its model.

    Args:
        path: The ``.pt`` file.
        task_name: When given, the checkpoint must have been trained on this task.
        task_config: When given, the checkpoint's task config must equal it. Given as a config object,
            the checkpoint's is read through its class first, so fields added to the class since the
            checkpoint was saved take their defaults.
        input_shape: When given, ``(C, h, w)`` must equal the checkpoint's.
        device: Where to put the model.

    Raises:
        CheckpointError: Missing or unreadable file, not a checkpoint of this format,
            invalid configs, weights that do not fit the model, or a task/shape mismatch.
    """
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"checkpoint not found: {path}")
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises many types for a damaged file
        reason = f"{type(exc).__name__}: {exc}"
        raise CheckpointError(f"{path}: unreadable or corrupt checkpoint ({reason})") from None
    if not isinstance(payload, dict) or payload.get("format") != CHECKPOINT_FORMAT:
        raise CheckpointError(f"{path}: not a {CHECKPOINT_FORMAT} checkpoint")
    missing = [key for key in _REQUIRED if key not in payload]
    if missing:
        raise CheckpointError(f"{path}: checkpoint lacks {missing}")
    if task_name is not None and payload["task_name"] != task_name:
        raise CheckpointError(f"{path}: trained on task {payload['task_name']!r}, not {task_name!r}")
    if task_config is not None:
        stored: dict[str, Any] = payload["task_config"]
        if isinstance(task_config, Config):
            expected = task_config.to_dict()
            try:
                stored = type(task_config).from_dict(stored).to_dict()
            except ConfigError as exc:
                name = type(task_config).__name__
                raise CheckpointError(f"{path}: its task config is not a valid {name}: {exc}") from None
        else:
            expected = task_config
        if stored != expected:
            diff = sorted(k for k in set(expected) | set(stored) if expected.get(k) != stored.get(k))
            raise CheckpointError(f"{path}: task config differs from the checkpoint's in {diff}")
    channels, height, width = (int(v) for v in payload["input_shape"])
    shape = (channels, height, width)
    if input_shape is not None and tuple(input_shape) != shape:
        raise CheckpointError(f"{path}: trained on inputs of shape {shape}, not {tuple(input_shape)}")
    try:
        model_config = ModelConfig.from_dict(payload["model_config"])
        target_config = TargetConfig.from_dict(payload["target_config"])
        peak_config = PeakConfig.from_dict(payload["peak_config"])
        mission = payload.get("peak_config_mission")
        mission_peak_config = None if mission is None else PeakConfig.from_dict(mission)
    except ConfigError as exc:
        raise CheckpointError(f"{path}: invalid config in checkpoint: {exc}") from None
    model = build_model(model_config)
    try:
        model.load_state_dict(payload["model_state"])
    except (RuntimeError, KeyError, TypeError) as exc:
        raise CheckpointError(f"{path}: weights do not fit the model config: {exc}") from None
    model.to(device).eval()
    return Checkpoint(path, model, model_config, target_config, peak_config, payload["task_name"],
                      payload["task_config"], shape, float(payload["mission_dimension_px"]), payload,
                      mission_peak_config)


def checkpoint_label(path: str | Path) -> str:
    """How results name a checkpoint without a path of this machine.

    Relative to the working folder when the file lies below it, else its file name (a relative
    path is kept as given).
    """
    path = Path(path)
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return path.name if path.is_absolute() else str(path)
