"""``uav-swarm place``: guards for a user's own building (Art Gallery inside it, Fortress around it).

    uav-swarm place --task fp --building shop.geojson --out out/shop
    uav-swarm place --task agp --building hall.csv --out out/hall --method expert --bridge-config bridge.toml

The building (:mod:`uav_swarm.missions.monitoring.footprint`: a GeoJSON Polygon in WGS84, or vertices in
metres) is fitted to the monitoring raster and placed with one of three methods:

- ``learned``: the shipped network's peaks (milliseconds, no guarantee);
- ``refined`` (default): the peaks repaired until every witness is seen
  (:mod:`uav_swarm.missions.monitoring.guard_repair`);
- ``expert``: the exact set cover (fewest guards; slower).

Outputs in ``--out`` (written only when everything succeeded): ``guards.geojson`` (the guards as
points, and the building as fitted, in the input's coordinates: longitude/latitude for GeoJSON
input, metres otherwise), ``placement.json`` (method, scale, guards, coverage, time),
``placement.png`` (the building, the guards and what each sees) and, with ``--bridge-config``, one
QGroundControl ``.plan`` mission per guard in ``missions/`` (GeoJSON guards are placed in the bridge's
local frame around its home; metres are taken as East-North metres from that home).

A building the placement cannot take (holes, several parts, self-intersecting, degenerate, too many
vertices, too large for the raster at ``--max-pixel-m``, or a Fortress outline some boundary point
of which no outside pixel sees) exits with code 2, a message naming the problem and nothing written.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["register", "run"]

METHODS = ("learned", "refined", "expert")


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``place`` subcommand."""
    parser = subparsers.add_parser(
        "place", help="place guards for your own building (GeoJSON or metres), write them back and missions",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add = parser.add_argument
    add("--task", required=True, choices=("agp", "fp"), help="agp: guards inside; fp: guards outside")
    add("--building", required=True, type=Path,
        help=".geojson (WGS84 Polygon) or .json/.csv/.txt vertices (m)")
    add("--out", required=True, type=Path, help="output folder")
    add("--method", choices=METHODS, default="refined", help="placement method (default: %(default)s)")
    add("--checkpoint", help="network for learned/refined (default: uav_swarm/checkpoints/<task>.pt)")
    add("--max-pixel-m", type=float, default=10.0,
        help="refuse buildings needing more metres per raster pixel (default: %(default)s)")
    add("--bridge-config", type=Path, help="bridge TOML: home, mission shape, fence and vehicle ids")
    add("--alt-m", type=float,
        help="flight altitude above home for the missions (default: [mission] cruise_alt_m)")
    parser.set_defaults(func=run)


def _place(task: Any, scene: Any, method: str, checkpoint: str | None) -> tuple[np.ndarray, float]:
    """Guard positions (pixels) by ``method`` and the seconds it took (network included)."""
    from uav_swarm.missions.registry import build_refiner

    refiner = build_refiner(task)
    start = time.perf_counter()
    if method == "expert":
        return refiner.solve(scene), time.perf_counter() - start
    from learning.checkpoint import load_checkpoint
    from learning.inference import utility_maps
    from learning.peaks import find_peaks
    from learning.precision import resolve_precision
    from uav_swarm.planning.planner import default_checkpoint

    path = checkpoint or default_checkpoint(task.name)
    ckpt = load_checkpoint(path, task_name=task.name, input_shape=(task.channels, *task.shape))
    precision = resolve_precision("auto", next(ckpt.model.parameters()).device)
    utility_maps(ckpt.model, task.observe(scene)[None], precision)  # warm-up: time the steady state
    start = time.perf_counter()
    utility = utility_maps(ckpt.model, task.observe(scene)[None], precision)[0]
    positions = find_peaks(utility, ckpt.peak_config)
    if method == "refined":
        positions = refiner.refine(scene, positions)
    return positions, time.perf_counter() - start


def _missions(args: argparse.Namespace, fitted: Any, guards_m: np.ndarray) -> dict[int, Any]:
    """One mission per guard, by vehicle id (checked against the fence before anything is written)."""
    from bridge.config import BridgeConfig
    from bridge.geo import geodetic_to_enu
    from bridge.mission import build_mission
    from typed_config import ConfigError, load_toml

    bridge = load_toml(BridgeConfig, args.bridge_config)
    if bridge.vehicles and len(bridge.vehicles) < len(guards_m):
        raise ConfigError(f"{args.bridge_config}: {len(bridge.vehicles)} vehicles for {len(guards_m)} "
                          "guards: list at least one vehicle per guard")
    ids = [v.system_id for v in bridge.vehicles[:len(guards_m)]] or list(range(1, len(guards_m) + 1))
    alt_m = bridge.mission.cruise_alt_m if args.alt_m is None else args.alt_m
    if fitted.footprint.origin is None:
        local = guards_m
    else:
        lonlat = fitted.footprint.to_input(guards_m)
        local = np.array([geodetic_to_enu(bridge.home, lat, lon, bridge.home.alt_m)[:2]
                          for lon, lat in lonlat])
    return {sid: build_mission([(float(x), float(y), alt_m)], bridge.home, bridge.mission, bridge.geofence)
            for sid, (x, y) in zip(ids, local, strict=True)}


def _geojson(fitted: Any, guards_m: np.ndarray, seen_share: np.ndarray, method: str) -> dict[str, Any]:
    footprint = fitted.footprint
    coordinates = "WGS84 longitude, latitude" if footprint.origin is not None else "metres of the input"
    outline = footprint.to_input(fitted.to_metres(fitted.polygon.vertices_px))
    features = [{"type": "Feature", "properties": {"role": "building as placed", "name": footprint.name},
                 "geometry": {"type": "Polygon", "coordinates": [[*outline.tolist(), outline[0].tolist()]]}}]
    for i, (point, share) in enumerate(zip(footprint.to_input(guards_m), seen_share, strict=True)):
        features.append({"type": "Feature", "properties": {"role": "guard", "guard": i + 1, "method": method,
                                                           "sees_share": round(float(share), 4)},
                         "geometry": {"type": "Point", "coordinates": point.tolist()}})
    return {"type": "FeatureCollection", "coordinates": coordinates, "features": features}


def _plot(path: Path, witnesses: np.ndarray, fitted: Any, guards_px: np.ndarray, seen_by: np.ndarray,
          title: str) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from learning.files import atomic_path

    polygon = fitted.polygon
    fig = Figure(figsize=(6.0, 6.0), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    ring = np.vstack([polygon.vertices_px, polygon.vertices_px[:1]])
    ax.fill(ring[:, 0], ring[:, 1], color="0.9", zorder=0)
    ax.plot(ring[:, 0], ring[:, 1], color="black", linewidth=1.5, zorder=3)
    colours = [f"C{i % 10}" for i in range(len(guards_px))]
    for g in range(len(guards_px)):  # what each guard sees (a witness seen by several: the first guard)
        first = seen_by[g] & ~np.any(seen_by[:g], axis=0)
        ax.scatter(witnesses[first, 0], witnesses[first, 1], s=6, color=colours[g], alpha=0.5, zorder=1)
    unseen = ~np.any(seen_by, axis=0)
    ax.scatter(witnesses[unseen, 0], witnesses[unseen, 1], s=10, color="red", marker="x", zorder=2,
               label=f"unseen ({int(unseen.sum())})")
    ax.scatter(guards_px[:, 0], guards_px[:, 1], s=120, c=colours, marker="*", edgecolors="black", zorder=4,
               label=f"guards ({len(guards_px)})")
    ax.set_aspect("equal")
    ax.set_title(title, fontsize=9)
    ax.set_xlabel(f"x (pixels of {fitted.metres_per_px:.2f} m)")
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")


def run(args: argparse.Namespace) -> int:
    """Place the building's guards and write the outputs; unplaceable input exits with code 2."""
    from bridge.errors import BridgeError
    from bridge.mission_files import save_mission
    from learning.checkpoint import CheckpointError
    from learning.files import write_json_atomic
    from typed_config import ConfigError
    from uav_swarm.missions.monitoring.footprint import FootprintError, fit_to_raster, read_footprint
    from uav_swarm.missions.monitoring.setcover import InfeasibleCoverError
    from uav_swarm.missions.monitoring.task import MonitoringScene
    from uav_swarm.missions.registry import build_task

    task = build_task(args.task)
    try:
        if not args.max_pixel_m > 0:
            raise FootprintError(f"--max-pixel-m = {args.max_pixel_m}: allowed > 0")
        footprint = read_footprint(args.building)
        fitted = fit_to_raster(footprint, task.config.polygon.size_px, task.config.polygon.margin_px,
                               args.max_pixel_m)
        scene = MonitoringScene(fitted.polygon, np.zeros((0, 2)))
        positions_px, seconds = _place(task, scene, args.method, args.checkpoint)
        guards_px = np.unique(np.clip(np.rint(positions_px), 0, fitted.polygon.size_px - 1), axis=0)
        guards_m = fitted.to_metres(guards_px)
        missions = _missions(args, fitted, guards_m) if args.bridge_config else {}
    except (FootprintError, InfeasibleCoverError, CheckpointError, ConfigError) as exc:
        print(f"uav-swarm place: {exc}", file=sys.stderr)
        return 2
    except BridgeError as exc:  # the geofence refuses a guard: nothing is written
        print(f"uav-swarm place: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 2
    seen_by = task.seen_by(fitted.polygon, guards_px)  # (guards, witnesses)
    seen = np.any(seen_by, axis=0)
    quality = {"qos": float(np.all(seen)), "seen_fraction": float(np.mean(seen)) if seen.size else 1.0}
    args.out.mkdir(parents=True, exist_ok=True)
    geojson = _geojson(fitted, guards_m, seen_by.mean(axis=1), args.method)
    write_json_atomic(args.out / "guards.geojson", geojson)
    files = ["guards.geojson", "placement.json", "placement.png"]
    for sid, mission in missions.items():
        (args.out / "missions").mkdir(exist_ok=True)
        save_mission(args.out / "missions" / f"vehicle_{sid}.plan", mission)
        files.append(f"missions/vehicle_{sid}.plan")
    summary = {
        "task": task.name, "method": args.method, "building": footprint.name,
        "input_vertices": len(footprint.vertices_m), "placed_vertices": fitted.polygon.n_vertices,
        "metres_per_px": fitted.metres_per_px,
        "n_guards": len(guards_px), "guards_m": guards_m.tolist(),
        "fully_covered": bool(quality["qos"] == 1.0), "seen_fraction": quality["seen_fraction"],
        "time_ms": seconds * 1e3, "files": files,
    }
    write_json_atomic(args.out / "placement.json", summary)
    title = (f"{footprint.name}: {task.name} {args.method}, {len(guards_px)} guards, "
             f"{100 * quality['seen_fraction']:.1f} % seen")
    _plot(args.out / "placement.png", task.witnesses(fitted.polygon), fitted, guards_px, seen_by, title)
    print(f"{footprint.name}: {len(guards_px)} {args.method} guards ({task.name}), "
          f"{100 * quality['seen_fraction']:.1f} % of the witnesses seen, {seconds * 1e3:.1f} ms; "
          f"wrote {', '.join(files)} in {args.out}")
    return 0
