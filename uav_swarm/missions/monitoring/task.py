"""Building monitoring missions as :class:`learning.task.Task`: Art Gallery (``agp``) and Fortress (``fp``).

A scene is one random simple polygon (:mod:`uav_swarm.missions.monitoring.polygons`) on a
``size_px`` x ``size_px`` raster (64 by default) together with its exact expert placement
(:mod:`uav_swarm.missions.monitoring.guards`), solved when the scene is sampled: a polygon whose
Fortress instance is infeasible on the pixel grid (a boundary point no exterior pixel
centre sees) or whose optimum needs more than ``max_guards`` guards is redrawn from the same
generator, so every sampled scene has a valid expert and ``expert(scene)`` costs nothing.

Positions are pixel coordinates ``(x=col, y=row)`` of the raster, pixel centres at integers.

Observation (``float32``, shape ``(2, size, size)``):

* channel 0, **filled**: 1 where the pixel centre lies in the closed polygon (exactly the
  Art Gallery candidates and witnesses), else 0;
* channel 1, **outline**: 1 where the boundary passes through the pixel's square (each edge
  sampled every 0.1 px and rounded to the nearest pixel), else 0. Thin spikes with no
  pixel centre inside still show here.

QoS of a placement (:meth:`ArtGalleryTask.qos`, :meth:`FortressTask.qos`): positions are
rounded to the nearest pixel centre and clipped to the raster; a rounded position counts as
a guard only where the mission allows one (Art Gallery: in the closed polygon; Fortress:
strictly outside it), others see nothing. ``"seen_fraction"`` is the share of the expert's
witnesses (interior pixel centres, or boundary points) seen by some guard and ``"qos"`` is
1.0 when all are seen (the building is perfectly covered), else 0.0. The expert scores 1.0.

``mission_dimension_px`` is the raster side (64): the metrics' match radius is 10 % of it.

Examples:
    >>> task = ArtGalleryTask(MonitoringConfig(polygon=PolygonConfig(max_vertices=8)))
    >>> scene = task.sample(np.random.default_rng(0))
    >>> task.observe(scene).shape, task.qos(scene, task.expert(scene))["qos"]
    ((2, 64, 64), 1.0)
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from learning.symmetry import transform_positions
from learning.task import MAX_POSITIONS
from typed_config import Config, param
from uav_swarm.missions.monitoring.guard_repair import RepairConfig, repair_guards
from uav_swarm.missions.monitoring.guards import (
    GuardProblem,
    art_gallery_problem,
    boundary_points,
    fortress_problem,
    interior_pixels,
    solve_guards,
)
from uav_swarm.missions.monitoring.polygons import (
    Polygon,
    PolygonConfig,
    PolygonSamplingError,
    locate_points,
    random_polygon,
)
from uav_swarm.missions.monitoring.setcover import InfeasibleCoverError
from uav_swarm.missions.monitoring.visibility import Region, visibility_matrix

__all__ = [
    "MonitoringConfig",
    "FortressConfig",
    "MonitoringScene",
    "ArtGalleryTask",
    "FortressTask",
    "GuardRefiner",
    "rasterize_polygon",
]

logger = logging.getLogger(__name__)

_OUTLINE_STEP_PX = 0.1
"""Sampling step along edges when drawing the outline channel."""


@dataclass(frozen=True)
class MonitoringConfig(Config):
    """Config of the Art Gallery task (and the base of the Fortress one)."""

    polygon: PolygonConfig = param(PolygonConfig(), doc="how buildings are drawn (table [task.polygon])")
    max_guards: int = param(
        MAX_POSITIONS, ge=1, le=MAX_POSITIONS, doc="buildings whose optimum needs more guards are redrawn")
    max_redraws: int = param(100, ge=1, le=100_000, doc="buildings drawn per scene before giving up")


@dataclass(frozen=True)
class FortressConfig(MonitoringConfig):
    """Config of the Fortress task."""

    boundary_spacing_px: float = param(
        1.0, ge=0.1, le=8.0, doc="largest distance between boundary witnesses along an edge (pixels)")


@dataclass(frozen=True, eq=False)
class MonitoringScene:
    """One building and its expert placement.

    Attributes:
        polygon: The building.
        guards_px: ``(k, 2)`` float64 read-only expert guard positions ``(x, y)``, sorted by row then column.
    """

    polygon: Polygon
    guards_px: np.ndarray


def _scene(polygon: Polygon, guards_px: np.ndarray) -> MonitoringScene:
    """A scene with its guards sorted by row, then column."""
    guards = guards_px[np.lexsort((guards_px[:, 0], guards_px[:, 1]))]
    guards.setflags(write=False)
    return MonitoringScene(polygon, guards)


def rasterize_polygon(polygon: Polygon) -> np.ndarray:
    """The observation channels of a building: ``(2, size, size)`` float32 filled and outline.

    Args:
        polygon: The building.
    """
    size = polygon.size_px
    filled = (polygon.pixel_locations() >= 0).astype(np.float32)
    edges = polygon.edges_px
    lengths = np.hypot(edges[:, 2] - edges[:, 0], edges[:, 3] - edges[:, 1])
    steps = np.ceil(lengths / _OUTLINE_STEP_PX).astype(np.int64)
    edge = np.repeat(np.arange(len(edges)), steps + 1)
    first = np.concatenate([[0], np.cumsum(steps + 1)[:-1]])
    t = (np.arange(len(edge)) - first[edge]) / steps[edge]
    points = edges[edge, :2] + (edges[edge, 2:] - edges[edge, :2]) * t[:, None]
    cols, rows = np.clip(np.rint(points), 0, size - 1).astype(np.int64).T
    outline = np.zeros((size, size), dtype=np.float32)
    outline[rows, cols] = 1.0
    return np.stack([filled, outline])


class _MonitoringTask:
    """Sampling, observation, expert and QoS shared by both missions; subclasses set the region."""

    name: str
    config_class: type[MonitoringConfig]
    region: Region
    channels = 2
    refiner_class: type[GuardRefiner]

    def __init__(self, config: MonitoringConfig | None = None) -> None:
        config = self.config_class() if config is None else config
        if not isinstance(config, self.config_class):
            raise TypeError(
                f"{type(self).__name__} needs a {self.config_class.__name__}, got {type(config).__name__}")
        self.config = config
        size = config.polygon.size_px
        self.shape = (size, size)
        self.mission_dimension_px = float(size)

    def problem(self, polygon: Polygon) -> GuardProblem:
        """The discretised guarding instance of ``polygon``."""
        raise NotImplementedError

    def witnesses(self, polygon: Polygon) -> np.ndarray:
        """``(W, 2)`` the points a placement must see."""
        raise NotImplementedError

    def sample(self, rng: np.random.Generator) -> MonitoringScene:
        """Draw a building with a valid expert placement (see the module docstring).

        Raises:
            PolygonSamplingError: ``max_redraws`` buildings in a row were infeasible or needed
                more than ``max_guards`` guards.
        """
        for _ in range(self.config.max_redraws):
            polygon = random_polygon(rng, self.config.polygon)
            problem = self.problem(polygon)
            try:
                chosen = solve_guards(problem)
            except InfeasibleCoverError as exc:
                logger.debug("%s: redrawing an infeasible building: %s", self.name, exc)
                continue
            if len(chosen) > self.config.max_guards:
                logger.debug("%s: redrawing a building needing %d guards", self.name, len(chosen))
                continue
            return _scene(polygon, problem.candidates_px[chosen])
        raise PolygonSamplingError(
            f"{self.name}: {self.config.max_redraws} buildings in a row were infeasible or needed more than "
            f"max_guards = {self.config.max_guards} guards (raise max_redraws or max_guards)")

    def transform_scene(self, scene: MonitoringScene, flip_x: bool, flip_y: bool, transpose: bool
                        ) -> MonitoringScene:
        """The building under a symmetry of the raster (:mod:`learning.symmetry`), its expert solved anew."""
        vertices = transform_positions(scene.polygon.vertices_px, self.shape, flip_x, flip_y, transpose)
        polygon = Polygon(vertices, scene.polygon.size_px)
        problem = self.problem(polygon)
        return _scene(polygon, problem.candidates_px[solve_guards(problem)])

    def observe(self, scene: MonitoringScene) -> np.ndarray:
        """``(2, size, size)`` float32: filled polygon and outline (see the module docstring)."""
        return rasterize_polygon(scene.polygon)

    def expert(self, scene: MonitoringScene) -> np.ndarray:
        """The exact expert's ``(k, 2)`` float64 guard positions ``(x, y)``, ``1 <= k <= max_guards``."""
        return np.array(scene.guards_px, dtype=np.float64)

    def qos(self, scene: MonitoringScene, positions_px: np.ndarray) -> dict[str, float]:
        """Whether the building is fully seen by guards at ``positions_px`` (see the module docstring).

        Args:
            scene: The building.
            positions_px: ``(k, 2)`` predicted positions ``(x, y)`` (any floats).

        Returns:
            ``{"qos": 1.0 or 0.0, "seen_fraction": share of witnesses seen}``.

        Raises:
            ValueError: ``positions_px`` is not ``(k, 2)`` or not finite.
        """
        positions = np.asarray(positions_px, dtype=np.float64)
        if positions.size == 0:
            positions = positions.reshape(0, 2)
        if positions.ndim != 2 or positions.shape[1] != 2 or not np.all(np.isfinite(positions)):
            raise ValueError(f"positions_px must be a finite (k, 2) array, got shape {positions.shape}")
        guards = np.unique(np.clip(np.rint(positions), 0, scene.polygon.size_px - 1), axis=0)
        seen = np.any(self.seen_by(scene.polygon, guards), axis=0)
        fraction = float(np.mean(seen)) if seen.size else 1.0
        return {"qos": float(bool(np.all(seen))), "seen_fraction": fraction}

    def seen_by(self, polygon: Polygon, guards_px: np.ndarray) -> np.ndarray:
        """``(k, W)`` bool: the witnesses each guard sees; a guard where the mission allows none sees nothing.

        Args:
            polygon: The building.
            guards_px: ``(k, 2)`` guard positions on pixel centres (rounded, within the raster).
        """
        guards = np.asarray(guards_px, dtype=np.float64).reshape(-1, 2)
        witnesses = self.witnesses(polygon)
        codes = locate_points(guards, polygon.vertices_px)
        allowed = codes >= 0 if self.region == "interior" else codes < 0
        seen = np.zeros((len(guards), len(witnesses)), dtype=bool)
        seen[allowed] = visibility_matrix(polygon, guards[allowed], witnesses, self.region)
        return seen


