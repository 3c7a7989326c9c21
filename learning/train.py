"""Training the utility network on a dataset of demonstrations.

``train(data_dir, out_dir, ...)`` reads top to bottom: load the shards, split off a
validation part, build the model, then for each epoch minimise the MSE between
the utility map and the target map ``R(ζ)/α1`` with Adam, validate (loss,
correspondence and precision of the extracted peaks), and write
``out_dir/checkpoint.pt`` (the latest, with the optimiser state to resume from) and
``out_dir/best.pt`` (best validation corr + precision, weights and metadata only:
the file to ship) and ``out_dir/history.png`` (the curves so far). With ``patience``
the run stops once that many epochs pass without a better validation score.

Speed: the forward pass runs under bfloat16 autocast where the device computes it
natively (``precision = "auto"``, :mod:`learning.precision`; float32 master weights,
optimiser state and loss), on channels-last tensors; validation chooses the peak
thresholds on a subset (``calibrate_samples``) and scores the whole split.

Determinism: on CPU, the same data, configs and seed give bit-identical weights
(fixed initialisation seed, one loader generator per epoch seeded from
``(seed, epoch)``, deterministic algorithms enforced during training). Resuming
continues from the epoch after the checkpoint's, so an interrupted run resumed
ends as the uninterrupted run would.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
import torch
import torch.nn.functional as F
from torch.utils.data import DataLoader
from tqdm.auto import tqdm

from learning.calibrate import calibrate_peaks
from learning.checkpoint import CHECKPOINT_FORMAT, CheckpointError, load_checkpoint, save_checkpoint
from learning.data import load_arrays
from learning.grow import grow_state_dict
from learning.loader import ShardDataset
from learning.losses import focal_loss
from learning.metrics import MATCH_FRACTION, aggregate, score_sample
from learning.model import ModelConfig, UtilityNet, build_model, with_memory_format
from learning.peaks import PeakConfig, find_peaks
from learning.plots import plot_history
from learning.precision import Precision, autocast, resolve_precision
from learning.targets import TargetConfig
from typed_config import Config, param

__all__ = ["TrainConfig", "TrainResult", "train", "pick_device", "split_indices", "validate"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TrainConfig(Config):
    """Optimisation settings."""

    epochs: int = param(50, ge=1, le=100_000, doc="passes over the training part")
    batch_size: int = param(16, ge=1, le=4096, doc="samples per step")
    lr: float = param(1e-3, gt=0.0, le=1.0, doc="Adam learning rate")
    schedule: Literal["constant", "cosine", "step"] = param("cosine", doc="learning-rate schedule")
    step_epochs: int = param(10, ge=1, doc="'step' schedule: epochs between decays")
    step_gamma: float = param(0.5, gt=0.0, le=1.0, doc="'step' schedule: decay factor")
    weight_decay: float = param(0.0, ge=0.0, le=1.0, doc="Adam L2 weight decay")
    seed: int = param(0, ge=0, doc="initialisation, split and shuffling seed")
    device: Literal["auto", "cpu", "cuda"] = param("auto", doc="'auto': CUDA when available")
    num_workers: int = param(0, ge=0, le=64, doc="data loader worker processes")
    torch_threads: int = param(0, ge=0, le=256, doc="CPU threads for torch (0: torch's default; 1 is "
                               "often fastest on a busy machine)")
    max_steps: int | None = param(None, ge=1, doc="stop after this many optimiser steps (all epochs)")
    val_fraction: float = param(0.1, ge=0.0, lt=1.0, doc="share of the dataset held out for validation")
    augment: bool = param(False, doc="random grid symmetries (only for tasks that are symmetric)")
    calibrate_peaks: bool = param(False, doc="choose the peak thresholds on the validation split every "
                                  "epoch (learning.calibrate); best.pt carries the chosen ones")
    calibrate_samples: int = param(1000, ge=0, doc="validation samples the thresholds are chosen on (0: all; "
                                   "the metrics are always measured on the whole split)")
    precision: Literal["auto", "float32", "bfloat16"] = param(
        "auto", doc="'auto': bfloat16 autocast where the device computes it natively (learning.precision), "
        "else float32; weights, optimiser and loss stay float32")
    channels_last: bool = param(True, doc="channels-last memory format for the network and its batches")
    patience: int = param(0, ge=0, doc="stop after this many epochs without a better validation "
                          "corr + precision (0: run every epoch)")
    focal_weight: float = param(
        0.001, ge=0.0, le=100.0, doc="weight of the peak head's focal loss beside the MSE (learning.losses); "
        "networks without a peak head train on the MSE alone")


@dataclass(frozen=True)
class TrainResult:
    """Where the run wrote its checkpoints, and its per-epoch history."""

    checkpoint: Path
    best_checkpoint: Path
    history: list[dict[str, float]]


def split_indices(n: int, config: TrainConfig) -> tuple[np.ndarray, np.ndarray]:
    """The sorted training and validation indices of ``n`` scenes (by ``seed`` and ``val_fraction``)."""
    order = np.random.default_rng(config.seed).permutation(n)
    n_val = min(n - 1, max(1, round(config.val_fraction * n))) if config.val_fraction > 0 and n > 1 else 0
    return np.sort(order[n_val:]), np.sort(order[:n_val])


def pick_device(choice: str) -> torch.device:
    """``"auto"`` -> CUDA when available, else CPU."""
    if choice == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    return torch.device(choice)


def _lr_factor(config: TrainConfig, step: int, steps_per_epoch: int, total_steps: int) -> float:
    if config.schedule == "cosine":
        return 0.5 * (1.0 + math.cos(math.pi * min(step, total_steps) / max(total_steps, 1)))
    if config.schedule == "step":
        return config.step_gamma ** (step // (steps_per_epoch * config.step_epochs))
    return 1.0


@torch.inference_mode()
def validate(model: UtilityNet, dataset: ShardDataset, eps_px: float, peaks: PeakConfig, device: torch.device,
             batch_size: int = 64, calibrate: bool = False, precision: Precision = "float32",
             calibrate_samples: int = 0) -> tuple[dict[str, float], PeakConfig]:
    """Mean MSE loss, correspondence and precision (the paper's matching rule) of ``model`` on ``dataset``.

    Args:
        model: The network (set to eval mode).
        dataset: The validation split.
        eps_px: Match radius, pixels.
        peaks: Peak extraction settings (the starting point of calibration).
        device: Where ``model`` is.
        batch_size: Samples per forward pass.
        calibrate: Choose the thresholds first, on the first ``calibrate_samples`` samples
            (all when 0), then measure the whole split with them.
        precision: Autocast precision of the forward passes (the loss is float32).
        calibrate_samples: See ``calibrate``.

    Returns:
        The metrics and the peak settings they were measured with: ``peaks``, or with
        ``calibrate`` the thresholds that :func:`learning.calibrate.calibrate_peaks` chose.
    """
    model.eval()
    losses, utilities = [], []
    rasters: list[np.ndarray] = []
    for start in range(0, len(dataset), batch_size):
        items = [dataset[i] for i in range(start, min(start + batch_size, len(dataset)))]
        x = torch.stack([item[0] for item in items]).to(device)  # (B, C, h, w)
        y = torch.stack([item[1] for item in items]).to(device)  # (B, 1, h, w)
        with autocast(precision, device):
            u = model(x).float()  # (B, 1, h, w)
        losses.append(F.mse_loss(u, y, reduction="sum").item() / y[0].numel())
        utilities.extend(u[:, 0].cpu().numpy())
        rasters.extend(item[0].numpy() for item in items)
    experts = [dataset.expert(i) for i in range(len(dataset))]
    if calibrate:
        k = calibrate_samples or len(utilities)
        peaks, _ = calibrate_peaks(utilities[:k], experts[:k], eps_px, peaks, rasters=rasters[:k])
    summary = aggregate(score_sample(e, find_peaks(u, peaks, raster=x), eps_px)
                        for u, e, x in zip(utilities, experts, rasters, strict=True))
    metrics = {"val_loss": sum(losses) / len(dataset), "val_corr": summary["corr"],
               "val_precision": summary["precision"]}
    return metrics, peaks


def train(
    data_dir: str | Path,
    out_dir: str | Path,
    *,
    model_config: ModelConfig | None = None,
    target_config: TargetConfig | None = None,
    train_config: TrainConfig | None = None,
    peak_config: PeakConfig | None = None,
    resume: str | Path | None = None,
    init: str | Path | None = None,
    grow: tuple[int | None, int | None] | None = None,
    progress: bool = True,
) -> TrainResult:
    """Train a utility network on the dataset in ``data_dir``; checkpoints go to ``out_dir``.

    Args:
        data_dir: A complete dataset folder (see :mod:`learning.data`).
        out_dir: Output folder (created if needed).
        model_config: Architecture (``in_channels`` is taken from the data).
        target_config: The target Gaussians.
        train_config: Optimisation settings (on resume: defaults to the checkpoint's;
            pass one to extend ``epochs``).
        peak_config: Peak extraction for validation, saved in the checkpoint.
        resume: A checkpoint of this dataset's task to continue from; its model,
            target and peak configs are used.
        init: A checkpoint of this dataset's task whose weights start a new run (fine-tuning,
            e.g. a shipped ``best.pt`` on a larger dataset); its model config is used (but
            ``peak_head`` from ``model_config`` when given: a new head starts from scratch), the
            optimiser, schedule and history start afresh.
        grow: With ``init``: the ``(width, depth)`` the init network is grown to first, computing
            the same utility map (:mod:`learning.grow`); ``None`` (or ``None`` in either place) keeps it.
        progress: Show a progress bar (on a terminal only: none in a log or a pipe).

    Raises:
        learning.data.DatasetError: Incomplete or corrupt dataset.
        learning.checkpoint.CheckpointError: ``resume`` is corrupt or from another task or shape.
    """
    manifest, arrays = load_arrays(data_dir)
    input_shape = (manifest["channels"], *manifest["shape"])
    state: dict[str, Any] = {}
    if resume is not None:
        ckpt = load_checkpoint(resume, task_name=manifest["task"], task_config=manifest["task_config"],
                               input_shape=input_shape)
        state = ckpt.payload
        if "optimizer_state" not in state:
            raise CheckpointError(f"{resume}: has no optimizer state (a best.pt); resume from checkpoint.pt")
        model_config, target_config, peak_config = ckpt.model_config, ckpt.target_config, ckpt.peak_config
        train_config = train_config or TrainConfig.from_dict(state["train_config"])
    init_state = None
    if init is not None:
        if resume is not None:
            raise ValueError("pass either resume (continue a run) or init (start from its weights), not both")
        start = load_checkpoint(init, task_name=manifest["task"], task_config=manifest["task_config"],
                                input_shape=input_shape)
        peak_head = model_config.peak_head if model_config is not None else start.model_config.peak_head
        model_config = start.model_config.replace(peak_head=peak_head)  # a peak head may be added or dropped
        init_state = start.model.state_dict()
        if grow is not None:
            width, depth = grow
            grown = model_config.replace(width=width or model_config.width, depth=depth or model_config.depth)
            init_state = grow_state_dict(init_state, start.model_config.replace(peak_head=peak_head), grown,
                                         seed=(train_config or TrainConfig()).seed)
            model_config = grown
    elif grow is not None:
        raise ValueError("grow needs init (the network to grow)")
    vector_channels = tuple(manifest.get("vector_channels", ()))
    model_config = (model_config or ModelConfig()).replace(in_channels=manifest["channels"],
                                                           vector_channels=vector_channels)
    target_config = target_config or TargetConfig()
    train_config = train_config or TrainConfig()
    peak_config = peak_config or PeakConfig()
    cfg = train_config
    device = pick_device(cfg.device)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)

    train_indices, val_indices = split_indices(len(arrays["inputs"]), cfg)
    train_set = ShardDataset(arrays, target_config, train_indices, cfg.augment, cfg.seed,
                             peak_heatmaps=model_config.peak_head, vector_channels=vector_channels)
    val_set = ShardDataset(arrays, target_config, val_indices)
    n_val = len(val_indices)
    eps_px = MATCH_FRACTION * manifest["mission_dimension_px"]

    precision = resolve_precision(cfg.precision, device)
    memory_format = torch.channels_last if cfg.channels_last else torch.contiguous_format
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(cfg.seed)
        model = build_model(model_config)
        if init_state is not None:
            missing, unexpected = model.load_state_dict(init_state, strict=False)
            stray = [k for k in (*missing, *unexpected) if not k.startswith("peak_head.")]
            if stray:
                raise CheckpointError(f"{init}: its weights do not fit this network: {stray[:5]}")
        model = with_memory_format(model, memory_format, device)
    optimizer = torch.optim.Adam(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    steps_per_epoch = math.ceil(len(train_set) / cfg.batch_size)
    total_steps = min(cfg.epochs * steps_per_epoch, cfg.max_steps or math.inf)
    scheduler = torch.optim.lr_scheduler.LambdaLR(
        optimizer, lambda s: _lr_factor(cfg, s, steps_per_epoch, int(total_steps)))
    history: list[dict[str, float]] = []
    step, first_epoch, elapsed_s, samples = 0, 0, 0.0, 0
    if state:
        model.load_state_dict(state["model_state"])
        optimizer.load_state_dict(state["optimizer_state"])
        scheduler.load_state_dict(state["scheduler_state"])
        history, step, first_epoch = list(state["history"]), int(state["step"]), int(state["epoch"]) + 1
        elapsed_s = float(history[-1]["elapsed_s"]) if history else 0.0
        samples = int(history[-1].get("samples", step * cfg.batch_size)) if history else 0
    scored = [(h["val_corr"] + h["val_precision"], int(h["epoch"])) for h in history if "val_corr" in h]
    best_score, best_epoch = max(scored, default=(-1.0, first_epoch - 1))
    payload = {
        "format": CHECKPOINT_FORMAT, "model_config": model_config.to_dict(),
        "target_config": target_config.to_dict(), "peak_config": peak_config.to_dict(),
        "train_config": cfg.to_dict(), "task_name": manifest["task"], "task_config": manifest["task_config"],
        "input_shape": list(input_shape), "mission_dimension_px": manifest["mission_dimension_px"],
        "precision": precision,
        "data": {"seed": manifest["seed"], "split": manifest["split"], "n": manifest["n"]},
    }
    if init is not None:
        payload["init"] = Path(init).name
        if grow is not None:
            payload["grown_from"] = {"width": start.model_config.width, "depth": start.model_config.depth}
    ckpt_path, best_path = out / "checkpoint.pt", out / "best.pt"
    log.info("training %s on %d samples (%d validation) on %s in %s",
             model_config.arch, len(train_set), n_val, device, precision)

    deterministic, threads = torch.are_deterministic_algorithms_enabled(), torch.get_num_threads()
    torch.use_deterministic_algorithms(device.type == "cpu" or deterministic, warn_only=True)
    if cfg.torch_threads:
        torch.set_num_threads(cfg.torch_threads)
    bar = tqdm(total=int(total_steps), initial=step, disable=None if progress else True, unit="step")
    try:
        for epoch in range(first_epoch, cfg.epochs):
            if step >= total_steps:
                break
            if cfg.patience and n_val and epoch - best_epoch > cfg.patience:
                log.info("stopping: no better validation score for %d epochs", cfg.patience)
                break
            t0 = time.perf_counter()
            model.train()
            train_set.set_epoch(epoch)
            generator = torch.Generator().manual_seed(cfg.seed * 100_003 + epoch)
            loader = DataLoader(train_set, batch_size=cfg.batch_size, shuffle=True, generator=generator,
                                num_workers=cfg.num_workers, pin_memory=device.type == "cuda")
            loss_sum, seen = 0.0, 0
            for batch in loader:
                x, y, *heatmap = (t.to(device, non_blocking=True, memory_format=memory_format) for t in batch)
                with autocast(precision, device):  # x (B, C, h, w); y, u, heatmap, logits (B, 1, h, w)
                    u, logits = model.forward_with_peaks(x) if heatmap else (model(x), None)
                loss = F.mse_loss(u.float(), y)
                if logits is not None:
                    loss = loss + cfg.focal_weight * focal_loss(logits, heatmap[0])
                optimizer.zero_grad(set_to_none=True)
                loss.backward()
                optimizer.step()
                scheduler.step()
                step += 1
                loss_sum, seen = loss_sum + loss.item() * len(x), seen + len(x)
                bar.update(1)
                bar.set_postfix(epoch=epoch, loss=f"{loss.item():.4f}")
                if step >= total_steps:
                    break
            samples += seen
            record: dict[str, float] = {"epoch": epoch, "step": step, "samples": samples,
                                        "train_loss": loss_sum / max(seen, 1),
                                        "lr": float(scheduler.get_last_lr()[0])}
            epoch_peaks = peak_config
            if n_val:
                metrics, epoch_peaks = validate(model, val_set, eps_px, peak_config, device,
                                                calibrate=cfg.calibrate_peaks, precision=precision,
                                                calibrate_samples=cfg.calibrate_samples)
                record.update(metrics)
                if cfg.calibrate_peaks:
                    record.update(threshold_abs=epoch_peaks.threshold_abs,
                                  min_contrast=epoch_peaks.min_contrast)
            elapsed_s += time.perf_counter() - t0
            record["elapsed_s"] = elapsed_s
            history.append(record)
            log.info("epoch %d: %s", epoch, {k: round(v, 4) for k, v in record.items()})
            payload.update(model_state=model.state_dict(), optimizer_state=optimizer.state_dict(),
                           scheduler_state=scheduler.state_dict(), epoch=epoch, step=step, history=history)
            save_checkpoint(ckpt_path, payload)
            title = f"{manifest['task']}, {model_config.arch}, {precision}"
            plot_history(out / "history.png", history, title)
            score = record.get("val_corr", 0.0) + record.get("val_precision", 0.0)
            if not n_val or score > best_score or not best_path.exists():
                best_score, best_epoch = score, epoch
                lean = {k: v for k, v in payload.items() if k not in ("optimizer_state", "scheduler_state")}
                lean["peak_config"] = epoch_peaks.to_dict()
                save_checkpoint(best_path, lean)
    finally:
        bar.close()
        torch.use_deterministic_algorithms(deterministic)
        torch.set_num_threads(threads)
    return TrainResult(ckpt_path, best_path, history)
