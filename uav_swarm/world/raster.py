"""From metres to rasters: pedestrian density maps and the metre <-> pixel mapping.

A raster of ``shape = (h, w)`` covers the area ``[0, width_m] x [0, height_m]``; row ``i``
covers ``y`` in ``[i * h_px, (i + 1) * h_px)`` and column ``j`` covers ``x`` in
``[j * w_px, (j + 1) * w_px)``, with ``w_px = width_m / w`` and ``h_px = height_m / h``
(row 0 is the South edge). Pixel coordinates are ``(x = column, y = row)`` floats whose
integer values are pixel centres: pixel ``(j, i)`` is centred on
``((j + 0.5) * w_px, (i + 0.5) * h_px)`` metres.

Examples:
    >>> import numpy as np
    >>> density_map(np.array([[1.0, 1.0], [1.5, 0.2], [9.9, 9.9]]), 10.0, 10.0, (2, 2)).tolist()
    [[2.0, 0.0], [0.0, 1.0]]
    >>> density_maps(np.array([[1.0, 1.0], [9.9, 9.9]]), np.array([0, 1]), 2, 10.0, 10.0, (1, 1)).tolist()
    [[[1.0]], [[1.0]]]
    >>> metres_to_pixels(np.array([[2.5, 7.5]]), 10.0, 10.0, (2, 2)).tolist()
    [[0.0, 1.0]]
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["density_map", "density_maps", "metres_to_pixels", "pixels_to_metres"]


def _check_shape(shape: tuple[int, int]) -> tuple[int, int]:
    if len(shape) != 2 or min(shape) < 1:
        raise ValueError(f"shape must be (h, w) with h, w >= 1, got {shape}")
    return int(shape[0]), int(shape[1])


def _check_area(width_m: float, height_m: float) -> None:
    if not (width_m > 0 and height_m > 0):
        raise ValueError(f"width_m and height_m must be > 0, got {width_m} x {height_m}")


def _check_points(name: str, points: np.ndarray) -> np.ndarray:
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 2:
        raise ValueError(f"{name} must have shape (k, 2), got {points.shape}")
    return points


def density_map(
    positions_m: np.ndarray, width_m: float, height_m: float, shape: tuple[int, int],
    weights: np.ndarray | None = None,
) -> np.ndarray:
    """Count the pedestrians in each pixel (or sum a value of theirs).

    Points on the far edges (``x == width_m`` or ``y == height_m``) count in the last
    column or row; points outside the area are not counted.

    Args:
        positions_m: (N, 2) positions in metres.
        width_m: Area width (x extent) in metres.
        height_m: Area height (y extent) in metres.
        shape: Raster shape ``(h, w)``.
        weights: Optional ``(N,)`` value of each pedestrian summed instead of counting 1
            (a velocity component gives the momentum density).

    Returns:
        (h, w) float32 counts (or sums of ``weights``) of pedestrians per pixel.

    Raises:
        ValueError: Bad shape, area or positions array.
    """
    h, w = _check_shape(shape)
    _check_area(width_m, height_m)
    positions_m = _check_points("positions_m", positions_m)
    if weights is not None:
        weights = np.asarray(weights, dtype=np.float64).reshape(-1)
        if len(weights) != len(positions_m) or not np.all(np.isfinite(weights)):
            raise ValueError(f"weights must be {len(positions_m)} finite values, got shape {weights.shape}")
    sums = _binned(positions_m, np.zeros(len(positions_m), np.int64),
                   np.ones(1) if weights is None else weights, weights is None, 1, h, w, float(width_m),
                   float(height_m))
    return sums.reshape(h, w).astype(np.float32)


@numba.njit(cache=True, nogil=True)
def _binned(positions_m: np.ndarray, copy_index: np.ndarray, weights: np.ndarray, ones: bool, n_copies: int,
            h: int, w: int, width_m: float, height_m: float) -> np.ndarray:
    """(B * h * w,) float64 sums of the weights (or counts) of the points inside the area, per pixel.

    A point's column is ``min(floor(x * (w / width_m)), w - 1)`` (so the far edge counts in the last
    column), its row likewise; the sums run in the points' order.
    """
    sums = np.zeros(n_copies * h * w)
    col_scale, row_scale = w / width_m, h / height_m
    for n in range(positions_m.shape[0]):
        x, y = positions_m[n, 0], positions_m[n, 1]
        if x >= 0 and x <= width_m and y >= 0 and y <= height_m:
            col = min(int(x * col_scale), w - 1)
            row = min(int(y * row_scale), h - 1)
            sums[(copy_index[n] * h + row) * w + col] += 1.0 if ones else weights[n]
    return sums


def density_maps(
    positions_m: np.ndarray, copy_index: np.ndarray, n_copies: int, width_m: float, height_m: float,
    shape: tuple[int, int],
) -> np.ndarray:
    """:func:`density_map` of B worlds at once, whose points are stacked in one array.

    Args:
        positions_m: (N, 2) positions in metres of all worlds.
        copy_index: (N,) int, the world of each point (``0 <= copy_index < n_copies``).
        n_copies: Number of worlds B.
        width_m: Area width (x extent) in metres, the same for every world.
        height_m: Area height (y extent) in metres.
        shape: Raster shape ``(h, w)``.

    Returns:
        (B, h, w) float32 counts of points per pixel of each world.
    """
    h, w = _check_shape(shape)
    _check_area(width_m, height_m)
    sums = _binned(np.ascontiguousarray(positions_m, dtype=np.float64),
                   np.ascontiguousarray(copy_index, dtype=np.int64), np.ones(1), True, n_copies, h, w,
                   float(width_m), float(height_m))
    return sums.reshape(n_copies, h, w).astype(np.float32)


def metres_to_pixels(
    xy_m: np.ndarray, width_m: float, height_m: float, shape: tuple[int, int]
) -> np.ndarray:
    """Convert positions in metres to pixel coordinates ``(x = column, y = row)``.

    Args:
        xy_m: (k, 2) positions in metres.
        width_m: Area width in metres.
        height_m: Area height in metres.
        shape: Raster shape ``(h, w)``.

    Returns:
        (k, 2) float64 pixel coordinates (integers at pixel centres).
    """
    h, w = _check_shape(shape)
    _check_area(width_m, height_m)
    xy_m = _check_points("xy_m", xy_m)
    scale = np.array([w / width_m, h / height_m])
    return xy_m * scale - 0.5


def pixels_to_metres(
    xy_px: np.ndarray, width_m: float, height_m: float, shape: tuple[int, int]
) -> np.ndarray:
    """Convert pixel coordinates ``(x = column, y = row)`` to metres (inverse of :func:`metres_to_pixels`).

    Args:
        xy_px: (k, 2) pixel coordinates.
        width_m: Area width in metres.
        height_m: Area height in metres.
        shape: Raster shape ``(h, w)``.

    Returns:
        (k, 2) float64 positions in metres.
    """
    h, w = _check_shape(shape)
    _check_area(width_m, height_m)
    xy_px = _check_points("xy_px", xy_px)
    scale = np.array([width_m / w, height_m / h])
    return (xy_px + 0.5) * scale
