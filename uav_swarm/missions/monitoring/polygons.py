"""Random simple polygons ("buildings") with vertices on the pixel centres of a square raster.

Coordinates are pixel coordinates ``(x, y) = (column, row)`` of a ``size_px`` x ``size_px``
raster, with the centre of pixel ``[row i, column j]`` at ``(x=j, y=i)``. Every vertex lies on
a pixel centre (integer coordinates), so orientation tests between vertices and pixel
centres are exact in floating point; the visibility module relies on it.

Generation (:func:`random_polygon`) follows CGAL's ``random_polygon_2`` idea, "2-opt
untangling": draw ``n`` distinct lattice points in general position (no three collinear)
inside the raster less a margin, join them in a random order, then, while two edges cross,
pick one crossing pair at random (from the generator) and reverse the chain between them
(a 2-opt move). Each move strictly shortens the closed tour, so the loop ends with a simple
polygon. Unlike star-shaped or convex-hull based generators this yields many reflex
vertices and non-star-shaped buildings, so several guards are often needed. Candidates
are then rejected (and redrawn) when they have fewer reflex vertices than asked for, or
when a vertex comes closer than ``min_clearance_px`` to a non-adjacent edge (no slivers
or near-touching walls). The margin keeps room outside the building for Fortress guards.

With the defaults (6-20 vertices, 64 px, margin 4, clearance 1 px) the clearance rule rejects
more of the many-vertex draws, so accepted polygons lean to fewer vertices (median 12; 43 %
have at most 10, 26 % at least 16); the median building covers about 1040 px^2 (a third of the
55 x 55 px box; 5-95 %: 500-1560) with 4 reflex vertices. Its exact Art Gallery optimum is
1, 2, 3 or 4 guards for 32, 46, 21 and 0.5 % of them (``benchmarks/README.md``).

Examples:
    >>> rng = np.random.default_rng(0)
    >>> polygon = random_polygon(rng, PolygonConfig(min_vertices=8, max_vertices=8))
    >>> polygon.n_vertices, is_simple(polygon.vertices_px), polygon.signed_area_px2 > 0
    (8, True, True)
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from typed_config import Config, ConfigError, param
from uav_swarm.world.geometry import point_segment_distances, segments_cross

__all__ = [
    "Polygon",
    "PolygonConfig",
    "PolygonSamplingError",
    "random_polygon",
    "is_simple",
    "signed_area",
    "reflex_mask",
    "locate_points",
]

logger = logging.getLogger(__name__)

_EPS = 1e-9
"""Zero test for orientation determinants of vertices and pixel centres (integers: exact)."""


class PolygonSamplingError(RuntimeError):
    """No polygon satisfying the config was found within ``max_attempts`` draws."""


@dataclass(frozen=True)
class PolygonConfig(Config):
    """How random buildings are drawn (all lengths in pixels of the square raster)."""

    size_px: int = param(64, ge=8, le=512, doc="raster side in pixels")
    margin_px: int = param(4, ge=0, le=128, doc="vertices keep this many pixels from the raster border")
    min_vertices: int = param(6, ge=3, le=64, doc="fewest polygon vertices")
    max_vertices: int = param(20, ge=3, le=64, doc="most polygon vertices (drawn uniformly in the range)")
    min_reflex_vertices: int = param(1, ge=0, le=61, doc="polygons with fewer reflex vertices are redrawn")
    min_clearance_px: float = param(
        1.0, ge=0.0, le=16.0, doc="smallest distance from a vertex to a non-adjacent edge (pixels)")
    max_attempts: int = param(1000, ge=1, le=1_000_000, doc="draws before giving up")

    def check(self) -> None:
        """Cross-field rules: vertex range, reflex count, room for the points."""
        if self.min_vertices > self.max_vertices:
            raise ConfigError(
                f"PolygonConfig.min_vertices = {self.min_vertices} must be <= "
                f"max_vertices = {self.max_vertices}")
        if self.min_reflex_vertices > self.max_vertices - 3:
            raise ConfigError(
                f"PolygonConfig.min_reflex_vertices = {self.min_reflex_vertices} is impossible: a simple "
                f"polygon with at most max_vertices = {self.max_vertices} vertices has at most "
                f"{self.max_vertices - 3}")
        span = self.size_px - 1 - 2 * self.margin_px
        if span < 4:
            raise ConfigError(
                f"PolygonConfig.margin_px = {self.margin_px} leaves a {span} px span in a {self.size_px} px "
                f"raster: allowed 2 * margin_px <= size_px - 5")


def signed_area(vertices_px: np.ndarray) -> float:
    """Shoelace signed area, positive when the vertices turn counter-clockwise in the ``(x, y)`` frame.

    Args:
        vertices_px: ``(n, 2)`` vertices.
    """
    v = np.asarray(vertices_px, dtype=np.float64)
    w = np.roll(v, -1, axis=0)
    return float(0.5 * np.sum(v[:, 0] * w[:, 1] - v[:, 1] * w[:, 0]))


def _edges(vertices_px: np.ndarray) -> np.ndarray:
    v = np.asarray(vertices_px, dtype=np.float64)
    return np.concatenate([v, np.roll(v, -1, axis=0)], axis=1)


def _crossing_edge_pairs(vertices_px: np.ndarray) -> np.ndarray:
    """``(m, 2)`` pairs ``i < j`` of non-adjacent edges that touch or cross (edge i: vertex i to i + 1)."""
    edges = _edges(vertices_px)
    n = len(edges)
    touching = segments_cross(edges[:, None, :], edges[None, :, :])
    i, j = np.triu_indices(n, k=2)
    keep = ~((i == 0) & (j == n - 1))  # the first and last edges share vertex 0
    i, j = i[keep], j[keep]
    hit = touching[i, j]
    return np.stack([i[hit], j[hit]], axis=1)


def _turns(vertices_px: np.ndarray) -> np.ndarray:
    """Cross product of the incoming and outgoing edge at each vertex (> 0: left turn)."""
    v = np.asarray(vertices_px, dtype=np.float64)
    e_in = v - np.roll(v, 1, axis=0)
    e_out = np.roll(v, -1, axis=0) - v
    return e_in[:, 0] * e_out[:, 1] - e_in[:, 1] * e_out[:, 0]


def is_simple(vertices_px: np.ndarray) -> bool:
    """Whether the closed chain is a simple polygon.

    Simple means: at least 3 vertices, no repeated vertex, no vertex where the boundary goes
    straight on or folds back (zero turn), and no two non-adjacent edges touching or crossing.

    Args:
        vertices_px: ``(n, 2)`` vertices in order (either orientation).
    """
    v = np.asarray(vertices_px, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 2 or len(v) < 3:
        return False
    if len(np.unique(v, axis=0)) != len(v) or np.any(np.abs(_turns(v)) <= _EPS):
        return False
    return len(_crossing_edge_pairs(v)) == 0


def reflex_mask(vertices_px: np.ndarray) -> np.ndarray:
    """``(n,)`` bool: the vertices whose interior angle exceeds 180 degrees (any orientation)."""
    turns = _turns(vertices_px)
    return turns * np.sign(signed_area(vertices_px)) < 0


def locate_points(points_px: np.ndarray, vertices_px: np.ndarray) -> np.ndarray:
    """Where points lie relative to a simple polygon: 1 inside, 0 on the boundary, -1 outside.

    Boundary: the point is collinear with an edge and within its extent (exact for rational
    coordinates of small denominator, see the visibility module). Otherwise the crossing
    number of a ray towards +x decides, with the half-open rule on edge end points.

    Args:
        points_px: ``(m, 2)`` points.
        vertices_px: ``(n, 2)`` polygon vertices.

    Returns:
        ``(m,)`` int8 codes.
    """
    p = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
    e = _edges(vertices_px)
    px, py = p[:, 0, None], p[:, 1, None]
    ax, ay, bx, by = e[:, 0], e[:, 1], e[:, 2], e[:, 3]
    cross = (bx - ax) * (py - ay) - (by - ay) * (px - ax)
    within = ((px - ax) * (px - bx) <= _EPS) & ((py - ay) * (py - by) <= _EPS)
    on_boundary = np.any((np.abs(cross) <= _EPS) & within, axis=1)
    straddles = (ay > py) != (by > py)
    # x of the edge at height py, compared without division: sign by edge direction.
    x_side = cross * np.sign(by - ay) > 0  # the point is left of the upward-oriented edge: ray meets it
    inside = (np.count_nonzero(straddles & x_side, axis=1) % 2) == 1
    return np.where(on_boundary, 0, np.where(inside, 1, -1)).astype(np.int8)


@dataclass(frozen=True, eq=False)
class Polygon:
    """A simple polygon with integer (pixel-centre) vertices, counter-clockwise in ``(x, y)``.

    Construction validates simplicity and the raster bounds and reorders clockwise input.

    Attributes:
        vertices_px: ``(n, 2)`` float64 read-only vertices ``(x=col, y=row)``, integer valued.
        size_px: Side of the square raster the polygon is drawn on.
    """

    vertices_px: np.ndarray
    size_px: int
    _reflex: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        v = np.array(self.vertices_px, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != 2 or len(v) < 3:
            raise ValueError(f"Polygon.vertices_px must have shape (n >= 3, 2), got {v.shape}")
        if not np.all(np.isfinite(v)) or np.any(v != np.round(v)):
            raise ValueError("Polygon.vertices_px must be integer pixel centres (exact geometry needs them)")
        if v.min() < 0 or v.max() > self.size_px - 1:
            raise ValueError(
                f"Polygon.vertices_px span [{v.min()}, {v.max()}]: allowed 0 <= x, y <= size_px - 1 = "
                f"{self.size_px - 1}")
        if not is_simple(v):
            raise ValueError(
                "Polygon.vertices_px is not a simple polygon (self-touching, repeated or straight vertex)")
        if signed_area(v) < 0:
            v = v[::-1].copy()
        v.setflags(write=False)
        reflex = reflex_mask(v)
        reflex.setflags(write=False)
        object.__setattr__(self, "vertices_px", v)
        object.__setattr__(self, "_reflex", reflex)

    @property
    def n_vertices(self) -> int:
        """Number of vertices."""
        return len(self.vertices_px)

    @property
    def reflex(self) -> np.ndarray:
        """``(n,)`` bool read-only mask of reflex vertices."""
        return self._reflex

    @property
    def signed_area_px2(self) -> float:
        """Area in square pixels (positive: vertices are stored counter-clockwise)."""
        return signed_area(self.vertices_px)

    @property
    def edges_px(self) -> np.ndarray:
        """``(n, 4)`` edges ``x1, y1, x2, y2``; edge ``i`` joins vertex ``i`` to vertex ``i + 1``."""
        return _edges(self.vertices_px)

    def pixel_locations(self) -> np.ndarray:
        """``(size, size)`` int8 location of every pixel centre: 1 inside, 0 on the boundary, -1 outside.

        The same codes as :func:`locate_points` on the pixel centres, computed row by row: a centre
        is on the boundary when it is a lattice point of an edge, and otherwise inside when an odd
        number of edges (half-open in y) cross its row strictly to its right.
        """
        v = self.vertices_px.astype(np.int64)
        a, b = v, np.roll(v, -1, axis=0)
        rows = np.arange(self.size_px)[:, None]
        straddles = (a[:, 1] > rows) != (b[:, 1] > rows)  # (size, n)
        dy = np.where(b[:, 1] == a[:, 1], 1, b[:, 1] - a[:, 1])
        x_cross = a[:, 0] + (b[:, 0] - a[:, 0]) * (rows - a[:, 1]) / dy  # exact sign: see the docstring
        cols = np.arange(self.size_px)[None, :, None]
        right = straddles[:, None, :] & (cols < x_cross[:, None, :])
        codes = np.where(np.count_nonzero(right, axis=2) % 2 == 1, 1, -1).astype(np.int8)
        d = b - a
        steps = np.gcd(np.abs(d[:, 0]), np.abs(d[:, 1]))
        edge = np.repeat(np.arange(len(v)), steps)
        k = np.arange(len(edge)) - np.repeat(np.cumsum(steps) - steps, steps)
        lattice = a[edge] + d[edge] // steps[edge, None] * k[:, None]
        codes[lattice[:, 1], lattice[:, 0]] = 0
        return codes


def _general_position_points(rng: np.random.Generator, n: int, low: int, high: int) -> np.ndarray:
    """``n`` distinct integer points in ``[low, high]^2`` with no three collinear."""
    points = np.empty((0, 2), dtype=np.float64)
    while len(points) < n:
        p = rng.integers(low, high + 1, size=2).astype(np.float64)
        if len(points) >= 2:
            i, j = np.triu_indices(len(points), k=1)
            a, b = points[i], points[j]
            cross = (b[:, 0] - a[:, 0]) * (p[1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (p[0] - a[:, 0])
            if np.any(cross == 0):
                continue
        elif len(points) == 1 and np.all(points[0] == p):
            continue
        points = np.vstack([points, p])
    return points


def _untangle(points: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """2-opt moves on a random tour of ``points`` until it is simple; returns the ordered vertices."""
    tour = points[rng.permutation(len(points))]
    while True:
        pairs = _crossing_edge_pairs(tour)
        if len(pairs) == 0:
            return tour
        i, j = pairs[rng.integers(len(pairs))]
        tour[i + 1:j + 1] = tour[i + 1:j + 1][::-1].copy()


def _clearance_px(vertices_px: np.ndarray) -> float:
    """Smallest distance from a vertex to an edge not incident to it."""
    n = len(vertices_px)
    dist = point_segment_distances(vertices_px, _edges(vertices_px))
    k = np.arange(n)
    dist[k, k] = np.inf
    dist[k, (k - 1) % n] = np.inf
    return float(dist.min())


def random_polygon(rng: np.random.Generator, config: PolygonConfig) -> Polygon:
    """Draw a random simple polygon by 2-opt untangling (see the module docstring).

    Args:
        rng: The only source of randomness.
        config: Raster size, margin, vertex range and rejection rules.

    Raises:
        PolygonSamplingError: No draw passed the rejection rules in ``max_attempts`` tries.
    """
    low, high = config.margin_px, config.size_px - 1 - config.margin_px
    for _ in range(config.max_attempts):
        n = int(rng.integers(config.min_vertices, config.max_vertices + 1))
        vertices = _untangle(_general_position_points(rng, n, low, high), rng)
        if np.count_nonzero(reflex_mask(vertices)) < config.min_reflex_vertices:
            continue
        if _clearance_px(vertices) < config.min_clearance_px:
            continue
        return Polygon(vertices, config.size_px)
    raise PolygonSamplingError(
        f"no polygon met min_reflex_vertices = {config.min_reflex_vertices} and min_clearance_px = "
        f"{config.min_clearance_px} in max_attempts = {config.max_attempts} draws")
