"""A user's building in metres: walls, witnesses, guard positions and visibility with a margin.

Its walls, the points a placement must see, where guards may stand, and who sees what, with exact
geometry.

The raster (:mod:`uav_swarm.missions.monitoring.footprint`) is what the network sees; this module is the
truth a placement is judged on. An :class:`Outline` is a polygon in East-North metres, holes
(courtyards) allowed, checked with GEOS (shapely): the outer ring counter-clockwise and the holes
clockwise, so the building's interior is on the left of every wall.

* **Witnesses** (:func:`witnesses`, spacing ``witness_spacing_m``): the Art Gallery's are the points of
  a square grid strictly inside the building (farther than :data:`TOUCH_M` from every wall; courtyards
  excluded) and every vertex; the Fortress's are
  every vertex and points at most the spacing apart along every wall, courtyard walls included.
* **Candidates** (:func:`candidates`): lattice points of the mission's region (inside the building,
  or outside it, courtyards included, within ``reach_m`` of its bounding box) at least ``standoff_m``
  from every wall: a UAV does not hover touching a facade.
* **Visibility** (:func:`visibility`). Guard ``g`` sees witness ``w`` when the segment ``g w``

  1. touches no wall other than the ones ``w`` lies on (so it stays in one region: no crossing, no
     passing through a corner, no running along a wall),
  2. leaves ``w`` into the mission's region (the open side of the wall ``w`` lies on, or the open
     angle of the corner ``w`` is), and
  3. keeps at least ``min_clearance_m`` from every wall farther than ``2 min_clearance_m`` from ``w``
     (no segment ending at ``w`` keeps the margin from a wall nearer ``w`` than the margin, and a witness
     in a short jog of the wall, near-collinear walls a step of about the margin apart, is seen only
     past the step: rule 1 alone applies to the walls near ``w``).

  With ``min_clearance_m > 0`` nothing relies on a grazing line: a guard seeing a wall at a shallow
  angle, or past a corner by a hair, does not see it. ``min_clearance_m = 0`` keeps only rule 1-2.

Distances are computed in float64 on metres, and "touching" means closer than :data:`TOUCH_M`.

Examples:
    >>> outline = Outline.from_rings(np.array([[0.0, 0.0], [20.0, 0.0], [20.0, 10.0], [0.0, 10.0]]))
    >>> points = witnesses(outline, "interior", spacing_m=1.0)
    >>> bool(visibility(outline, np.array([[10.0, 5.0]]), points, 0.5).all())
    True
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import shapely

from uav_swarm.missions.monitoring.sightlines import sees
from uav_swarm.world.geometry import point_segment_distances

__all__ = ["OutlineError", "Outline", "Witnesses", "Region", "witnesses", "candidates", "visibility",
           "TOUCH_M"]

Region = Literal["interior", "exterior"]

TOUCH_M = 1e-7
"""A segment closer than this to a wall touches it (metres; far below any survey's accuracy)."""

class OutlineError(ValueError):
    """An outline the placement cannot take; the message names the problem, in metres."""


@dataclass(frozen=True, eq=False)
class Outline:
    """A building outline in metres.

    Attributes:
        polygon: The building (shapely, valid; the outer ring counter-clockwise, holes clockwise).
        walls_m: ``(E, 4)`` every wall ``ax, ay, bx, by``, ring after ring, the interior on its left.
        next_wall: ``(E,)`` index of the wall that starts where each wall ends (same ring).
        name: A name for outputs.
    """

    polygon: shapely.Polygon
    walls_m: np.ndarray
    next_wall: np.ndarray
    name: str = "building"

    @classmethod
    def from_rings(cls, exterior_m: np.ndarray, holes_m: Sequence[np.ndarray] = (), name: str = "building"
                   ) -> Outline:
        """An outline from its outer ring and holes (``(n, 2)`` metres each, not closed).

        Raises:
            OutlineError: A ring of fewer than 3 distinct vertices, no area, or an invalid polygon
                (self-intersecting, a hole outside or touching another ring), named with its place.
        """
        rings = [np.asarray(exterior_m, dtype=np.float64).reshape(-1, 2)]
        rings += [np.asarray(h, dtype=np.float64).reshape(-1, 2) for h in holes_m]
        for i, ring in enumerate(rings):
            distinct = len(np.unique(ring, axis=0))
            if distinct < 3 or not np.all(np.isfinite(ring)):
                what = "the outer ring" if i == 0 else f"hole {i}"
                raise OutlineError(f"{name}: {what} has {distinct} distinct finite vertices; a ring needs 3")
        polygon = shapely.Polygon(rings[0], rings[1:])
        if not polygon.is_valid:
            reason = shapely.is_valid_reason(polygon)
            raise OutlineError(f"{name}: not a valid building outline: {reason} (metres, East-North); "
                               "the outline crosses or touches itself, or a courtyard leaves the building")
        if polygon.area <= 0.0:
            raise OutlineError(f"{name}: the outline encloses no area (degenerate)")
        polygon = shapely.orient_polygons(polygon)
        walls: list[np.ndarray] = []
        following: list[np.ndarray] = []
        for ring in [polygon.exterior, *polygon.interiors]:
            xy = np.asarray(ring.coords)[:-1]
            keep = np.any(xy != np.roll(xy, 1, axis=0), axis=1)  # drop repeated vertices
            xy = xy[keep]
            start = sum(len(w) for w in walls)
            walls.append(np.concatenate([xy, np.roll(xy, -1, axis=0)], axis=1))
            following.append(start + (np.arange(len(xy)) + 1) % len(xy))
        return cls(polygon, np.concatenate(walls), np.concatenate(following), name)

    @property
    def n_vertices(self) -> int:
        """Vertices of all rings together (one per wall)."""
        return len(self.walls_m)

    def wall_distances(self, points_m: np.ndarray) -> np.ndarray:
        """``(N,)`` distance of each point to the nearest wall, metres."""
        points = np.asarray(points_m, dtype=np.float64).reshape(-1, 2)
        return shapely.distance(shapely.points(points), self.polygon.boundary)

    def inside(self, points_m: np.ndarray) -> np.ndarray:
        """``(N,)`` bool: strictly inside the building (a courtyard is outside)."""
        points = np.asarray(points_m, dtype=np.float64).reshape(-1, 2)
        return shapely.contains_xy(self.polygon, points[:, 0], points[:, 1])


@dataclass(frozen=True)
class Witnesses:
    """Points a placement must see.

    Attributes:
        points_m: ``(W, 2)`` positions, metres.
        walls: ``(W, 2)`` int64: the walls each point lies on (a vertex: the wall starting there and the
            wall ending there), ``-1`` for none.
        near: ``(W, E)`` bool: the walls, other than its own, nearer the point than twice the margin
            (rule 3 spares them); None until :meth:`prepared` is called.
        clearance_m: The margin ``near`` was computed for.
        codes: ``(W, E)`` uint8 where each point lies about each wall (``visibility``'s quick test), for
            the margin and region of :meth:`prepared`; None until then.
        region: The region ``codes`` was computed for.
    """

    points_m: np.ndarray
    walls: np.ndarray
    near: np.ndarray | None = None
    clearance_m: float | None = None
    codes: np.ndarray | None = None
    region: Region | None = None

    def __len__(self) -> int:
        return len(self.points_m)

    def subset(self, index: np.ndarray) -> Witnesses:
        """The witnesses at ``index``."""
        near = None if self.near is None else self.near[index]
        codes = None if self.codes is None else self.codes[index]
        return Witnesses(self.points_m[index], self.walls[index], near, self.clearance_m, codes, self.region)

    def prepared(self, outline: Outline, clearance_m: float, region: Region) -> Witnesses:
        """These witnesses with ``near`` and ``codes`` computed for a margin and region (kept if so)."""
        if self.clearance_m == clearance_m and self.region == region and self.near is not None:
            return self
        near = np.zeros((len(self), outline.n_vertices), dtype=bool)
        close = outline.wall_distances(self.points_m) < 2 * clearance_m  # GEOS first: most points are far
        near[close] = point_segment_distances(self.points_m[close], outline.walls_m) < 2 * clearance_m
        for column in self.walls.T:
            rows = np.flatnonzero(column >= 0)
            near[rows, column[rows]] = False
        codes = _codes(outline, region, self.points_m, max(clearance_m, TOUCH_M))
        return Witnesses(self.points_m, self.walls, near, clearance_m, codes, region)


def _wall_points(outline: Outline, spacing_m: float, vertices_only: bool) -> Witnesses:
    walls = outline.walls_m
    start, vector = walls[:, :2], walls[:, 2:] - walls[:, :2]
    previous = np.empty(len(walls), dtype=np.int64)
    previous[outline.next_wall] = np.arange(len(walls))
    if vertices_only:
        pieces = np.ones(len(walls), dtype=np.int64)
    else:
        pieces = np.maximum(1, np.ceil(np.hypot(*vector.T) / spacing_m - 1e-9)).astype(np.int64)
    wall = np.repeat(np.arange(len(walls)), pieces)
    step = np.arange(len(wall)) - np.concatenate([[0], np.cumsum(pieces)[:-1]])[wall]
    points = start[wall] + vector[wall] * (step / pieces[wall])[:, None]
    on = np.stack([wall, np.where(step == 0, previous[wall], -1)], axis=1)
    return Witnesses(points, on)


def witnesses(outline: Outline, region: Region, spacing_m: float = 0.5) -> Witnesses:
    """The points a placement must see (see the module docstring).

    Raises:
        ValueError: ``spacing_m`` is not positive.
    """
    if not spacing_m > 0:
        raise ValueError(f"witness spacing_m = {spacing_m}: allowed > 0")
    if region == "exterior":
        return _wall_points(outline, spacing_m, vertices_only=False)
    corners = _wall_points(outline, spacing_m, vertices_only=True)
    grid = _grid(outline.polygon.bounds, spacing_m)
    grid = grid[outline.inside(grid)]
    grid = grid[outline.wall_distances(grid) > TOUCH_M]  # closer is on the wall: a projection's rounding
    return Witnesses(np.concatenate([corners.points_m, grid]),
                     np.concatenate([corners.walls, np.full((len(grid), 2), -1, dtype=np.int64)]))


def _grid(bounds: tuple[float, float, float, float], spacing_m: float) -> np.ndarray:
    """``(N, 2)`` points of a square grid of ``spacing_m`` centred on the box ``bounds``."""
    low, high = np.array(bounds[:2]), np.array(bounds[2:])
    counts = np.floor((high - low) / spacing_m).astype(np.int64) + 1
    first = (low + high) / 2 - (counts - 1) * spacing_m / 2
    xs = first[0] + spacing_m * np.arange(counts[0])
    ys = first[1] + spacing_m * np.arange(counts[1])
    gx, gy = np.meshgrid(xs, ys)
    return np.stack([gx.ravel(), gy.ravel()], axis=1)


def candidates(outline: Outline, region: Region, spacing_m: float, standoff_m: float, reach_m: float = 0.0
               ) -> np.ndarray:
    """``(G, 2)`` lattice points where a guard may stand (see the module docstring), metres.

    Args:
        outline: The building.
        region: ``"interior"`` (Art Gallery) or ``"exterior"`` (Fortress).
        spacing_m: The lattice spacing.
        standoff_m: Least distance from every wall.
        reach_m: Fortress only: how far beyond the building's bounding box guards may stand.
    """
    if not spacing_m > 0:
        raise ValueError(f"candidate spacing_m = {spacing_m}: allowed > 0")
    x0, y0, x1, y1 = outline.polygon.bounds
    grow = reach_m if region == "exterior" else 0.0
    grid = _grid((x0 - grow, y0 - grow, x1 + grow, y1 + grow), spacing_m)
    inside = outline.inside(grid)
    grid = grid[inside if region == "interior" else ~inside]
    return grid[outline.wall_distances(grid) >= max(standoff_m, TOUCH_M)]


def _cross(ax: np.ndarray, ay: np.ndarray, bx: np.ndarray, by: np.ndarray) -> np.ndarray:
    return ax * by - ay * bx


def visibility(outline: Outline, guards_m: np.ndarray, targets: Witnesses, min_clearance_m: float,
               region: Region = "interior") -> np.ndarray:
    """``(G, W)`` bool: guard ``g`` sees witness ``w`` (the three rules of the module docstring).

    Guards are assumed in ``region``, at least ``min_clearance_m`` from every wall (:func:`candidates`
    makes them so).

    Args:
        outline: The building.
        guards_m: ``(G, 2)`` guard positions, metres.
        targets: The witnesses.
        min_clearance_m: The visibility margin (``>= 0``).
        region: ``"interior"`` (Art Gallery) or ``"exterior"`` (Fortress).
    """
    if not min_clearance_m >= 0:
        raise ValueError(f"min_clearance_m = {min_clearance_m}: allowed >= 0")
    guards = np.ascontiguousarray(np.asarray(guards_m, dtype=np.float64).reshape(-1, 2))
    if len(guards) == 0 or len(targets) == 0:
        return np.zeros((len(guards), len(targets)), dtype=bool)
    targets = targets.prepared(outline, min_clearance_m, region)
    assert targets.near is not None and targets.codes is not None  # prepared() computes both
    bound = max(min_clearance_m, TOUCH_M)
    far_limit = bound - TOUCH_M if min_clearance_m > TOUCH_M else TOUCH_M
    guard_codes = _codes(outline, region, guards, bound)
    return sees(outline.walls_m, guards, targets.points_m, targets.walls, targets.near, guard_codes,
                targets.codes, far_limit, TOUCH_M, region == "interior")


def _codes(outline: Outline, region: Region, points: np.ndarray, bound: float) -> np.ndarray:
    """``(N, E)`` uint8 codes of where each point lies about each wall.

    Bits 0-3: left of, right of, below or above the wall's box grown by ``bound``; bit 4: ``bound``
    beyond the wall's line, on the region's side.
    """
    walls = outline.walls_m
    low = np.minimum(walls[:, :2], walls[:, 2:]) - bound
    high = np.maximum(walls[:, :2], walls[:, 2:]) + bound
    x, y = points[:, 0, None], points[:, 1, None]
    codes = ((x < low[:, 0]).astype(np.uint8) | ((x > high[:, 0]).astype(np.uint8) << 1)
             | ((y < low[:, 1]).astype(np.uint8) << 2) | ((y > high[:, 1]).astype(np.uint8) << 3))
    return codes | (_beyond(outline, region, points, bound).astype(np.uint8) << 4)


def _beyond(outline: Outline, region: Region, points: np.ndarray, bound: float) -> np.ndarray:
    """``(N, E)`` bool: the point lies at least ``bound`` beyond each wall's line, on the region's side."""
    start, vector = outline.walls_m[:, :2], outline.walls_m[:, 2:] - outline.walls_m[:, :2]
    unit = (1.0 if region == "interior" else -1.0) * vector / np.hypot(vector[:, 0], vector[:, 1])[:, None]
    return _cross(unit[None, :, 0], unit[None, :, 1], points[:, None, 0] - start[None, :, 0],
                  points[:, None, 1] - start[None, :, 1]) >= bound
