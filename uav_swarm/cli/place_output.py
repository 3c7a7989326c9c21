"""What ``uav-swarm place`` writes: the site's GeoJSON and its picture (one record per building)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from uav_swarm.missions.monitoring.footprint import FittedFootprint, Footprint
from uav_swarm.missions.monitoring.outline_guards import Placement

__all__ = ["PlacedBuilding", "site_geojson", "plot_site"]


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
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
