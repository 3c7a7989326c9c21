"""Choosing the peak thresholds on the validation split.

A utility network trained by MSE learns the wide Gaussian of its targets long before the sharp
one: early in training (and on small budgets) its peaks stand lower and less sharply than
the ``1 + α2/α1`` of the targets, and fixed thresholds then find no peak at all. The
thresholds of non-maximum suppression are inference settings, not weights, so they are chosen
where the paper leaves them open: on the validation split, by the same score that selects the
best epoch (correspondence + precision), over a small grid of ``threshold_abs`` and
``min_contrast`` values (``min_distance_px``, ``threshold_rel`` and ``max_peaks`` stay as
configured). Ties go to the first grid point (lowest threshold, then lowest contrast), so the
choice is deterministic.

Examples:
    >>> u = np.zeros((16, 16)); u[4, 4] = 0.3; u[11, 11] = 0.2
    >>> best, _ = calibrate_peaks([u], [np.array([[4.0, 4.0], [11.0, 11.0]])], 1.6, PeakConfig())
    >>> best.threshold_abs <= 0.2
    True
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from learning.metrics import aggregate, score_sample
from learning.peaks import PeakConfig, find_peaks
from typed_config import Config, ConfigError, param

__all__ = ["CalibrationConfig", "calibrate_peaks"]


@dataclass(frozen=True)
class CalibrationConfig(Config):
    """The grid of peak thresholds tried on the validation split (utility-map units)."""

    thresholds: tuple[float, ...] = param(
        (0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.7), doc="threshold_abs values tried")
    contrasts: tuple[float, ...] = param((0.0, 0.02, 0.05, 0.1, 0.2), doc="min_contrast values tried")

    def check(self) -> None:
        """Both grids are non-empty and the contrasts are >= 0."""
        if not self.thresholds or not self.contrasts:
            raise ConfigError("CalibrationConfig.thresholds and .contrasts must each hold at least one value")
        if min(self.contrasts) < 0.0:
            raise ConfigError(f"CalibrationConfig.contrasts = {self.contrasts}: values must be >= 0")


def calibrate_peaks(
    utilities: Sequence[np.ndarray],
    experts: Sequence[np.ndarray],
    eps_px: float,
    base: PeakConfig,
    grid: CalibrationConfig | None = None,
    rasters: Sequence[np.ndarray] | None = None,
) -> tuple[PeakConfig, dict[str, float]]:
    """The peak settings that maximise correspondence + precision on ``utilities``.

    Args:
        utilities: ``(h, w)`` utility maps of the validation samples.
        experts: The matching ``(k, 2)`` expert positions (pixels).
        eps_px: Match radius.
        base: The configured settings; only ``threshold_abs`` and ``min_contrast`` change.
        grid: The values tried; default ``CalibrationConfig()``.
        rasters: The samples' ``(C, h, w)`` inputs (needed when ``base.region`` is not ``"any"``).

    Returns:
        The chosen config and its aggregate scores (``corr``, ``precision``, ...).

    Raises:
        ValueError: ``utilities`` and ``experts`` differ in length or are empty.
    """
    if len(utilities) != len(experts) or not utilities:
        raise ValueError(f"need as many utility maps as expert placements, >= 1 "
                         f"(got {len(utilities)} and {len(experts)})")
    grid = grid or CalibrationConfig()
    inputs = list(rasters) if rasters is not None else [None] * len(utilities)
    best: tuple[float, PeakConfig, dict[str, float]] | None = None
    for threshold in sorted(grid.thresholds):
        for contrast in sorted(grid.contrasts):
            config = base.replace(threshold_abs=threshold, min_contrast=contrast)
            summary = aggregate(score_sample(expert, find_peaks(u, config, raster=x), eps_px)
                                for u, expert, x in zip(utilities, experts, inputs, strict=True))
            score = summary["corr"] + summary["precision"]
            if best is None or score > best[0]:
                best = (score, config, summary)
    assert best is not None
    return best[1], best[2]
