"""Target maps: an expert placement rasterised as a sum of two Gaussians per position.

The paper's regression target for a placement ζ (pixel positions) is

    R(ζ)(p) = Σ_{k=1,2} α_k Σ_{x∈ζ} exp(-‖p - x‖² / (2 σ_k²))

with a sharp, high Gaussian (α1 = 255, σ1 = 1 px) that pins the maxima on the
expert positions and a wide, low one (α2, σ2) that keeps a gradient far from them.

Scale convention: :func:`render_targets` returns R in the paper's units (an
isolated expert on a pixel centre peaks at α1 + α2). The network regresses
``R / α1`` (see :func:`learning.data.ShardDataset`), so its utility map peaks near
``1 + α2/α1`` at an isolated expert and the peak thresholds of
:mod:`learning.peaks` are expressed in those normalised units.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from typed_config import Config, param

__all__ = ["TargetConfig", "render_targets", "render_peak_heatmap"]


@dataclass(frozen=True)
class TargetConfig(Config):
    """The two Gaussians of the target map (pixel units)."""

    alpha1: float = param(255.0, gt=0.0, doc="height of the sharp Gaussian")
    sigma1: float = param(1.0, gt=0.0, le=1000.0, doc="width of the sharp Gaussian, pixels")
    alpha2: float = param(50.0, ge=0.0, doc="height of the wide Gaussian (0 disables it)")
    sigma2: float = param(50.0, gt=0.0, le=1000.0, doc="width of the wide Gaussian, pixels")


def render_targets(positions_px: np.ndarray, shape: tuple[int, int], config: TargetConfig) -> np.ndarray:
    """Rasterise positions into the two-Gaussian target map R(ζ).

    The sum is separable, ``exp(-(dx² + dy²)/2σ²) = exp(-dx²/2σ²) · exp(-dy²/2σ²)``,
    so each Gaussian costs one ``(k, h) × (k, w)`` matrix product.

    Args:
        positions_px: ``(k, 2)`` pixel positions ``(x=column, y=row)``; ``k`` may be 0.
        shape: Raster shape ``(h, w)``.
        config: The Gaussians' heights and widths.

    Returns:
        ``(h, w)`` float32 map in the paper's units (an isolated expert on a
        pixel centre peaks at ``alpha1 + alpha2``).

    Examples:
        >>> r = render_targets(np.array([[3.0, 2.0]]), (5, 8), TargetConfig(alpha2=0.0))
        >>> float(r[2, 3]), float(r.max())
        (255.0, 255.0)
    """
    positions_px = np.asarray(positions_px, dtype=np.float64).reshape(-1, 2)
    h, w = shape
    out = np.zeros((h, w), dtype=np.float64)
    if len(positions_px) == 0:
        return out.astype(np.float32)
    dx = np.arange(w, dtype=np.float64)[None, :] - positions_px[:, 0:1]  # (k, w)
    dy = np.arange(h, dtype=np.float64)[None, :] - positions_px[:, 1:2]  # (k, h)
    for alpha, sigma in ((config.alpha1, config.sigma1), (config.alpha2, config.sigma2)):
        if alpha == 0.0:
            continue
        gx = np.exp(-(dx**2) / (2.0 * sigma**2))  # (k, w)
        gy = np.exp(-(dy**2) / (2.0 * sigma**2))  # (k, h)
        out += alpha * (gy.T @ gx)  # (h, w)
    return out.astype(np.float32)


def render_peak_heatmap(positions_px: np.ndarray, shape: tuple[int, int], sigma: float) -> np.ndarray:
    """The keypoint heatmap of a placement: ``max`` over positions of a unit Gaussian of width ``sigma``.

    Positions are rounded to pixel centres first, so each one's pixel is exactly 1 (the positives of
    :func:`learning.losses.focal_loss`), as keypoint detectors such as CenterNet draw them.

    Args:
        positions_px: ``(k, 2)`` pixel positions ``(x, y)``; ``k`` may be 0.
        shape: Raster shape ``(h, w)``.
        sigma: Gaussian width, pixels.

    Returns:
        ``(h, w)`` float32 map in [0, 1].

    Examples:
        >>> m = render_peak_heatmap(np.array([[2.4, 1.0]]), (4, 5), 1.0)
        >>> float(m[1, 2]), round(float(m[1, 3]), 3)
        (1.0, 0.607)
    """
    centres = np.clip(np.rint(np.asarray(positions_px, dtype=np.float64).reshape(-1, 2)), 0,
                      [shape[1] - 1, shape[0] - 1])
    h, w = shape
    if len(centres) == 0:
        return np.zeros((h, w), dtype=np.float32)
    gx = np.exp(-((np.arange(w)[None, :] - centres[:, 0:1]) ** 2) / (2.0 * sigma**2))  # (k, w)
    gy = np.exp(-((np.arange(h)[None, :] - centres[:, 1:2]) ** 2) / (2.0 * sigma**2))  # (k, h)
    return (gy[:, :, None] * gx[:, None, :]).max(axis=0).astype(np.float32)  # (h, w)
