"""Inference: rasters -> utility maps -> positions, in batches or one raster at a time.

A replan has a budget of a few milliseconds, so this path avoids autograd
(``torch.inference_mode``), keeps the model on its device in eval mode, and
reuses the CoordConv grid that the model builds once per raster shape. Precision
is that of :mod:`learning.precision` (bfloat16 autocast where native).

Test-time augmentation (``tta=True``): the utility map is the mean of the maps of
the 8 symmetries of the square raster (flips and transposition), each mapped back,
computed in one batch. It needs a square raster and a task whose rule commutes with
the symmetries (the same condition as training augmentation).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import torch

from learning.model import UtilityNet
from learning.peaks import PeakConfig, find_peaks
from learning.precision import Precision, autocast
from learning.symmetry import SYMMETRIES, transform_vector_channels

__all__ = ["SYMMETRIES", "apply_symmetry", "invert_symmetry", "utility_maps", "utility_map",
           "predict_positions"]



def apply_symmetry(x: torch.Tensor, flip_x: bool, flip_y: bool, transpose: bool) -> torch.Tensor:
    """``x`` ``(..., h, w)`` flipped along x (columns), then y (rows), then transposed."""
    if flip_x:
        x = x.flip(-1)
    if flip_y:
        x = x.flip(-2)
    return x.transpose(-2, -1) if transpose else x


def invert_symmetry(x: torch.Tensor, flip_x: bool, flip_y: bool, transpose: bool) -> torch.Tensor:
    """The inverse of :func:`apply_symmetry` with the same arguments."""
    if transpose:
        x = x.transpose(-2, -1)
    if flip_y:
        x = x.flip(-2)
    return x.flip(-1) if flip_x else x


def _forward(model: UtilityNet, x: torch.Tensor, precision: Precision, tta: bool) -> torch.Tensor:
    """``(B, h, w)`` float32 utility maps of a ``(B, C, h, w)`` batch."""
    device = x.device
    if not tta:
        with autocast(precision, device):
            return model(x)[:, 0].float()
    if x.shape[-1] != x.shape[-2]:
        raise ValueError(f"test-time augmentation needs square rasters, got {tuple(x.shape[-2:])}")
    vectors = model.config.vector_channels
    views = torch.cat([transform_vector_channels(apply_symmetry(x, *s), vectors, *s)
                       for s in SYMMETRIES])  # (8B, C, h, w)
    with autocast(precision, device):
        maps = model(views.contiguous(memory_format=torch.channels_last))[:, 0].float()  # (8B, h, w)
    b = len(x)
    return torch.stack([invert_symmetry(maps[i * b:(i + 1) * b], *s)
                        for i, s in enumerate(SYMMETRIES)]).mean(dim=0)  # (B, h, w)


def _batches(inputs: np.ndarray, batch_size: int) -> Iterator[np.ndarray]:
    for start in range(0, len(inputs), batch_size):
        yield inputs[start:start + batch_size]


@torch.inference_mode()
def utility_maps(model: UtilityNet, inputs: np.ndarray, precision: Precision = "float32", tta: bool = False,
                 batch_size: int = 64) -> np.ndarray:
    """The ``(n, h, w)`` float32 utility maps of ``(n, C, h, w)`` rasters.

    Args:
        model: A utility network (set to eval mode).
        inputs: The rasters.
        precision: ``"float32"`` or ``"bfloat16"`` (autocast; see :mod:`learning.precision`).
        tta: Average the maps of the 8 grid symmetries (square rasters only).
        batch_size: Rasters per forward pass (times 8 with ``tta``).

    Raises:
        ValueError: ``inputs`` is not ``(n, C, h, w)`` with the model's channel count, or
            ``tta`` with a non-square raster.
    """
    inputs = np.asarray(inputs, dtype=np.float32)
    if inputs.ndim != 4 or inputs.shape[1] != model.config.in_channels:
        raise ValueError(f"inputs shape {inputs.shape} must be (n, C={model.config.in_channels}, h, w)")
    model.eval()
    device = next(model.parameters()).device
    out = [_forward(model, torch.from_numpy(chunk).to(device).contiguous(memory_format=torch.channels_last),
                    precision, tta).cpu().numpy() for chunk in _batches(inputs, batch_size)]
    return np.concatenate(out) if out else np.zeros((0, *inputs.shape[-2:]), dtype=np.float32)


def utility_map(model: UtilityNet, raster: np.ndarray, precision: Precision = "float32", tta: bool = False
                ) -> np.ndarray:
    """The ``(h, w)`` float32 utility map of one ``(C, h, w)`` raster.

    Raises:
        ValueError: ``raster`` is not ``(C, h, w)`` with the model's channel count.
    """
    raster = np.asarray(raster, dtype=np.float32)
    if raster.ndim != 3 or raster.shape[0] != model.config.in_channels:
        raise ValueError(f"raster shape {raster.shape} must be (C={model.config.in_channels}, h, w)")
    return utility_maps(model, raster[None], precision, tta)[0]


def predict_positions(model: UtilityNet, raster: np.ndarray, k: int = 10, peaks: PeakConfig | None = None,
                      precision: Precision = "float32", tta: bool = False) -> np.ndarray:
    """Placement for one raster: the at most ``k`` peaks of the model's utility map.

    Args:
        model: A trained utility network (e.g. ``load_checkpoint(path).model``).
        raster: ``(C, h, w)`` observation.
        k: Most positions to return (the UAVs available).
        peaks: Peak extraction settings; the checkpoint's ``peak_config`` is the
            one validated in training.
        precision: Network precision (see :func:`utility_maps`).
        tta: Test-time augmentation (see :func:`utility_maps`).

    Returns:
        ``(m, 2)`` float64 pixel positions ``(x=column, y=row)``, ``m <= k``, by decreasing utility.
    """
    return find_peaks(utility_map(model, raster, precision, tta), peaks, max_peaks=k)
