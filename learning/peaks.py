"""Peak extraction: the local maxima of a utility map are the placements.

A pixel is a candidate when it equals the maximum of its
``(2·min_distance_px + 1)²`` window (border pixels compare only with the pixels
that exist), reaches the thresholds, and stands at least ``min_contrast`` above
the minimum of the same window (this rejects the broad, flat maxima that the wide
target Gaussian creates between experts). Equal-valued 8-connected candidates
(plateaus) give one peak at their centroid. Candidates are then taken by
decreasing value, dropping any closer than ``min_distance_px`` to one already
taken (non-maximum suppression), up to ``max_peaks``. A single-pixel peak is
refined to sub-pixel precision by a 1-D parabola through it and its two
neighbours along each axis (skipped on the border, where a neighbour is missing).
With ``min_separation_px`` a peak is also dropped when its refined position stands closer than that to
a peak already taken, so the returned peaks are that far apart (the UAVs' minimum separation).

``region`` restricts the peaks to the pixels where the mission allows a position, read from the input
raster's first channel (the monitoring missions' filled building): ``"filled"`` keeps the pixels where it
is 1 (an Art Gallery guard stands inside), ``"empty"`` those where it is 0 (a Fortress guard stands
outside). The other pixels take the map's floor (``min(map, 0)``) before the window filters, so a high
value across a wall neither becomes a peak nor suppresses the best allowed pixel beside it; the returned
positions round to allowed pixel centres (a plateau's centroid is moved to its nearest allowed pixel).

Thresholds are in the utility map's units: the network regresses ``R / α1``
(see :mod:`learning.targets`), so an isolated expert peaks near ``1 + α2/α1``.
Cost on a 64×64 map: about 0.1-0.2 ms, two ``scipy.ndimage`` window filters; regions are labelled
only when two candidates touch (a network's output rarely has plateaus).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from typed_config import Config, ConfigError, param

__all__ = ["PEAK_REGIONS", "PeakConfig", "allowed_pixels", "find_peaks"]

PEAK_REGIONS = ("any", "filled", "empty")
"""Where a peak may stand: anywhere, or on the pixels where the input's first channel is 1 or 0."""

_EIGHT_CONNECTED = np.ones((3, 3), dtype=bool)


@dataclass(frozen=True)
class PeakConfig(Config):
    """Non-maximum suppression settings (values in utility-map units)."""

    threshold_abs: float = param(0.5, doc="a peak's value must be at least this")
    threshold_rel: float = param(0.0, ge=0.0, le=1.0, doc="... and this fraction of the map's maximum")
    min_contrast: float = param(0.25, ge=0.0, doc="a peak must exceed its window's minimum by this much")
    min_distance_px: int = param(2, ge=1, le=64, doc="window half-size, minimum peak distance, px")
    max_peaks: int = param(10, ge=1, le=1000, doc="at most this many peaks (the UAV budget)")
    subpixel: bool = param(True, doc="refine single-pixel peaks with a parabola fit")
    region: str = param("any", doc="where peaks may stand: 'any', or where the input's first channel is "
                        "1 ('filled') or 0 ('empty')")

    def check(self) -> None:
        """``region`` is one of :data:`PEAK_REGIONS`."""
        if self.region not in PEAK_REGIONS:
            raise ConfigError(f"PeakConfig.region = {self.region!r} is not allowed: choose one of "
                              f"{list(PEAK_REGIONS)}")


def allowed_pixels(raster: np.ndarray, region: str) -> np.ndarray | None:
    """``(h, w)`` bool: the pixels where ``region`` lets a peak stand; None for ``"any"``.

    Args:
        raster: The network's ``(C, h, w)`` input; its first channel says filled (1) or empty (0).
        region: One of :data:`PEAK_REGIONS`.

    Examples:
        >>> x = np.zeros((2, 2, 3)); x[0, :, 1] = 1.0
        >>> allowed_pixels(x, "empty").astype(int).tolist()
        [[1, 0, 1], [1, 0, 1]]
    """
    if region == "any":
        return None
    filled = np.asarray(raster)[0] > 0.5
    return filled if region == "filled" else ~filled


def _parabola_offset(left: float, centre: float, right: float) -> float:
    """Vertex offset in [-0.5, 0.5] of the parabola through three equally spaced samples."""
    curvature = left - 2.0 * centre + right
    if curvature >= 0.0:  # flat or not a maximum: no refinement
        return 0.0
    return min(0.5, max(-0.5, float(0.5 * (left - right) / curvature)))


def _has_plateau(candidates: np.ndarray) -> bool:
    """Whether two candidates touch (8-connected), i.e. some region has more than one pixel."""
    return bool(
        (candidates[:, 1:] & candidates[:, :-1]).any()
        or (candidates[1:, :] & candidates[:-1, :]).any()
        or (candidates[1:, 1:] & candidates[:-1, :-1]).any()
        or (candidates[1:, :-1] & candidates[:-1, 1:]).any()
    )


