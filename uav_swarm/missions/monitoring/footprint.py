"""A user's building: footprint files in, a :class:`Polygon` on the monitoring raster out, and back.

Two inputs (:func:`read_footprint`):

- **GeoJSON** (``.geojson``, or ``.json`` holding a GeoJSON object): a ``Polygon`` geometry, a
  ``Feature`` with one, or a ``FeatureCollection`` of exactly one such feature, in WGS84
  longitude/latitude as GIS tools export it. The outline is projected to East-North metres
  around the mean of its vertices (:func:`bridge.geo.geodetic_to_enu`). A ``MultiPolygon`` of one
  part is that part; of several parts it is refused (place each part from its own file), and so is
  a polygon with holes (an inner courtyard): the missions take simple polygons without holes.
- **Vertices in metres**: a ``.json`` list of ``[x, y]`` pairs, or a ``.csv`` / ``.txt`` file with
  one ``x, y`` (or ``x y``) pair per line (``#`` starts a comment).

The outline must be a simple polygon (:func:`uav_swarm.missions.monitoring.polygons.is_simple`) of at most
``max_vertices`` distinct vertices; a repeated closing vertex is dropped.

Fitting (:func:`fit_to_raster`): the outline is scaled uniformly so that its larger side spans the
raster less ``margin_px`` on each side (the room Fortress guards need outside), vertices are rounded
to pixel centres (the missions' exact geometry needs them) and vertices the rounding makes
repeated or straight are dropped. A building needing more than ``max_pixel_m`` metres per pixel,
or whose rounded outline is no longer simple or lost a part (an input vertex farther than half a
pixel diagonal from it: detail finer than a pixel), is refused.
:meth:`FittedFootprint.to_metres` maps raster positions back to the input's metres.

Examples:
    >>> footprint = Footprint(np.array([[0.0, 0.0], [40.0, 0.0], [40.0, 20.0], [0.0, 20.0]]))
    >>> fitted = fit_to_raster(footprint)
    >>> fitted.polygon.n_vertices, round(fitted.metres_per_px, 3)
    (4, 0.727)
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bridge.geo import Home, enu_to_geodetic, geodetic_to_enu
from uav_swarm.missions.monitoring.polygons import Polygon, is_simple
from uav_swarm.world.geometry import point_segment_distances

__all__ = ["FootprintError", "Footprint", "FittedFootprint", "read_footprint", "fit_to_raster"]

DEFAULT_MAX_VERTICES = 64
"""Most vertices a footprint may have (the exact experts' cost grows with them)."""


_ROUNDING_PX = 0.5 * 2 ** 0.5 + 1e-9
"""Farthest an input vertex may lie from the rounded outline (rounding moves a vertex this far at most)."""


class FootprintError(ValueError):
    """A footprint file the placement cannot take; the message names the problem."""


@dataclass(frozen=True)
class Footprint:
    """A building outline in East-North metres.

    Attributes:
        vertices_m: ``(n, 2)`` float64 outline vertices ``(x east, y north)``, metres.
        origin: The geodetic point the metres are measured from (GeoJSON input), None for metres input.
        name: A name for outputs (the GeoJSON feature's ``name`` property, else the file's stem).
    """

    vertices_m: np.ndarray
    origin: Home | None = None
    name: str = "building"

    def to_input(self, points_m: np.ndarray) -> np.ndarray:
        """``(k, 2)`` points in the input's coordinates: ``(lon, lat)`` degrees for GeoJSON, else metres."""
        points_m = np.asarray(points_m, dtype=np.float64).reshape(-1, 2)
        if self.origin is None:
            return points_m.copy()
        out = [enu_to_geodetic(self.origin, float(x), float(y), 0.0) for x, y in points_m]
        return np.array([[lon, lat] for lat, lon, _ in out]).reshape(-1, 2)


@dataclass(frozen=True)
class FittedFootprint:
    """A footprint on the raster.

    Attributes:
        footprint: The input outline.
        polygon: Its rounded outline on the raster (pixel coordinates, ``y`` grows north).
        metres_per_px: The uniform scale.
        offset_m: ``(2,)`` metres of the pixel coordinate ``(0, 0)``.
    """

    footprint: Footprint
    polygon: Polygon
    metres_per_px: float
    offset_m: np.ndarray

    def to_metres(self, positions_px: np.ndarray) -> np.ndarray:
        """``(k, 2)`` raster positions to the input's metres."""
        return self.offset_m + np.asarray(positions_px, dtype=np.float64).reshape(-1, 2) * self.metres_per_px


def _ring_from_geojson(data: Any, path: Path) -> tuple[list, str | None]:
    """The outer ring and the name of the one polygon of a GeoJSON object."""
    name = None
    if isinstance(data, dict) and data.get("type") == "FeatureCollection":
        features = data.get("features") or []
        if len(features) != 1:
            raise FootprintError(f"{path}: a FeatureCollection of {len(features)} features; give exactly "
                                 "one building per file")
        data = features[0]
    if isinstance(data, dict) and data.get("type") == "Feature":
        name = (data.get("properties") or {}).get("name")
        data = data.get("geometry")
    kind = data.get("type") if isinstance(data, dict) else None
    coordinates = data.get("coordinates") if isinstance(data, dict) else None
    if kind == "MultiPolygon" and isinstance(coordinates, list):
        if len(coordinates) != 1:
            raise FootprintError(f"{path}: a MultiPolygon of {len(coordinates)} separate parts; place each "
                                 "part from its own file (one Polygon each)")
        kind, coordinates = "Polygon", coordinates[0]
    if kind != "Polygon" or not isinstance(coordinates, list) or not coordinates:
        raise FootprintError(f"{path}: no Polygon geometry (found {kind!r}); a building is a GeoJSON "
                             "Polygon")
    if len(coordinates) > 1:
        raise FootprintError(f"{path}: the polygon has {len(coordinates) - 1} hole(s) (an inner courtyard); "
                             "the placement takes polygons without holes: give the outer ring alone")
    return coordinates[0], name


def _read_points(path: Path) -> tuple[np.ndarray, Home | None, str | None]:
    """Raw outline points, their geodetic origin (GeoJSON) and a name, from a file."""
    try:
        text = path.read_text()
    except OSError as exc:
        raise FootprintError(f"{path}: cannot read the building file ({exc.strerror})") from None
    if path.suffix.lower() in (".geojson", ".json"):
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise FootprintError(f"{path}: not valid JSON ({exc.msg}, line {exc.lineno})") from None
        if isinstance(data, list):
            return _as_points(data, path), None, None
        ring, name = _ring_from_geojson(data, path)
        lonlat = _as_points(ring, path)
        if np.any(np.abs(lonlat[:, 0]) > 180.0) or np.any(np.abs(lonlat[:, 1]) > 90.0):
            raise FootprintError(f"{path}: coordinates outside longitude [-180, 180] / latitude [-90, 90]; "
                                 "GeoJSON is WGS84 degrees (give metres as a plain list of vertices instead)")
        origin = Home(lat_deg=float(lonlat[:, 1].mean()), lon_deg=float(lonlat[:, 0].mean()), alt_m=0.0)
        metres = [geodetic_to_enu(origin, float(lat), float(lon), 0.0)[:2] for lon, lat in lonlat]
        return np.array(metres), origin, name
    if path.suffix.lower() in (".csv", ".txt"):
        rows = []
        for line in text.splitlines():
            line = line.split("#", 1)[0].strip()
            if line:
                rows.append(next(csv.reader([line.replace(" ", ",")], skipinitialspace=True)))
        return _as_points([[cell for cell in row if cell] for row in rows], path), None, None
    raise FootprintError(f"{path}: unknown building file type {path.suffix!r}; allowed .geojson, .json "
                         "(GeoJSON or a list of [x, y] metres), .csv or .txt (x, y metres per line)")


def _as_points(values: Any, path: Path) -> np.ndarray:
    try:
        points = np.array([[float(v) for v in point[:2]] for point in values if len(point) >= 2],
                          dtype=np.float64)
    except (TypeError, ValueError):
        raise FootprintError(f"{path}: vertices must be pairs of numbers") from None
    if len(points) != len(values) or not np.all(np.isfinite(points)):
        raise FootprintError(f"{path}: vertices must be pairs of finite numbers")
    return points.reshape(-1, 2)


def read_footprint(path: str | Path, max_vertices: int = DEFAULT_MAX_VERTICES) -> Footprint:
    """Read a building outline (see the module docstring).

    Raises:
        FootprintError: Unreadable or unknown file, holes, several parts, fewer than 3 or more than
            ``max_vertices`` vertices, a self-intersecting or degenerate outline.
    """
    path = Path(path)
    points, origin, name = _read_points(path)
    if len(points) >= 2 and np.array_equal(points[0], points[-1]):
        points = points[:-1]
    keep = np.ones(len(points), dtype=bool)
    keep[1:] = np.any(points[1:] != points[:-1], axis=1)
    points = points[keep]
    if len(points) < 3:
        raise FootprintError(f"{path}: {len(points)} distinct vertices; a building needs at least 3")
    if len(points) > max_vertices:
        raise FootprintError(f"{path}: {len(points)} vertices; allowed at most {max_vertices}")
    scale = float(np.ptp(points, axis=0).max())
    if scale == 0.0 or np.linalg.matrix_rank(points - points.mean(axis=0), tol=1e-9 * scale) < 2:
        raise FootprintError(f"{path}: the outline encloses no area (degenerate: its vertices are collinear)")
    if not is_simple(points):
        raise FootprintError(f"{path}: the outline is not a simple polygon (it crosses or touches itself, or "
                             "repeats a vertex)")
    return Footprint(points, origin, name or path.stem)


def _clean_ring(vertices: np.ndarray) -> np.ndarray:
    """Drop repeated and straight (collinear) vertices until none is left."""
    while len(vertices) >= 3:
        repeated = np.all(vertices == np.roll(vertices, 1, axis=0), axis=1)
        if np.any(repeated):
            vertices = vertices[~repeated]
            continue
        before, after = np.roll(vertices, 1, axis=0), np.roll(vertices, -1, axis=0)
        turn = (vertices[:, 0] - before[:, 0]) * (after[:, 1] - vertices[:, 1]) - (
            vertices[:, 1] - before[:, 1]) * (after[:, 0] - vertices[:, 0])
        straight = turn == 0
        if not np.any(straight):
            break
        vertices = np.delete(vertices, int(np.argmax(straight)), axis=0)
    return vertices


def fit_to_raster(footprint: Footprint, size_px: int = 64, margin_px: int = 4, max_pixel_m: float = 10.0
                  ) -> FittedFootprint:
    """Scale and round a footprint onto the ``size_px`` raster (see the module docstring).

    Raises:
        FootprintError: The building needs more than ``max_pixel_m`` metres per pixel, or its rounded
            outline is no longer a simple polygon.
    """
    vertices = footprint.vertices_m
    low = vertices.min(axis=0)
    span_px = size_px - 1 - 2 * margin_px
    extent_m = float(np.ptp(vertices, axis=0).max())
    metres_per_px = extent_m / span_px
    if metres_per_px > max_pixel_m:
        raise FootprintError(
            f"the building spans {extent_m:.1f} m: on the {size_px} px raster that is {metres_per_px:.2f} m "
            f"per pixel, above max_pixel_m = {max_pixel_m} (too large to resolve at that accuracy)")
    offset_m = low - margin_px * metres_per_px
    exact_px = (vertices - offset_m) / metres_per_px
    rounded = _clean_ring(np.rint(exact_px))
    edges = np.concatenate([rounded, np.roll(rounded, -1, axis=0)], axis=1)
    lost = len(rounded) == 0 or point_segment_distances(exact_px, edges).min(axis=1).max() > _ROUNDING_PX
    if len(rounded) < 3 or lost or not is_simple(rounded):
        raise FootprintError(
            f"at {metres_per_px:.2f} m per pixel the outline of {len(vertices)} vertices touches itself once "
            "rounded to pixel centres: it has detail finer than a pixel (simplify it, or place a part of it)")
    polygon = Polygon(rounded, size_px=size_px)
    return FittedFootprint(footprint, polygon, metres_per_px, offset_m)
