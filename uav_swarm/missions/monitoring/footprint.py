"""A user's buildings: footprint files in, outlines in metres, and the raster the network sees.

Two inputs (:func:`read_site`):

- **GeoJSON** (``.geojson``, or ``.json`` holding a GeoJSON object), in WGS84 longitude/latitude as GIS
  tools export it: a ``Polygon`` (holes, i.e. courtyards, allowed), a ``MultiPolygon`` (one building per
  part), a ``Feature`` with either, or a ``FeatureCollection`` of such features (a whole site). The site
  is projected to East-North metres (:func:`bridge.geo.geodetic_to_enu`) around a given origin (the
  bridge's home), else around the mean of the outer rings' distinct vertices (a ring's closing vertex,
  which repeats its first, counted once).
- **Vertices in metres** (one building without holes): a ``.json`` list of ``[x, y]`` pairs, or a
  ``.csv`` / ``.txt`` file with one ``x, y`` (or ``x y``) pair per line (``#`` starts a comment).

Each building must be a valid polygon (GEOS: rings that neither cross nor touch, courtyards inside the
building) of at most ``max_vertices`` vertices over all its rings; a repeated closing vertex is dropped.
:meth:`Footprint.outline` is the building in metres every placement is judged on.

The raster (:func:`fit_to_raster`) is only what the network sees: the outer ring scaled uniformly so
that its larger side spans the raster less ``margin_px`` on each side, vertices rounded to pixel centres
and vertices the rounding makes repeated or straight dropped. A ring needing more than ``max_pixel_m``
metres per pixel, or whose rounded ring is no longer simple or lost a part (detail finer than a pixel),
raises :class:`FootprintError`; the command then shows the network parts of the building
(``uav_swarm.cli.place``) and the repair covers the rest.
:meth:`FittedFootprint.to_metres` maps raster positions back to metres.

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
from uav_swarm.missions.monitoring.outline import Outline, OutlineError
from uav_swarm.missions.monitoring.polygons import Polygon, is_simple
from uav_swarm.world.geometry import point_segment_distances

__all__ = ["FootprintError", "Footprint", "FittedFootprint", "read_site", "read_footprint", "fit_to_raster",
           "site_origin"]

DEFAULT_MAX_VERTICES = 64
"""Most vertices a footprint may have (the exact experts' cost grows with them)."""


DEGENERATE_WIDTH_M = 0.01
"""An outline whose vertices spread less than this across their line encloses no area (metres).

Exact collinearity is not enough: WGS84 vertices on one straight line come out of the projection to
metres a fraction of a millimetre off it."""

_ROUNDING_PX = 0.5 * 2 ** 0.5 + 1e-9
"""Farthest an input vertex may lie from the rounded outline (rounding moves a vertex this far at most)."""


class FootprintError(ValueError):
    """A footprint file the placement cannot take; the message names the problem."""


@dataclass(frozen=True)
class Footprint:
    """A building outline in East-North metres.

    Attributes:
        vertices_m: ``(n, 2)`` float64 outer ring ``(x east, y north)``, metres.
        origin: The geodetic point the metres are measured from (GeoJSON input), None for metres input.
        name: A name for outputs (the GeoJSON feature's ``name`` property, else the file's stem).
        holes_m: The courtyards' rings, ``(m, 2)`` metres each.
    """

    vertices_m: np.ndarray
    origin: Home | None = None
    name: str = "building"
    holes_m: tuple[np.ndarray, ...] = ()

    def outline(self) -> Outline:
        """The building in metres, holes included, as placements are judged on it."""
        return Outline.from_rings(self.vertices_m, self.holes_m, self.name)

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


def _polygons_from_geojson(data: Any, path: Path) -> list[tuple[list, str | None]]:
    """Every polygon (its rings) of a GeoJSON object, with the name of its feature."""
    if isinstance(data, dict) and data.get("type") == "FeatureCollection":
        features = data.get("features") or []
        if not features:
            raise FootprintError(f"{path}: a FeatureCollection without features; give at least one building")
        return [p for feature in features for p in _polygons_from_geojson(feature, path)]
    name = None
    if isinstance(data, dict) and data.get("type") == "Feature":
        name = (data.get("properties") or {}).get("name")
        data = data.get("geometry")
    kind = data.get("type") if isinstance(data, dict) else None
    coordinates = data.get("coordinates") if isinstance(data, dict) else None
    if kind == "MultiPolygon" and isinstance(coordinates, list) and coordinates:
        return [(rings, name if len(coordinates) == 1 else f"{name or path.stem} part {i + 1}")
                for i, rings in enumerate(coordinates)]
    if kind != "Polygon" or not isinstance(coordinates, list) or not coordinates:
        raise FootprintError(f"{path}: no Polygon geometry (found {kind!r}); a building is a GeoJSON "
                             "Polygon or MultiPolygon")
    return [(coordinates, name)]


def site_origin(outer_rings_lonlat: list[np.ndarray]) -> Home:
    """The mean of the outer rings' distinct vertices (closing vertices once), as a geodetic origin.

    Examples:
        >>> ring = np.array([[8.0, 47.0], [8.0004, 47.0], [8.0004, 47.0002], [8.0, 47.0002], [8.0, 47.0]])
        >>> origin = site_origin([ring])  # the closing vertex (8.0, 47.0) counts once
        >>> round(origin.lon_deg, 6), round(origin.lat_deg, 6)
        (8.0002, 47.0001)
    """
    points = np.concatenate([_clean(ring) for ring in outer_rings_lonlat])
    return Home(lat_deg=float(points[:, 1].mean()), lon_deg=float(points[:, 0].mean()), alt_m=0.0)


def _read_rings(path: Path, origin: Home | None = None
                ) -> tuple[list[tuple[list[np.ndarray], str | None]], Home | None]:
    """The rings of every building of a file (metres), the geodetic origin (GeoJSON) and the names.

    GeoJSON is projected around ``origin`` when given, else around :func:`site_origin`.
    """
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
            return [([_as_points(data, path)], None)], None
        polygons = [([_as_points(ring, path) for ring in rings], name)
                    for rings, name in _polygons_from_geojson(data, path)]
        lonlat = np.concatenate([rings[0] for rings, _ in polygons])
        if len(lonlat) == 0:
            raise FootprintError(f"{path}: no vertices; a building needs at least 3")
        if np.any(np.abs(lonlat[:, 0]) > 180.0) or np.any(np.abs(lonlat[:, 1]) > 90.0):
            raise FootprintError(f"{path}: coordinates outside longitude [-180, 180] / latitude [-90, 90]; "
                                 "GeoJSON is WGS84 degrees (give metres as a plain list of vertices instead)")
        frame = origin if origin is not None else site_origin([rings[0] for rings, _ in polygons])

        def metres(ring: np.ndarray) -> np.ndarray:
            return np.array([geodetic_to_enu(frame, float(lat), float(lon), frame.alt_m)[:2]
                             for lon, lat in ring])

        return [([metres(ring) for ring in rings], name) for rings, name in polygons], frame
    if path.suffix.lower() in (".csv", ".txt"):
        rows = []
        for line in text.splitlines():
            line = line.split("#", 1)[0].strip()
            if line:
                rows.append(next(csv.reader([line.replace(" ", ",")], skipinitialspace=True)))
        return [([_as_points([[cell for cell in row if cell] for row in rows], path)], None)], None
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


def _clean(ring: np.ndarray) -> np.ndarray:
    """The ring without its closing vertex and without repeated consecutive vertices."""
    if len(ring) >= 2 and np.array_equal(ring[0], ring[-1]):
        ring = ring[:-1]
    keep = np.ones(len(ring), dtype=bool)
    keep[1:] = np.any(ring[1:] != ring[:-1], axis=1)
    return ring[keep]


def _width_m(points: np.ndarray) -> float:
    """How far the vertices spread across their best-fitting line, metres (0: collinear)."""
    centred = points - points.mean(axis=0)
    across = np.linalg.svd(centred, full_matrices=False)[2][-1]  # the direction of least spread
    return float(np.ptp(centred @ across))


def _building(rings: list[np.ndarray], origin: Home | None, name: str, where: str, max_vertices: int
              ) -> Footprint:
    rings = [_clean(ring) for ring in rings]
    points = rings[0]
    if len(points) < 3:
        raise FootprintError(f"{where}: {len(points)} distinct vertices; a building needs at least 3")
    count = sum(len(ring) for ring in rings)
    if count > max_vertices:
        raise FootprintError(f"{where}: {count} vertices; allowed at most {max_vertices}")
    width_m = _width_m(points)
    if width_m <= DEGENERATE_WIDTH_M:
        raise FootprintError(f"{where}: the outline encloses no area (degenerate: its vertices lie on one "
                             f"line, {width_m:.2g} m across at the widest; a building is at least "
                             f"{DEGENERATE_WIDTH_M} m wide)")
    if not is_simple(points):
        raise FootprintError(f"{where}: the outline is not a simple polygon (it crosses or touches itself, "
                             "or repeats a vertex)")
    footprint = Footprint(points, origin, name, tuple(rings[1:]))
    try:
        footprint.outline()
    except OutlineError as exc:
        raise FootprintError(f"{where}: {exc}") from None
    return footprint


def read_site(path: str | Path, max_vertices: int = DEFAULT_MAX_VERTICES, origin: Home | None = None
              ) -> list[Footprint]:
    """Every building of a file (see the module docstring), in one East-North frame.

    GeoJSON is projected around ``origin`` (e.g. the bridge's home) when given, else around the mean of
    the outer rings' distinct vertices (:func:`site_origin`); vertices in metres are taken as they are.

    Raises:
        FootprintError: Unreadable or unknown file, a building of fewer than 3 or more than
            ``max_vertices`` vertices, a self-intersecting or degenerate outline, a courtyard outside
            its building; the message names the building.
    """
    path = Path(path)
    buildings, frame = _read_rings(path, origin)
    out = []
    for i, (rings, name) in enumerate(buildings):
        label = name or (path.stem if len(buildings) == 1 else f"{path.stem} {i + 1}")
        where = f"{path}" if len(buildings) == 1 else f"{path} ({label})"
        out.append(_building(rings, frame, label, where, max_vertices))
    return out


def read_footprint(path: str | Path, max_vertices: int = DEFAULT_MAX_VERTICES) -> Footprint:
    """The one building of a file (:func:`read_site`; a site of several buildings is refused)."""
    site = read_site(path, max_vertices)
    if len(site) != 1:
        raise FootprintError(f"{path}: {len(site)} buildings; read a site with read_site")
    return site[0]


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
