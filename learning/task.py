"""The Task protocol: what a mission must provide to be learned from demonstration.

Coordinates: every position that crosses this interface is in **pixel
coordinates** of the observation raster, as floats ``(x, y) = (column, row)``,
with the centre of pixel ``[row i, column j]`` at ``(x=j, y=i)``. A task converts
to and from its own units (metres, polygon coordinates) internally.

A scene must be reproducible from the generator it was sampled with, so a
dataset stores one seed per sample and evaluation regenerates scenes from it.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np

from typed_config import Config

__all__ = ["Task", "Refiner", "MAX_POSITIONS"]

MAX_POSITIONS = 10
"""The largest number of positions (UAVs, guards) an expert may place."""


@runtime_checkable
class Task(Protocol):
    """A mission: scenes, their raster observation, the expert and the QoS.

    Attributes:
        name: Registry name, e.g. ``"wifi-s1"``.
        config: The task's validated config (saved in shards and checkpoints).
        channels: Number of observation channels C.
        shape: Raster shape ``(h, w)``.
        mission_dimension_px: The mission's size in pixels; the match radius
            ε of the metrics is 10 % of it.

    A task whose observation holds vector components (a velocity field, say) may also have
    ``vector_channels``: their channel indices as ``(x, y)`` pairs, flattened; augmentation and
    test-time augmentation turn them with the raster (:func:`learning.symmetry.transform_vector_channels`).
    """

    name: str
    config: Config
    channels: int
    shape: tuple[int, int]
    mission_dimension_px: float

    def sample(self, rng: np.random.Generator) -> Any:
        """Draw one scene using only ``rng``."""
        ...

    def observe(self, scene: Any) -> np.ndarray:
        """The scene as a ``float32`` array of shape ``(C, h, w)``."""
        ...

    def expert(self, scene: Any) -> np.ndarray:
        """The expert placement: ``float64`` array ``(k, 2)`` of pixel ``(x, y)``, ``0 <= k <= 10``."""
        ...

    def qos(self, scene: Any, positions_px: np.ndarray) -> dict[str, float]:
        """Quality of service of a placement on the real scene.

        Returns a dict with at least the key ``"qos"`` (in [0, 1]); tasks may add
        more (e.g. mean throughput, mean seen fraction).
        """
        ...


@runtime_checkable
class Refiner(Protocol):
    """Mission knowledge that turns learned positions into a placement obeying the mission's rules.

    Evaluation (``evaluate(..., refiner=...)``) reports the refined placement beside the pure
    learned one, and times both against the expert solving the scene from scratch.
    """

    @property
    def config(self) -> Config:
        """The refinement's settings (printed beside its results)."""

    def refine(self, scene: Any, positions_px: np.ndarray) -> np.ndarray:
        """The refined ``(k, 2)`` float64 pixel positions ``(x, y)`` starting from ``positions_px``."""
        ...

    def solve(self, scene: Any) -> np.ndarray:
        """The expert's placement computed from scratch (what the refinement is timed against)."""
        ...


@runtime_checkable
class PlacementCheck(Protocol):
    """Mission knowledge applied to learned positions using only the observation the network saw.

    Evaluation (``evaluate(..., check=...)``) extracts the peaks at ``threshold_abs`` and keeps what
    the check returns (for the Wi-Fi missions: the UAVs their deployment rule justifies).
    """

    threshold_abs: float

    def __call__(self, observation: np.ndarray, positions_px: np.ndarray) -> np.ndarray:
        """The checked ``(k', 2)`` float64 pixel positions ``(x, y)`` among ``positions_px``."""
        ...

    def settings(self) -> dict[str, Any]:
        """The check's settings, for results files."""
        ...
