"""The 8 symmetries of the square raster, on pixel positions (torch-free, for tasks and probes alike).

A symmetry is ``(flip_x, flip_y, transpose)``: the columns are mirrored, then the rows,
then the axes swapped, as :class:`learning.loader.ShardDataset` augments its rasters.
"""

from __future__ import annotations

import itertools

import numpy as np

__all__ = ["Symmetry", "SYMMETRIES", "transform_positions", "inverse_transform_positions"]

Symmetry = tuple[bool, bool, bool]
"""``(flip_x, flip_y, transpose)``."""

SYMMETRIES: tuple[Symmetry, ...] = tuple(itertools.product((False, True), repeat=3))
"""All 8, the identity first."""


def transform_positions(positions_px: np.ndarray, shape: tuple[int, int], flip_x: bool, flip_y: bool,
                        transpose: bool) -> np.ndarray:
    """Pixel positions ``(x, y)`` under the raster transform (flips, then transpose).

    Examples:
        >>> transform_positions(np.array([[1.0, 2.0]]), (8, 8), True, False, True).tolist()
        [[2.0, 6.0]]
    """
    h, w = shape
    out = np.array(positions_px, dtype=np.float64).reshape(-1, 2)
    if flip_x:
        out[:, 0] = (w - 1) - out[:, 0]
    if flip_y:
        out[:, 1] = (h - 1) - out[:, 1]
    if transpose:
        out = out[:, ::-1].copy()
    return out


def inverse_transform_positions(positions_px: np.ndarray, shape: tuple[int, int], flip_x: bool, flip_y: bool,
                                transpose: bool) -> np.ndarray:
    """Undo :func:`transform_positions` with the same arguments (transpose first, then the flips)."""
    out = transform_positions(positions_px, shape, False, False, transpose)
    return transform_positions(out, shape, flip_x, flip_y, False)
