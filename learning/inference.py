"""Fast single-raster inference for the planner: raster -> utility map -> positions.

A replan has a budget of a few milliseconds, so this path avoids autograd
(``torch.inference_mode``), keeps the model on its device in eval mode, and
reuses the CoordConv grid that the model builds once per raster shape.
"""

from __future__ import annotations

import numpy as np
import torch

from learning.model import UtilityNet
from learning.peaks import PeakConfig, find_peaks

__all__ = ["utility_map", "predict_positions"]


@torch.inference_mode()
def utility_map(model: UtilityNet, raster: np.ndarray) -> np.ndarray:
    """The ``(h, w)`` float32 utility map of one ``(C, h, w)`` raster.

    Raises:
        ValueError: ``raster`` is not ``(C, h, w)`` with the model's channel count.
    """
    raster = np.asarray(raster, dtype=np.float32)
    if raster.ndim != 3 or raster.shape[0] != model.config.in_channels:
        raise ValueError(f"raster shape {raster.shape} must be (C={model.config.in_channels}, h, w)")
    if model.training:
        model.eval()
    device = next(model.parameters()).device
    x = torch.from_numpy(raster)[None].to(device)  # (1, C, h, w)
    return model(x)[0, 0].float().cpu().numpy()  # (h, w)


def predict_positions(model: UtilityNet, raster: np.ndarray, k: int = 10, peaks: PeakConfig | None = None
                      ) -> np.ndarray:
    """Placement for one raster: the at most ``k`` peaks of the model's utility map.

    Args:
        model: A trained utility network (e.g. ``load_checkpoint(path).model``).
        raster: ``(C, h, w)`` observation.
        k: Most positions to return (the UAVs available).
        peaks: Peak extraction settings; the checkpoint's ``peak_config`` is the
            one validated in training.

    Returns:
        ``(m, 2)`` float64 pixel positions ``(x=column, y=row)``, ``m <= k``, by decreasing utility.
    """
    return find_peaks(utility_map(model, raster), peaks, max_peaks=k)
