"""A tiny synthetic Task for the learning tests: Gaussian blobs whose centres are the expert placement."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from learning.symmetry import transform_positions
from typed_config import Config, param


@dataclass(frozen=True)
class BlobConfig(Config):
    size_px: int = param(32, ge=8, le=256, doc="raster side")
    max_blobs: int = param(4, ge=0, le=10, doc="most blobs per scene")
    blob_sigma_px: float = param(1.5, gt=0.0, doc="blob width")


@dataclass(frozen=True)
class BlobScene:
    centres_px: np.ndarray  # (k, 2) x, y


class BlobTask:
    """Scenes of 0..max_blobs blobs; the expert places one position on each blob centre."""

    name = "blobs"
    config_class = BlobConfig
    channels = 1

    def __init__(self, config: BlobConfig | None = None) -> None:
        self.config = config or BlobConfig()
        self.shape = (self.config.size_px, self.config.size_px)
        self.mission_dimension_px = float(self.config.size_px)

    def sample(self, rng: np.random.Generator) -> BlobScene:
        k = int(rng.integers(0, self.config.max_blobs + 1))
        margin = 3.0
        centres = rng.uniform(margin, self.config.size_px - 1 - margin, size=(k, 2))
        return BlobScene(np.round(centres))

    def observe(self, scene: BlobScene) -> np.ndarray:
        n = self.config.size_px
        ys, xs = np.mgrid[0:n, 0:n]
        image = np.zeros((n, n))
        for x, y in scene.centres_px:
            image += np.exp(-((xs - x) ** 2 + (ys - y) ** 2) / (2 * self.config.blob_sigma_px**2))
        return image[None].astype(np.float32)

    def transform_scene(self, scene: BlobScene, flip_x: bool, flip_y: bool, transpose: bool) -> BlobScene:
        return BlobScene(transform_positions(scene.centres_px, self.shape, flip_x, flip_y, transpose))

    def jitter_scene(self, scene: BlobScene, rng: np.random.Generator, scale: float) -> BlobScene:
        return BlobScene(scene.centres_px + rng.normal(0.0, scale, scene.centres_px.shape))

    def expert(self, scene: BlobScene) -> np.ndarray:
        return scene.centres_px.astype(np.float64).reshape(-1, 2)

    def qos(self, scene: BlobScene, positions_px: np.ndarray) -> dict[str, float]:
        positions = np.asarray(positions_px, dtype=np.float64).reshape(-1, 2)
        if len(scene.centres_px) == 0:
            return {"qos": 1.0}
        if len(positions) == 0:
            return {"qos": 0.0}
        d = np.linalg.norm(scene.centres_px[:, None] - positions[None], axis=-1)
        return {"qos": float(np.mean(d.min(axis=1) <= 2.0))}


def make_blob_task() -> BlobTask:
    """Picklable factory (a top-level function)."""
    return BlobTask()
