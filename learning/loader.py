"""A torch Dataset over dataset shards that renders the target maps on the fly.

Each item is ``(input (C, h, w) float32, target (1, h, w) float32)`` with the target
``R(ζ) / α1`` (see :mod:`learning.targets`). Optional augmentation applies one
of the 8 symmetries of the square grid (flips and, for square rasters,
transposition) to the input and the expert positions alike; it is off by default
because a task may not be symmetric (e.g. a position-dependent rule). The
augmentation of item ``i`` in epoch ``e`` is drawn from
``default_rng((augment_seed, e, i))``, so it is reproducible with any number of
loader workers.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torch.utils.data import Dataset

from learning.symmetry import transform_positions, transform_vector_channels
from learning.targets import TargetConfig, render_peak_heatmap, render_targets

__all__ = ["ShardDataset"]


class ShardDataset(Dataset):
    """Samples of a dataset held in memory, with targets rendered per item.

    Args:
        arrays: The dataset's arrays, as returned by :func:`learning.data.load_arrays`.
        targets: The target Gaussians.
        indices: The rows to expose (e.g. the training part of a split); all by default.
        augment: Apply random grid symmetries.
        augment_seed: Seed of the augmentation draws.
        peak_heatmaps: Also return each item's keypoint heatmap
            (:func:`learning.targets.render_peak_heatmap`, width ``targets.sigma1``), for a peak head.
        vector_channels: Input channels holding vector components (``(x, y)`` pairs flattened), turned
            with each symmetry (:func:`learning.symmetry.transform_vector_channels`).
    """

    def __init__(self, arrays: dict[str, np.ndarray], targets: TargetConfig,
                 indices: Sequence[int] | np.ndarray | None = None, augment: bool = False,
                 augment_seed: int = 0,
                 peak_heatmaps: bool = False, vector_channels: Sequence[int] = ()) -> None:
        self.inputs = arrays["inputs"]
        self.positions = arrays["positions"]
        self.mask = arrays["mask"]
        self.indices = np.arange(len(self.inputs)) if indices is None else np.asarray(indices, dtype=np.int64)
        self.targets = targets
        self.augment = augment
        self.augment_seed = augment_seed
        self.peak_heatmaps = peak_heatmaps
        self.vector_channels = tuple(vector_channels)
        self.epoch = 0

    def set_epoch(self, epoch: int) -> None:
        """Select the augmentation draws of ``epoch`` (call before creating the epoch's iterator)."""
        self.epoch = epoch

    def __len__(self) -> int:
        return len(self.indices)

    def expert(self, item: int) -> np.ndarray:
        """The ``(k, 2)`` expert positions of item ``item`` (no augmentation)."""
        row = self.indices[item]
        return self.positions[row][self.mask[row]]

    def __getitem__(self, item: int) -> tuple[torch.Tensor, ...]:
        """``(input (C, h, w), target (1, h, w))``, and the ``(1, h, w)`` heatmap with ``peak_heatmaps``."""
        row = int(self.indices[item])
        x = self.inputs[row]  # (C, h, w)
        positions = self.positions[row][self.mask[row]]  # (k, 2)
        shape = x.shape[-2:]
        if self.augment:
            rng = np.random.default_rng((self.augment_seed, self.epoch, row))
            flip_x, flip_y = rng.random(2) < 0.5
            transpose = bool(shape[0] == shape[1] and rng.random() < 0.5)
            x = x[:, :, ::-1] if flip_x else x
            x = x[:, ::-1, :] if flip_y else x
            x = x.transpose(0, 2, 1) if transpose else x
            x = transform_vector_channels(x, self.vector_channels, bool(flip_x), bool(flip_y), transpose)
            positions = transform_positions(positions, shape, bool(flip_x), bool(flip_y), transpose)
        target = render_targets(positions, shape, self.targets) / np.float32(self.targets.alpha1)  # (h, w)
        tensors: tuple[torch.Tensor, ...] = (torch.from_numpy(np.ascontiguousarray(x)),
                                             torch.from_numpy(target[None]))
        if self.peak_heatmaps:
            heatmap = render_peak_heatmap(positions, shape, self.targets.sigma1)  # (h, w)
            tensors += (torch.from_numpy(heatmap[None]),)
        return tensors
