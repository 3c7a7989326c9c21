"""Exact Art Gallery and Fortress experts on the pixel raster.

Discretisation (pixel coordinates ``(x=col, y=row)``, pixel centres at integers):

* **Art Gallery (AGP).** Candidate guards and witnesses are the same set: the pixel centres
  in the closed polygon (:func:`interior_pixels`). A guard sees a witness when their segment
  stays in the closed polygon. The expert is the fewest candidates that see every witness.
* **Fortress (FP).** Candidate guards are the pixel centres strictly outside the polygon
  (:func:`exterior_pixels`, within the raster); witnesses are boundary points: every vertex
  and points spaced at most ``spacing_px`` along each edge (:func:`boundary_points`). A guard
  sees a witness when their segment does not cross the polygon's interior. The expert is
  the fewest candidates that see every witness.

Both are solved exactly as set cover (:mod:`uav_swarm.missions.monitoring.setcover`). Among optimal
covers the expert picks, deterministically, the one whose guards see the most witnesses in
total, then whose guards lie closest to the polygon's centroid (cost per guard
``1000 * (most_seen - seen) + round(distance_px)``; the distance term of up to 10 guards
stays below 1000, so it only breaks ties of the visibility term). Polygons in a 64 px raster
give distances below 91 px.

Examples:
    >>> from uav_swarm.missions.monitoring.polygons import Polygon
    >>> square = Polygon(np.array([[10, 10], [30, 10], [30, 30], [10, 30]]), size_px=40)
    >>> len(solve_guards(art_gallery_problem(square))), len(solve_guards(fortress_problem(square)))
    (1, 2)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from uav_swarm.missions.monitoring.polygons import Polygon
from uav_swarm.missions.monitoring.setcover import min_set_cover
from uav_swarm.missions.monitoring.visibility import Region, visibility_matrix

__all__ = [
    "GuardProblem",
    "interior_pixels",
    "exterior_pixels",
    "boundary_points",
    "art_gallery_problem",
    "fortress_problem",
    "solve_guards",
    "tie_break_cost",
    "MAX_BOUNDARY_DIVISIONS",
]

MAX_BOUNDARY_DIVISIONS = 1000
"""Most pieces an edge may be cut into (keeps boundary witnesses rationals of small denominator)."""

_VISIBILITY_WEIGHT = 1000
"""Weight of one unseen witness in the tie-break cost; must exceed 10 guards' rounded distances."""


@dataclass(frozen=True, eq=False)
class GuardProblem:
    """A discretised guarding instance.

    Attributes:
        polygon: The building.
        region: ``"interior"`` (Art Gallery) or ``"exterior"`` (Fortress).
        candidates_px: ``(G, 2)`` candidate guard positions ``(x, y)``.
        witnesses_px: ``(W, 2)`` points that must be seen.
        visibility: ``(G, W)`` bool, candidate ``g`` sees witness ``w``.
    """

    polygon: Polygon
    region: Region
    candidates_px: np.ndarray
    witnesses_px: np.ndarray
    visibility: np.ndarray


def _pixels_where(polygon: Polygon, wanted: np.ndarray) -> np.ndarray:
    rows, cols = np.nonzero(wanted)
    return np.stack([cols, rows], axis=1).astype(np.float64)


def interior_pixels(polygon: Polygon) -> np.ndarray:
    """``(N, 2)`` pixel centres ``(x, y)`` in the closed polygon (boundary included), row-major order."""
    return _pixels_where(polygon, polygon.pixel_locations() >= 0)


def exterior_pixels(polygon: Polygon) -> np.ndarray:
    """``(N, 2)`` pixel centres ``(x, y)`` of the raster strictly outside the polygon, row-major order."""
    return _pixels_where(polygon, polygon.pixel_locations() < 0)


def boundary_points(polygon: Polygon, spacing_px: float = 1.0) -> np.ndarray:
    """Witnesses on the boundary: each vertex, then evenly spaced points along its outgoing edge.

    Edge ``a -> b`` of length ``L`` is cut into ``m = ceil(L / spacing_px)`` equal pieces and
    contributes ``a + (b - a) i / m`` for ``i = 0 .. m - 1``.

    Args:
        polygon: The building.
        spacing_px: Largest distance between consecutive witnesses along an edge.

    Raises:
        ValueError: ``spacing_px`` is not positive or cuts an edge into more than
            :data:`MAX_BOUNDARY_DIVISIONS` pieces.
    """
    if not spacing_px > 0:
        raise ValueError(f"spacing_px = {spacing_px} must be > 0")
    v = polygon.vertices_px
    d = np.roll(v, -1, axis=0) - v
    pieces = np.maximum(1, np.ceil(np.hypot(d[:, 0], d[:, 1]) / spacing_px - 1e-9)).astype(np.int64)
    if pieces.max() > MAX_BOUNDARY_DIVISIONS:
        raise ValueError(
            f"spacing_px = {spacing_px} cuts an edge into {pieces.max()} pieces: allowed at most "
            f"{MAX_BOUNDARY_DIVISIONS} (raise spacing_px)")
    edge = np.repeat(np.arange(len(v)), pieces)
    first = np.concatenate([[0], np.cumsum(pieces)[:-1]])
    step = np.arange(len(edge)) - first[edge]
    return v[edge] + d[edge] * (step / pieces[edge])[:, None]


def art_gallery_problem(polygon: Polygon) -> GuardProblem:
    """The Art Gallery instance: interior pixel centres guard interior pixel centres."""
    points = interior_pixels(polygon)
    visibility = visibility_matrix(polygon, points, points, "interior")
    return GuardProblem(polygon, "interior", points, points, visibility)


def fortress_problem(polygon: Polygon, spacing_px: float = 1.0) -> GuardProblem:
    """The Fortress instance: exterior pixel centres guard boundary points spaced ``spacing_px``."""
    candidates = exterior_pixels(polygon)
    witnesses = boundary_points(polygon, spacing_px)
    visibility = visibility_matrix(polygon, candidates, witnesses, "exterior")
    return GuardProblem(polygon, "exterior", candidates, witnesses, visibility)


def tie_break_cost(problem: GuardProblem) -> np.ndarray:
    """``(G,)`` integer cost preferring guards that see more witnesses, then guards near the centroid."""
    seen = problem.visibility.sum(axis=1)
    v = problem.polygon.vertices_px
    w = np.roll(v, -1, axis=0)
    cross = v[:, 0] * w[:, 1] - v[:, 1] * w[:, 0]
    centroid = ((v + w) * cross[:, None]).sum(axis=0) / (3.0 * cross.sum())
    distance = np.rint(np.hypot(*(problem.candidates_px - centroid).T))
    return _VISIBILITY_WEIGHT * (seen.max(initial=0) - seen) + distance


def solve_guards(problem: GuardProblem) -> np.ndarray:
    """The exact expert: indices into ``problem.candidates_px`` of an optimal guard set.

    Fewest guards seeing every witness; ties broken by :func:`tie_break_cost` (see the module
    docstring), so the answer is deterministic.

    Raises:
        uav_swarm.missions.monitoring.setcover.InfeasibleCoverError: Some witness is seen by no candidate
            (possible for Fortress when a boundary point hides in a pocket with no pixel centre).
    """
    return min_set_cover(problem.visibility.T, tie_break_cost(problem))
