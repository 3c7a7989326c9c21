"""The 8 symmetries of the square raster, on pixel positions (torch-free, for tasks and probes alike).

A symmetry is ``(flip_x, flip_y, transpose)``: the columns are mirrored, then the rows,
then the axes swapped, as :class:`learning.loader.ShardDataset` augments its rasters.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["Symmetry", "SYMMETRIES", "transform_positions", "inverse_transform_positions",
           "transform_vector_channels"]

Symmetry = tuple[bool, bool, bool]
"""``(flip_x, flip_y, transpose)``."""

SYMMETRIES: tuple[Symmetry, ...] = tuple((flip_x, flip_y, transpose) for flip_x, flip_y, transpose
                                         in itertools.product((False, True), repeat=3))
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


def transform_vector_channels(x: Any, vector_channels: Sequence[int], flip_x: bool, flip_y: bool,
                              transpose: bool) -> Any:
    """Channels that hold a vector field's components, turned with the raster transform.

    A raster transform moves pixels; a channel that holds the x or y component of a vector (a
    velocity, say) must also turn: a flip along x negates the x component, a flip along y the y
    component, a transposition swaps the two. Apply this after moving the pixels.

    Args:
        x: ``(..., C, h, w)`` numpy array or torch tensor (not modified).
        vector_channels: Pairs of channel indices, flattened: ``(x0, y0, x1, y1, ...)``.
        flip_x: Mirror the columns.
        flip_y: Mirror the rows.
        transpose: Swap the axes.

    Returns:
        A new array (or tensor) when ``vector_channels`` is not empty, else ``x`` itself.

    Examples:
        >>> v = np.zeros((3, 1, 1)); v[1], v[2] = 1.0, 2.0
        >>> transform_vector_channels(v, (1, 2), True, False, True)[:, 0, 0].tolist()
        [0.0, 2.0, -1.0]
    """
    if len(vector_channels) == 0:
        return x
    if len(vector_channels) % 2:
        raise ValueError(f"vector_channels = {tuple(vector_channels)} must hold (x, y) pairs")
    out = x.clone() if hasattr(x, "clone") else np.array(x, copy=True)
    for cx, cy in zip(vector_channels[::2], vector_channels[1::2], strict=True):
        vx = -x[..., cx, :, :] if flip_x else x[..., cx, :, :] * 1
        vy = -x[..., cy, :, :] if flip_y else x[..., cy, :, :] * 1
        if transpose:
            vx, vy = vy, vx
        out[..., cx, :, :] = vx
        out[..., cy, :, :] = vy
    return out
