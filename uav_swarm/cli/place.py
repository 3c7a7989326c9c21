"""``uav-swarm place``: guards for a user's own buildings (Art Gallery inside, Fortress around).

    uav-swarm place --task fp --building shop.geojson --out out/shop
    uav-swarm place --task agp --building site.geojson --out out/site --method expert \
        --bridge-config bridge.toml

The buildings (:mod:`uav_swarm.missions.monitoring.footprint`: GeoJSON in WGS84, a Polygon with or without
courtyards, a MultiPolygon or a FeatureCollection of a whole site, or vertices in metres) are placed one
by one, each on its own outline in metres (:mod:`uav_swarm.missions.monitoring.outline`): witnesses every
``--witness-spacing-m`` (interior grid and vertices for AGP, walls for FP), sight lines keeping
``--min-clearance-m`` from the walls, guards ``--standoff-m`` from them and ``--min-separation-m`` from each
other, across all the buildings (guards fly: the UAVs' minimum separation). Three methods:

- ``learned``: the shipped network's peaks on the raster, as they are (milliseconds, no guarantee);
- ``refined`` (default): the peaks repaired on the real outline until every witness is seen
  (:func:`uav_swarm.missions.monitoring.outline_guards.repair_on_outline`);
- ``expert``: the exact reference on the real outline (the fewest guards of a 1 m lattice; slower).

The raster is only the network's input. A building wider than the raster at ``--max-pixel-m`` is shown
to the network in tiles (at most 8 x 8, i.e. up to 8 x 55 x ``--max-pixel-m`` metres); a part whose
rounded raster outline is not simple gets no proposals, and the repair covers it.

Outputs in ``--out`` (written only when every building succeeded): ``guards.geojson`` (the buildings as
given, the raster outlines the network saw, the guards; longitude/latitude for GeoJSON input, metres
otherwise), ``placement.json`` (per building: its centroid in latitude and longitude, guards in metres,
witnesses, coverage on the real outline, time; ``frame``: the origin of the guards' metres and what it is;
``missions``: which vehicle flies which guard; ``peaks``: the peak settings the network ran with and their
source), ``placement.png`` (the site in metres, what each guard sees, what nobody sees) and, with
``--bridge-config``, one QGroundControl ``.plan`` mission per guard in ``missions/`` (``uav-swarm mission
upload --config BRIDGE --from-dir OUT/missions`` sends them).

One frame: with ``--bridge-config`` the guards are East-North metres around the bridge's home (GeoJSON is
projected around it; metres are taken as East-North metres from it), the frame the missions fly in;
without, around the mean of the outer rings' distinct vertices (GeoJSON), or the input's own metres.

Each building's line names its centroid in latitude and longitude. GeoJSON lists [longitude, latitude]:
a site more than 20 km from the bridge's home is refused (exit 2), naming the swap when the site lies near
the home with the two swapped; without a bridge config, a site beyond 75 degrees of latitude is warned
about on stderr.

Input the placement cannot take (a self-intersecting or degenerate outline, a courtyard outside its
building, too many vertices, a building wider than the tiles allow, witnesses no guard position sees
with the margin, named in metres, or none keeping ``--min-separation-m``, named as the cause, a guard
outside the bridge's geofence, named with its vehicle) exits with code 2, a message naming the problem
and nothing written.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from uav_swarm.cli.conventions import config_flag, number, run_folder_flag

if TYPE_CHECKING:
    import numpy as np

__all__ = ["register", "run", "load_network", "propose", "place_building"]

METHODS = ("learned", "refined", "expert")

MAX_TILES_PER_SIDE = 8
"""Most raster tiles a side a building is shown to the network in."""

logger = logging.getLogger(__name__)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``place`` subcommand."""
    parser = subparsers.add_parser(
        "place", help="place guards for your own buildings (GeoJSON or metres), write them back and missions",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add = parser.add_argument
    sight = "uav_swarm.missions.monitoring.outline_guards:SightConfig."
    add("--task", required=True, choices=("agp", "fp"), help="agp: guards inside; fp: guards outside")
    add("--building", required=True, type=Path,
        help=".geojson (WGS84 Polygon, MultiPolygon or FeatureCollection) or .json/.csv/.txt vertices (m)")
    run_folder_flag(parser, "--out", required=True, help="output folder")
    add("--method", choices=METHODS, default="refined", help="placement method")
    add("--checkpoint",
        help="network for learned/refined (default: the shipped uav_swarm/checkpoints/<task>.pt)")
    add("--operating-point", choices=("mission", "balanced"),
        help="the checkpoint's peak settings, chosen for the mission's QoS or for corr + precision "
             "(default: mission where the checkpoint has it, else balanced)")
    add("--config", type=Path, help="task settings TOML whose [peaks] table applies over the checkpoint's "
                                    "peak settings (default: none)")
    add("--max-pixel-m", type=number(float, gt=0.0), default=10.0,
        help="coarsest raster the network sees; wider buildings are shown in tiles")
    config_flag(parser, "--witness-spacing-m", sight + "witness_spacing_m", key="")
    config_flag(parser, "--min-clearance-m", sight + "min_clearance_m", key="")
    config_flag(parser, "--standoff-m", sight + "standoff_m", key="")
    config_flag(parser, "--min-separation-m", sight + "min_separation_m", key="")
    add("--bridge-config", type=Path,
        help="bridge TOML: home, mission shape, fence and vehicle ids (default: none, no missions)")
    add("--alt-m", type=number(float, gt=0.0),
        help="flight altitude above home for the missions (default: [mission] cruise_alt_m)")
    parser.set_defaults(func=run)


def _tiles(footprint: Any, size_px: int, margin_px: int, max_pixel_m: float) -> list[Any]:
    """The pieces of the outer ring the network sees, each fitting the raster at ``max_pixel_m``."""
    import numpy as np
    import shapely

    from uav_swarm.missions.monitoring.footprint import Footprint, FootprintError

    side_m = (size_px - 1 - 2 * margin_px) * max_pixel_m
    low, extent = footprint.vertices_m.min(axis=0), np.ptp(footprint.vertices_m, axis=0)
    counts = np.maximum(1, np.ceil(extent / side_m - 1e-9)).astype(np.int64)
    if counts.max() > MAX_TILES_PER_SIDE:
        raise FootprintError(
            f"{footprint.name}: {extent.max():.0f} m wide: at --max-pixel-m {max_pixel_m} it needs "
            f"{counts.max()} tiles a side, allowed at most {MAX_TILES_PER_SIDE} (up to "
            f"{MAX_TILES_PER_SIDE * side_m:.0f} m; raise --max-pixel-m)")
    if counts.max() == 1:
        return [Footprint(footprint.vertices_m, name=footprint.name)]
    outer, step = shapely.Polygon(footprint.vertices_m), extent / counts
    pieces = []
    for i in range(counts[0]):
        for j in range(counts[1]):
            x0, y0 = low + step * (i, j)
            clipped = outer.intersection(shapely.box(x0, y0, x0 + step[0], y0 + step[1]))
            for part in getattr(clipped, "geoms", [clipped]):
                if isinstance(part, shapely.Polygon) and part.area > 0:
                    pieces.append(Footprint(np.asarray(part.exterior.coords)[:-1], name=footprint.name))
    return pieces


def propose(task: Any, footprint: Any, network: Any, max_pixel_m: float, min_separation_m: float = 0.0
            ) -> tuple[np.ndarray, tuple]:
    """The network's peaks (metres) over the building's raster or tiles, and the rasters it saw.

    Each raster's peaks stand ``min_separation_m`` apart; across tiles a peak closer than that to an earlier
    one is dropped.
    """
    import numpy as np

    from learning.inference import utility_maps
    from learning.peaks import find_peaks
    from uav_swarm.missions.monitoring.footprint import FootprintError, fit_to_raster
    from uav_swarm.missions.monitoring.task import MonitoringScene

    model, precision, peaks = network
    size, margin = task.config.polygon.size_px, task.config.polygon.margin_px
    rasters = []
    for piece in _tiles(footprint, size, margin, max_pixel_m):
        try:
            rasters.append(fit_to_raster(piece, size, margin, max_pixel_m))
        except FootprintError as exc:  # the repair covers this part without proposals
            logger.info("%s: the network sees no raster of a part: %s", footprint.name, exc)
    if not rasters:
        return np.zeros((0, 2)), ()
    observed = np.stack([task.observe(MonitoringScene(r.polygon, np.zeros((0, 2)))) for r in rasters])
    utility = utility_maps(model, observed, precision)
    proposals = np.concatenate([
        r.to_metres(find_peaks(u, peaks.config, raster=x,
                               min_separation_px=min_separation_m / r.metres_per_px))
        for r, u, x in zip(rasters, utility, observed, strict=True)])
    return _separated(proposals, np.zeros((0, 2)), min_separation_m), tuple(rasters)


def _separated(points_m: np.ndarray, fixed_m: np.ndarray, min_separation_m: float) -> np.ndarray:
    """The points in order, each dropped when closer than ``min_separation_m`` to a fixed or kept one."""
    import numpy as np
    kept = [np.asarray(p) for p in fixed_m]
    out = []
    for p in points_m:
        if all(np.hypot(*(p - q)) >= min_separation_m for q in kept):
            kept.append(p)
            out.append(p)
    return np.array(out, dtype=np.float64).reshape(-1, 2)


def load_network(task: Any, checkpoint: str | None, operating_point: str | None = None,
                 config: Path | None = None) -> tuple[Any, Any, Any]:
    """The network (on one thread, as the planner runs it), its precision and peaks, warmed up.

    The peaks (:class:`learning.operating_points.PeakChoice`) are the checkpoint's ``operating_point``
    with the ``[peaks]`` table of ``config`` over it.

    Raises:
        ConfigError: A ``[peaks]`` value that cannot apply, or an operating point the checkpoint lacks.
    """
    import numpy as np
    import torch

    from learning.checkpoint import load_checkpoint
    from learning.inference import utility_maps
    from learning.operating_points import choose_peaks
    from learning.precision import resolve_precision
    from uav_swarm.missions.registry import load_settings
    from uav_swarm.planning.planner import default_checkpoint

    torch.set_num_threads(1)  # one building at a time: more threads only wait on each other
    path = checkpoint or default_checkpoint(task.name)
    ckpt = load_checkpoint(path, task_name=task.name, input_shape=(task.channels, *task.shape))
    given = load_settings(task.name, config).peaks_given if config is not None else {}
    peaks = choose_peaks(ckpt.peak_config, ckpt.mission_peak_config, given, operating_point=operating_point,
                         source=f"config file {config}")
    precision = resolve_precision("auto", next(ckpt.model.parameters()).device)
    utility_maps(ckpt.model, np.zeros((1, task.channels, *task.shape), dtype=np.float32), precision)
    return ckpt.model, precision, peaks


def place_building(task: Any, footprint: Any, method: str, network: Any, sight: Any, max_pixel_m: float,
                   fixed_m: np.ndarray | None = None) -> Any:
    """One building's placement by ``method``, judged on its real outline.

    Its guards keep ``sight.min_separation_m`` between them and to ``fixed_m`` (other buildings' guards).
    """
    import numpy as np

    from uav_swarm.cli.place_output import PlacedBuilding
    from uav_swarm.missions.monitoring.outline_guards import judge, reference_guards, repair_on_outline

    outline = footprint.outline()
    fixed = np.zeros((0, 2)) if fixed_m is None else fixed_m
    start = time.perf_counter()
    if method == "expert":
        placement, rasters = reference_guards(outline, task.region, sight, fixed), ()
    else:
        proposals, rasters = propose(task, footprint, network, max_pixel_m, sight.min_separation_m)
        if method == "refined":
            placement = repair_on_outline(outline, task.region, proposals, sight, fixed)
        else:
            guards_m = _separated(proposals, fixed, sight.min_separation_m)
            placement = judge(outline, task.region, guards_m, sight)
    return PlacedBuilding(footprint, rasters, placement, time.perf_counter() - start)


def _missions(args: argparse.Namespace, bridge: Any, buildings: list[Any]) -> dict[int, Any]:
    """One mission per guard, by vehicle id (checked against the fence before anything is written).

    The guards are East-North metres around the bridge's home already (the site was read in that frame).
    """
    from bridge.errors import GeofenceError
    from bridge.missions.items import build_mission
    from typed_config import ConfigError

    guards = [(b.footprint.name, i + 1, g) for b in buildings for i, g in enumerate(b.placement.guards_m)]
    if bridge.vehicles and len(bridge.vehicles) < len(guards):
        raise ConfigError(f"{args.bridge_config}: {len(bridge.vehicles)} vehicles for {len(guards)} "
                          "guards: list at least one vehicle per guard")
    ids = [v.system_id for v in bridge.vehicles[:len(guards)]] or list(range(1, len(guards) + 1))
    alt_m = bridge.mission.cruise_alt_m if args.alt_m is None else args.alt_m
    missions = {}
    for sid, (name, guard, (x, y)) in zip(ids, guards, strict=True):
        try:
            missions[sid] = build_mission([(float(x), float(y), alt_m)], bridge.home, bridge.mission,
                                          bridge.geofence)
        except GeofenceError as exc:
            raise GeofenceError(f"vehicle {sid} ({name}, guard {guard}): {exc}") from None
    return missions


def counted(n: int, noun: str) -> str:
    """``n`` and the noun, plural unless one.

    Examples:
        >>> counted(1, "guard"), counted(3, "guard"), counted(0, "building")
        ('1 guard', '3 guards', '0 buildings')
    """
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


def run(args: argparse.Namespace) -> int:
    """Place every building's guards and write the outputs; unplaceable input exits with code 2."""
    import numpy as np

    from bridge.config import BridgeConfig
    from bridge.errors import BridgeError
    from bridge.missions.files import save_mission
    from learning.checkpoint import CheckpointError
    from typed_config import ConfigError, load_toml
    from typed_config.files import write_json_atomic
    from uav_swarm.cli.place_output import (
        centroid_lonlat,
        far_from_home,
        frame_record,
        plot_site,
        site_geojson,
        swap_warning,
    )
    from uav_swarm.missions.monitoring.footprint import FootprintError, read_site
    from uav_swarm.missions.monitoring.outline import OutlineError
    from uav_swarm.missions.monitoring.outline_guards import SightConfig
    from uav_swarm.missions.monitoring.setcover import InfeasibleCoverError
    from uav_swarm.missions.registry import build_task

    task = build_task(args.task)
    start = time.perf_counter()
    try:
        given = {"witness_spacing_m": args.witness_spacing_m, "min_clearance_m": args.min_clearance_m,
                 "standoff_m": args.standoff_m, "min_separation_m": args.min_separation_m}
        sight = SightConfig(**{key: value for key, value in given.items() if value is not None})
        bridge = load_toml(BridgeConfig, args.bridge_config) if args.bridge_config else None
        site = read_site(args.building)
        far = None if bridge is None else far_from_home(site, bridge.home)
        if far:
            raise FootprintError(f"{args.building}: {far}")
        if bridge is not None:  # the guards in the bridge's East-North frame, around its home
            site = read_site(args.building, origin=bridge.home)
        warning = swap_warning(site)
        if warning:
            print(f"uav-swarm place: warning: {args.building}: {warning}", file=sys.stderr)
        network = None if args.method == "expert" else load_network(task, args.checkpoint,
                                                                    args.operating_point, args.config)
        buildings: list[Any] = []
        for footprint in site:
            placed = np.concatenate([np.zeros((0, 2)), *(b.placement.guards_m for b in buildings)])
            buildings.append(place_building(task, footprint, args.method, network, sight, args.max_pixel_m,
                                            placed))
        guards_m = np.concatenate([b.placement.guards_m for b in buildings])
        missions = _missions(args, bridge, buildings) if bridge is not None else {}
    except (FootprintError, OutlineError, InfeasibleCoverError, CheckpointError, ConfigError) as exc:
        print(f"uav-swarm place: {exc}", file=sys.stderr)
        return 2
    except BridgeError as exc:  # the geofence refuses a guard: nothing is written
        print(f"uav-swarm place: {exc}", file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    write_json_atomic(args.out / "guards.geojson", site_geojson(buildings, args.method))
    files = ["guards.geojson", "placement.json", "placement.png"]
    guard_of = [(b.footprint.name, i + 1) for b in buildings for i in range(len(b.placement.guards_m))]
    flown = []
    for (sid, mission), (name, guard) in zip(missions.items(), guard_of, strict=False):
        (args.out / "missions").mkdir(exist_ok=True)
        save_mission(args.out / "missions" / f"vehicle_{sid}.plan", mission)
        files.append(f"missions/vehicle_{sid}.plan")
        flown.append({"vehicle": sid, "building": name, "guard": guard,
                      "file": f"missions/vehicle_{sid}.plan"})
    records = []
    for b in buildings:
        placement = b.placement
        seen = np.any(placement.seen_by, axis=0)
        centre = centroid_lonlat(b.footprint)
        records.append({
            "building": b.footprint.name,
            "centroid": None if centre is None else {"lat_deg": centre[1], "lon_deg": centre[0]},
            "vertices": b.footprint.outline().n_vertices,
            "courtyards": len(b.footprint.holes_m), "n_guards": len(placement.guards_m),
            "guards_m": placement.guards_m.tolist(), "n_proposals": placement.n_proposals,
            "n_added": placement.n_added, "n_pruned": placement.n_pruned,
            "n_witnesses": len(placement.witnesses), "n_unseen": int((~seen).sum()),
            "fully_covered": bool(np.all(seen)), "seen_fraction": placement.seen_fraction,
            "raster_metres_per_px": [r.metres_per_px for r in b.rasters], "time_ms": b.seconds * 1e3})
    summary = {
        "task": task.name, "method": args.method, "judged_on": "the input outline in metres", "sight": {
            "witness_spacing_m": sight.witness_spacing_m, "min_clearance_m": sight.min_clearance_m,
            "standoff_m": sight.standoff_m, "min_separation_m": sight.min_separation_m},
        "frame": frame_record(site[0], None if bridge is None else bridge.home, args.bridge_config),
        "peaks": None if network is None else network[2].to_dict(),
        "n_guards": len(guards_m),
        "fully_covered": all(r["fully_covered"] for r in records),
        "buildings": records, "missions": flown, "time_ms": (time.perf_counter() - start) * 1e3,
        "files": files}
    write_json_atomic(args.out / "placement.json", summary)
    n_seen = sum(r["n_witnesses"] - r["n_unseen"] for r in records)
    n_all = sum(r["n_witnesses"] for r in records)
    share = 100.0 * n_seen / n_all if n_all else 100.0
    title = (f"{args.building.name}: {task.name} {args.method}, {counted(len(guards_m), 'guard')}, "
             f"{share:.1f} % seen")
    plot_site(args.out / "placement.png", buildings, title)
    for r in records:
        where = ("" if r["centroid"] is None else
                 f" at lat {r['centroid']['lat_deg']:.6f}, lon {r['centroid']['lon_deg']:.6f}")
        print(f"{r['building']}{where}: {counted(r['n_guards'], args.method + ' guard')} ({task.name}), "
              f"{100 * r['seen_fraction']:.1f} % of {r['n_witnesses']} witnesses seen on the outline "
              f"({r['n_unseen']} unseen), {r['time_ms']:.0f} ms")
    if network is not None:
        print(f"peaks: {json.dumps(network[2].config.to_dict())} from the {network[2].source}")
    print(f"{counted(len(records), 'building')}, {counted(len(guards_m), 'guard')}, {share:.1f} % of the "
          "witnesses seen; "
          f"wrote {', '.join(files)} in {args.out}")
    return 0