class GuardRefiner:
    """Learned guard positions repaired until they see every witness (:mod:`~.monitoring.guard_repair`).

    Args:
        task: The Art Gallery or Fortress task.
        config: The repair's radii and effort; default ``RepairConfig()``.
    """

    config_class = RepairConfig

    def __init__(self, task: _MonitoringTask, config: RepairConfig | None = None) -> None:
        self.task = task
        self.config = config or RepairConfig()

    def refine(self, scene: MonitoringScene, positions_px: np.ndarray) -> np.ndarray:
        """``(k, 2)`` guards ``(x, y)`` that see every witness of the building, near ``positions_px``."""
        polygon = scene.polygon
        witnesses = self.task.witnesses(polygon)
        return repair_guards(polygon, self.task.region, witnesses, positions_px, self.config).guards_px

    def solve(self, scene: MonitoringScene) -> np.ndarray:
        """The exact expert from scratch: the visibility of every candidate, then the set cover."""
        problem = self.task.problem(scene.polygon)
        return problem.candidates_px[solve_guards(problem)]


class ArtGalleryTask(_MonitoringTask):
    """Art Gallery: fewest guards inside the building seeing all of its interior pixel centres."""

    name = "agp"
    config_class = MonitoringConfig
    region: Region = "interior"
    refiner_class = GuardRefiner

    def problem(self, polygon: Polygon) -> GuardProblem:
        """Interior pixel centres guarding interior pixel centres."""
        return art_gallery_problem(polygon)

    def witnesses(self, polygon: Polygon) -> np.ndarray:
        """The interior pixel centres (boundary included)."""
        return interior_pixels(polygon)


class FortressTask(_MonitoringTask):
    """Fortress: fewest guards outside the building seeing all of its boundary."""

    name = "fp"
    config_class = FortressConfig
    region: Region = "exterior"
    refiner_class = GuardRefiner
    config: FortressConfig

    def problem(self, polygon: Polygon) -> GuardProblem:
        """Exterior pixel centres guarding boundary points."""
        return fortress_problem(polygon, self.config.boundary_spacing_px)

    def witnesses(self, polygon: Polygon) -> np.ndarray:
        """Vertices and points every ``boundary_spacing_px`` along the edges."""
        return boundary_points(polygon, self.config.boundary_spacing_px)