def _nearest_members(centres: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """Region centroids ``(row, col)``; one that rounds off its region moves to its nearest pixel."""
    out = centres.copy()
    for i, (y, x) in enumerate(centres):
        r, c = int(round(y)), int(round(x))
        if labels[r, c] != i + 1:
            rows, cols = np.nonzero(labels == i + 1)
            k = int(np.argmin((rows - y) ** 2 + (cols - x) ** 2))
            out[i] = rows[k], cols[k]
    return out


def find_peaks(utility: np.ndarray, config: PeakConfig | None = None, max_peaks: int | None = None,
               min_separation_px: float = 0.0, raster: np.ndarray | None = None) -> np.ndarray:
    """Local maxima of a utility map after thresholds and non-maximum suppression.

    Args:
        utility: ``(h, w)`` map.
        config: Thresholds and distances; defaults to ``PeakConfig()``.
        max_peaks: Overrides ``config.max_peaks`` (e.g. the number of UAVs available).
        min_separation_px: The returned (refined) peaks stand at least this far apart, pixels.
        raster: The network's ``(C, h, w)`` input; needed when ``config.region`` is not ``"any"``.

    Returns:
        ``(k, 2)`` float64 pixel positions ``(x=column, y=row)``, by decreasing value.

    Raises:
        ValueError: ``utility`` is not a finite 2-D array, ``max_peaks < 0``, or ``config.region``
            needs a ``raster`` of the map's shape that is missing.

    Examples:
        >>> u = np.zeros((9, 9)); u[4, 6] = 1.0; u[4, 5] = u[4, 7] = 0.5
        >>> find_peaks(u).tolist()
        [[6.0, 4.0]]
        >>> x = np.ones((2, 9, 9)); x[0, :, 6:] = 0.0  # the building ends at column 5
        >>> find_peaks(u, PeakConfig(region="filled"), raster=x).tolist()
        [[5.0, 4.0]]
    """
    config = config or PeakConfig()
    limit = config.max_peaks if max_peaks is None else max_peaks
    if limit < 0:
        raise ValueError(f"max_peaks = {limit} must be >= 0")
    u = np.asarray(utility, dtype=np.float64)
    if u.ndim != 2 or not np.all(np.isfinite(u)):
        raise ValueError(f"utility must be a finite 2-D array, got shape {u.shape}")
    if limit == 0 or u.size == 0:
        return np.zeros((0, 2))
    allowed: np.ndarray | None = None
    if config.region != "any":
        if raster is None or np.asarray(raster).shape[1:] != u.shape:
            raise ValueError(f"region = {config.region!r} needs the input raster (C, {u.shape[0]}, "
                             f"{u.shape[1]})")
        allowed = allowed_pixels(raster, config.region)
    if allowed is not None:
        u = np.where(allowed, u, min(float(u.min()), 0.0))
    size = 2 * config.min_distance_px + 1
    local_max = ndimage.maximum_filter(u, size=size, mode="nearest")
    candidates = (u == local_max) & (u >= max(config.threshold_abs, config.threshold_rel * u.max()))
    if config.min_contrast > 0.0:
        local_min = ndimage.minimum_filter(u, size=size, mode="nearest")
        candidates &= u - local_min >= config.min_contrast
    if allowed is not None:
        candidates &= allowed
    if not candidates.any():
        return np.zeros((0, 2))
    rows, cols = np.nonzero(candidates)  # row-major, the order in which ndimage.label numbers regions
    if _has_plateau(candidates):
        labels, n = ndimage.label(candidates, structure=_EIGHT_CONNECTED)
        index = np.arange(1, n + 1)
        values = np.asarray(ndimage.maximum(u, labels, index))
        centres = np.asarray(ndimage.center_of_mass(candidates, labels, index)).reshape(-1, 2)
        if allowed is not None:
            centres = _nearest_members(centres, labels)
        single = np.asarray(ndimage.sum_labels(candidates, labels, index)) == 1
    else:  # every candidate is a region of its own (the usual case on a network's output)
        values = u[rows, cols]
        centres = np.stack([rows, cols], axis=1).astype(np.float64)
        single = np.ones(len(values), dtype=bool)
    order = np.argsort(-values, kind="stable")
    h, w = u.shape
    chosen: list[tuple[float, float]] = []
    for i in order.tolist():
        y, x = float(centres[i, 0]), float(centres[i, 1])
        if any(math.hypot(x - cx, y - cy) < config.min_distance_px for cx, cy in chosen):
            continue
        if config.subpixel and single[i]:
            r, c = int(y), int(x)
            if 0 < c < w - 1:
                x += _parabola_offset(u[r, c - 1], u[r, c], u[r, c + 1])
            if 0 < r < h - 1:
                y += _parabola_offset(u[r - 1, c], u[r, c], u[r + 1, c])
        if any(math.hypot(x - cx, y - cy) < min_separation_px for cx, cy in chosen):
            continue
        chosen.append((x, y))
        if len(chosen) == limit:
            break
    return np.asarray(chosen, dtype=np.float64).reshape(-1, 2)
