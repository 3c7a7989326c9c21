"""What ``uav-swarm place`` writes and says: the site's GeoJSON, its picture, where on Earth it is."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from uav_swarm.missions.monitoring.footprint import FittedFootprint, Footprint
from uav_swarm.missions.monitoring.outline_guards import Placement

__all__ = ["PlacedBuilding", "site_geojson", "plot_site", "centroid_lonlat", "frame_record", "swap_warning",
           "far_from_home"]

NEAR_HOME_M = 20_000.0
"""Farthest a site may lie from the bridge's home its guards are placed around and flown from, metres."""

POLAR_LAT_DEG = 75.0
"""Few buildings stand farther north or south than this: a latitude beyond it is likely a longitude."""


@dataclass(frozen=True)
class PlacedBuilding:
    """One building's placement.

    Attributes:
        footprint: The building as given (metres).
        rasters: The rasters the network saw (one, or one per tile; empty for the expert).
        placement: The guards and what they see on the real outline.
        seconds: Time to place it (network, repair or reference), excluding reading and writing.
    """

    footprint: Footprint
    rasters: tuple[FittedFootprint, ...]
    placement: Placement
    seconds: float


def centroid_lonlat(footprint: Footprint) -> tuple[float, float] | None:
    """The building's centroid as (longitude, latitude) degrees, None for input in metres."""
    import shapely

    if footprint.origin is None:
        return None
    centre = shapely.Polygon(footprint.vertices_m).centroid
    lon, lat = footprint.to_input(np.array([[centre.x, centre.y]]))[0]
    return float(lon), float(lat)


def frame_record(footprint: Footprint, home: Any | None = None, bridge_config: Path | None = None
                 ) -> dict[str, Any]:
    """The frame of ``guards_m`` in placement.json: East-North metres from a named origin, or the input's.

    Args:
        footprint: A building of the site (they share one frame).
        home: The bridge config's home (:class:`bridge.geo.Home`) when one was given: the origin.
        bridge_config: That config's path, to name it.
    """
    if home is not None:
        axes = ("east, north metres (local ENU, WGS84) from origin" if footprint.origin is not None else
                "x east, y north metres from origin (the input's metres, taken as such)")
        return {"guards_m": axes, "origin": {"lat_deg": home.lat_deg, "lon_deg": home.lon_deg,
                                             "alt_m": home.alt_m},
                "origin_is": f"the bridge's home ([home] of {bridge_config})"}
    origin = footprint.origin
    if origin is None:
        return {"guards_m": "x, y metres of the input (no geodetic origin: the building was given in metres)",
                "origin": None}
    return {"guards_m": "east, north metres (local ENU, WGS84) from origin",
            "origin": {"lat_deg": origin.lat_deg, "lon_deg": origin.lon_deg, "alt_m": origin.alt_m},
            "origin_is": "the mean of the outer rings' distinct vertices (each ring's closing vertex once)"}


def _swap_hint() -> str:
    return "GeoJSON coordinates are [longitude, latitude]; if the file lists [latitude, longitude], swap them"


def far_from_home(footprints: list[Footprint], home: Any) -> str | None:
    """Why a GeoJSON site cannot be placed around the bridge's ``home`` (farther than NEAR_HOME_M), or None.

    The guards are placed in East-North metres around the home and flown from it; a site far from it is
    a wrong home or, when it lies near the home with latitude and longitude swapped, a swapped file.
    """
    from bridge.geo import geodetic_to_enu

    centres = [c for c in map(centroid_lonlat, footprints) if c is not None]
    if not centres:
        return None
    lon, lat = np.mean(np.array(centres), axis=0)

    def distance_m(lat_deg: float, lon_deg: float) -> float:
        return float(np.hypot(*geodetic_to_enu(home, lat_deg, lon_deg, home.alt_m)[:2]))

    far = distance_m(lat, lon)
    if far <= NEAR_HOME_M:
        return None
    swapped = distance_m(lon, lat) if abs(lon) <= 90.0 else np.inf
    where = (f"the site's centroid (lat {lat:.5f}, lon {lon:.5f}) is {far / 1e3:.0f} km from the bridge's "
             f"home (lat {home.lat_deg:.5f}, lon {home.lon_deg:.5f}; allowed within "
             f"{NEAR_HOME_M / 1e3:.0f} km)")
    if swapped <= NEAR_HOME_M:
        return f"{where}, but {swapped / 1e3:.1f} km with latitude and longitude swapped: {_swap_hint()}"
    return f"{where}: give a bridge config whose [home] is at the site"


def swap_warning(footprints: list[Footprint]) -> str | None:
    """A warning when a GeoJSON site's latitude is implausible (beyond POLAR_LAT_DEG): likely swapped."""
    centres = [c for c in map(centroid_lonlat, footprints) if c is not None]
    if not centres:
        return None
    lon, lat = np.mean(np.array(centres), axis=0)
    if abs(lat) > POLAR_LAT_DEG:
        return (f"the site's centroid is at latitude {lat:.5f} (beyond {POLAR_LAT_DEG:g} degrees, where few "
                f"buildings stand) and longitude {lon:.5f}: {_swap_hint()}")
    return None


def _ring(footprint: Footprint, ring_m: np.ndarray) -> list[list[float]]:
    points = footprint.to_input(ring_m)
    return [*points.tolist(), points[0].tolist()]


def site_geojson(buildings: list[PlacedBuilding], method: str) -> dict[str, Any]:
    """The buildings as given, the rasters the network saw, and the guards, in the input's coordinates."""
    origin = buildings[0].footprint.origin
    features = []
    for b in buildings:
        fp = b.footprint
        features.append({"type": "Feature", "properties": {"role": "building", "name": fp.name},
                         "geometry": {"type": "Polygon", "coordinates": [
                             _ring(fp, fp.vertices_m), *(_ring(fp, hole) for hole in fp.holes_m)]}})
        for tile, fitted in enumerate(b.rasters):
            ring = _ring(fp, fitted.to_metres(fitted.polygon.vertices_px))
            features.append({"type": "Feature", "properties": {
                "role": "raster outline (what the network saw)", "name": fp.name, "tile": tile + 1,
                "metres_per_px": round(fitted.metres_per_px, 4)},
                "geometry": {"type": "Polygon", "coordinates": [ring]}})
        placement = b.placement
        witnessed = len(placement.witnesses) > 0
        shares = placement.seen_by.mean(axis=1) if witnessed else np.ones(len(placement.seen_by))
        for i, (point, share) in enumerate(zip(fp.to_input(placement.guards_m), shares, strict=True)):
            features.append({"type": "Feature", "properties": {
                "role": "guard", "name": fp.name, "guard": i + 1, "method": method,
                "sees_share": round(float(share), 4)},
                "geometry": {"type": "Point", "coordinates": point.tolist()}})
    coordinates = "WGS84 longitude, latitude" if origin is not None else "metres of the input"
    return {"type": "FeatureCollection", "coordinates": coordinates, "features": features}


def plot_site(path: Path, buildings: list[PlacedBuilding], title: str) -> None:
    """One picture of the site in metres: buildings, guards, what each guard sees, what nobody sees."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from typed_config.files import atomic_path

    fig = Figure(figsize=(7.0, 7.0), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    n_unseen = n_guards = 0
    for b in buildings:
        fp = b.footprint
        for ring, fill in [(fp.vertices_m, "0.88"), *((hole, "white") for hole in fp.holes_m)]:
            closed = np.vstack([ring, ring[:1]])
            ax.fill(closed[:, 0], closed[:, 1], color=fill, zorder=0)
            ax.plot(closed[:, 0], closed[:, 1], color="black", linewidth=1.2, zorder=3)
        placement = b.placement
        points, seen_by = placement.witnesses.points_m, placement.seen_by
        for g in range(len(placement.guards_m)):  # a witness seen by several: coloured by the first guard
            first = seen_by[g] & ~np.any(seen_by[:g], axis=0)
            ax.scatter(points[first, 0], points[first, 1], s=2, color=f"C{(n_guards + g) % 10}", alpha=0.35,
                       zorder=1, linewidths=0)
        unseen = ~np.any(seen_by, axis=0)
        ax.scatter(points[unseen, 0], points[unseen, 1], s=10, color="red", marker="x", zorder=2)
        colours = [f"C{(n_guards + g) % 10}" for g in range(len(placement.guards_m))]
        ax.scatter(placement.guards_m[:, 0], placement.guards_m[:, 1], s=110, c=colours, marker="*",
                   edgecolors="black", zorder=4)
        n_unseen += int(unseen.sum())
        n_guards += len(placement.guards_m)
    ax.plot([], [], "rx", label=f"unseen witnesses ({n_unseen})")
    ax.plot([], [], "k*", label=f"guards ({n_guards})")
    ax.set_aspect("equal")
    ax.set_title(title, fontsize=9)
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    handles, labels = ax.get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=2, fontsize=8, frameon=False)  # below the site
    fig.tight_layout(rect=(0.0, 0.04, 1.0, 1.0))
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
