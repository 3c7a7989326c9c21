"""``uav-swarm mission export|upload|download|clear``: MAVLink missions for the configured vehicles.

Vehicles, home, mission shape, geofence and protocol timing come from a bridge config
(``configs/bridge/*.toml``). Plans are local East-North-Up metres around home, the last
point of each plan the target: ``--target ID:X,Y[,Z]`` (once per vehicle, after its
``--waypoint ID:X,Y[,Z]`` points in order) or ``--plans FILE``
with JSON ``{"ID": [[x_m, y_m], [x_m, y_m, z_m], ...]}``. Mission files are named
``vehicle_<ID>.plan`` (QGroundControl) or ``vehicle_<ID>.waypoints`` (QGC WPL 110).

The vehicles' targets (each plan's last point, 2-D points at the mission's cruise altitude)
must stand at least ``--min-separation-m`` apart (3-D; default the UAVs' 5 m): export and upload
refuse closer targets, naming the pair, before anything is written or sent.

Each vehicle is handled on its own: an absent or failing vehicle does not stop the
others. Every failure is listed at the end, one line each (a vehicle's failure with its error class).
Exit codes: 0 done, 1 a vehicle failed, 2 bad input or a safety refusal (nothing sent).

Examples:
  uav-swarm mission export --config configs/bridge/px4_sitl_10.toml --target 1:40,25 --out out/missions
  uav-swarm mission upload --config configs/bridge/px4_sitl_10.toml --target 1:40,25 --target 2:-30,10,45
  uav-swarm mission upload --config configs/bridge/ardupilot_sitl_10.toml --from-dir out/missions
  uav-swarm mission download --config configs/bridge/px4_sitl_10.toml --out out/downloaded
  uav-swarm mission clear --config configs/bridge/px4_sitl_10.toml --vehicle 1 --vehicle 2
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from uav_swarm.cli.conventions import output_flag

if TYPE_CHECKING:  # the command imports the bridge on use, not at start-up
    from collections.abc import Iterable

    from bridge.config import BridgeConfig
    from bridge.flight.fleet import Fleet, MissionBuilder
    from bridge.missions.items import Mission

__all__ = ["register", "run", "parse_target", "read_plans"]

_AUTOPILOTS = {
    "generic": "MAV_AUTOPILOT_GENERIC",
    "ardupilot": "MAV_AUTOPILOT_ARDUPILOTMEGA",
    "px4": "MAV_AUTOPILOT_PX4",
}
_SUFFIX = {"plan": ".plan", "waypoints": ".waypoints"}


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``mission`` subcommand and its four actions."""
    parser = subparsers.add_parser(
        "mission",
        help="export, upload, download or clear MAVLink missions",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("action", choices=("export", "upload", "download", "clear"), help="what to do")
    add = parser.add_argument
    add("--config", type=Path, required=True, help="bridge config TOML (configs/bridge/*.toml)")
    add(
        "--target",
        action="append",
        default=[],
        metavar="ID:X,Y[,Z]",
        help="the target of one vehicle in ENU metres (once per vehicle; repeat for other vehicles; "
             "default: none)",
    )
    add(
        "--waypoint",
        action="append",
        default=[],
        metavar="ID:X,Y[,Z]",
        help="an intermediate point of one vehicle, flown before its target (repeatable, in order; "
             "default: none)",
    )
    add("--plans", type=Path, help='JSON file {"ID": [[x_m, y_m(, z_m)], ...]} (default: none)')
    add("--from-dir", type=Path,
        help="upload: the vehicle_<ID>.plan/.waypoints files of this folder (default: none)")
    output_flag(parser, "--out", "folder",
        help="export/download: folder for vehicle_<ID> files (required there; default: none)")
    add("--format", choices=tuple(_SUFFIX), default="plan", help="mission file format (default: %(default)s)")
    add(
        "--autopilot",
        choices=tuple(_AUTOPILOTS),
        default="generic",
        help="export: autopilot convention (ardupilot adds the home placeholder; default: %(default)s)",
    )
    add(
        "--vehicle",
        type=int,
        action="append",
        default=[],
        metavar="ID",
        help="download/clear: only these vehicles (repeatable; default: all)",
    )
    add("--min-separation-m", type=float, default=None, metavar="M",
        help="export/upload: least distance between two vehicles' targets, metres (default: [uav] "
             "min_separation_m's default, 5; 0: no check)")
    add("--no-verify", action="store_true", help="upload: skip the download-and-compare check")
    add(
        "--strict",
        action="store_true",
        help="upload: compare the mission read back exactly, accepting none of ArduPilot's known changes",
    )
    add(
        "--force",
        action="store_true",
        help="upload/clear: replace or clear a mission a vehicle is flying (armed in AUTO / AUTO.MISSION)",
    )
    parser.set_defaults(func=run)


def parse_target(text: str, option: str = "--target") -> tuple[int, list[float]]:
    """``"ID:X,Y[,Z]"`` -> ``(ID, [x_m, y_m(, z_m)])``, ``ID`` a MAVLink system id 1-255.

    Raises:
        ValueError: Malformed text, or an id outside 1-255 (0 is MAVLink's broadcast id).
    """
    try:
        system_id, coords = text.split(":", 1)
        values = [float(v) for v in coords.split(",")]
        if len(values) not in (2, 3):
            raise ValueError
        sid = int(system_id)
    except ValueError:
        raise ValueError(f"{option} {text!r}: expected ID:X,Y or ID:X,Y,Z (metres East, North, Up)") from None
    if not 1 <= sid <= 255:
        raise ValueError(f"{option} {text!r}: vehicle id {sid} is out of range: allowed 1-255 "
                         "(0 is MAVLink's broadcast id)")
    return sid, values


_JSON_TYPES = {dict: "object", list: "array", str: "string", int: "number", float: "number",
               bool: "boolean", type(None): "null"}


def _is_number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def read_plans(path: Path) -> dict[int, list[list[float]]]:
    """The plans of a ``--plans`` file: JSON ``{"ID": [[x_m, y_m(, z_m)], ...]}``, ``ID`` 1-255.

    Raises:
        ValueError: Not JSON, not an object, a key that is no vehicle id, or a plan that is not a
            non-empty list of 2 or 3 finite numbers each (the message names the file and the entry).
    """
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ValueError(f"--plans {path}: cannot read it ({exc.strerror})") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"--plans {path}: not valid JSON ({exc.msg}, line {exc.lineno})") from None
    expected = '{"ID": [[x_m, y_m], [x_m, y_m, z_m], ...]} with one key per vehicle id'
    if not isinstance(data, dict):
        raise ValueError(f"--plans {path}: a JSON {_JSON_TYPES.get(type(data), 'value')}; expected an object "
                         f"{expected}")
    plans: dict[int, list[list[float]]] = {}
    for key, points in data.items():
        if not key.strip().isdigit() or not 1 <= int(key) <= 255:
            raise ValueError(f"--plans {path}: key {key!r} is not a vehicle id (1-255); expected {expected}")
        valid = isinstance(points, list) and points and all(
            isinstance(p, list) and len(p) in (2, 3) and all(_is_number(v) for v in p) for p in points)
        if not valid:
            raise ValueError(f"--plans {path}: vehicle {key}: {json.dumps(points)[:80]} is not a list "
                             "of points [x_m, y_m] or [x_m, y_m, z_m] (finite numbers, at least the target)")
        plans[int(key)] = [[float(v) for v in p] for p in points]
    return plans


def _plans(args: argparse.Namespace) -> dict[int, list[list[float]]]:
    """Each vehicle's plan: its ``--waypoint`` points in order, then its one ``--target`` (or ``--plans``)."""
    plans: dict[int, list[list[float]]] = {}
    if args.plans is not None:
        plans.update(read_plans(args.plans))
    targets: dict[int, list[float]] = {}
    for text in args.target:
        system_id, point = parse_target(text)
        if system_id in targets or system_id in plans:
            raise ValueError(f"--target {text!r}: vehicle {system_id} already has a target; give one "
                             "--target per vehicle and its intermediate points as "
                             f"--waypoint {system_id}:X,Y[,Z]")
        targets[system_id] = point
    waypoints: dict[int, list[list[float]]] = {}
    for text in args.waypoint:
        system_id, point = parse_target(text, "--waypoint")
        if system_id not in targets:
            raise ValueError(f"--waypoint {text!r}: vehicle {system_id} has no --target to fly to after it")
        waypoints.setdefault(system_id, []).append(point)
    for system_id, point in targets.items():
        plans[system_id] = [*waypoints.get(system_id, []), point]
    return plans


def _check_plans(plans: dict[int, list[list[float]]], config: BridgeConfig) -> None:
    """Refuse, before any network wait, plans for vehicles the config lacks or outside the fence."""
    from bridge.missions.items import build_mission

    _check_ids(plans, config)
    for sid, points in plans.items():
        try:
            build_mission(points, config.home, config.mission, config.geofence)  # before any wait
        except ValueError as exc:
            raise type(exc)(f"vehicle {sid}: {exc}") from None


def _check_separation(plans: dict[int, list[list[float]]], config: BridgeConfig,
                      min_separation_m: float | None) -> None:
    """Refuse two vehicles' targets (last points, 3-D) closer than ``--min-separation-m``."""
    from uav_swarm.world.uav import UAVConfig

    minimum = UAVConfig().min_separation_m if min_separation_m is None else min_separation_m
    if not (minimum >= 0.0 and math.isfinite(minimum)):
        raise ValueError(f"--min-separation-m = {minimum}: allowed a finite value >= 0")
    ids = sorted(plans)
    cruise = config.mission.cruise_alt_m
    ends = [plans[sid][-1] for sid in ids]
    targets = [(*end[:2], end[2] if len(end) == 3 else cruise) for end in ends]
    for a in range(len(ids)):
        for b in range(a + 1, len(ids)):
            gap = math.dist(targets[a], targets[b])
            if gap < minimum:
                raise ValueError(
                    f"the targets of vehicles {ids[a]} and {ids[b]} are {gap:.2f} m apart: allowed >= "
                    f"--min-separation-m = {minimum:g} m (move a target, or give the vehicles different "
                    "altitudes)")


def _check_ids(ids: Iterable[int], config: BridgeConfig) -> None:
    """Refuse vehicle ids the bridge config lacks, naming the configured ones."""
    configured = sorted(v.system_id for v in config.vehicles)
    unknown = sorted(set(ids) - set(configured))
    if unknown:
        raise ValueError(f"vehicle(s) {unknown} are not in the bridge config; configured vehicle ids: "
                         f"{configured}")


def _mission_files(folder: Path) -> dict[int, Path]:
    files = {}
    for path in sorted(folder.glob("vehicle_*")):
        stem = path.stem.removeprefix("vehicle_")
        if stem.isdigit() and path.suffix in (".plan", ".waypoints"):
            files[int(stem)] = path
    if not files:
        raise ValueError(f"--from-dir {folder}: no vehicle_<ID>.plan or vehicle_<ID>.waypoints files")
    return files


def run(args: argparse.Namespace) -> int:
    """Run one mission action; returns the exit code (1: a vehicle failed, 2: bad input)."""
    import typed_config
    from bridge.config import BridgeConfig
    from bridge.errors import BridgeError

    config = typed_config.load_toml(BridgeConfig, args.config)
    try:
        return _ACTIONS[args.action](args, config)
    except BridgeError as exc:
        _say(args.action, exc)
        return 2 if isinstance(exc, ValueError) else 1
    except (ValueError, OSError, KeyError) as exc:  # bad input, unusable endpoint, unknown vehicle
        _say(args.action, exc)
        return 2


def _say(action: str, exc: BaseException) -> None:
    """One line on stderr: the action and the message (a vehicle's failure also its error class)."""
    text = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
    kind = "" if isinstance(exc, ValueError) else f"{type(exc).__name__}: "
    print(f"uav-swarm mission {action}: {kind}{text}", file=sys.stderr)


def _report(action: str, errors: dict[int, BaseException]) -> int:
    """List every vehicle's failure, one line each; the exit code (2 when all are refusals, nothing sent)."""
    from bridge.errors import RefusedError

    for _, exc in sorted(errors.items()):
        _say(action, exc)
    if not errors:
        return 0
    return 2 if all(isinstance(e, (RefusedError, ValueError)) for e in errors.values()) else 1


def _present(fleet: Fleet, ids: list[int]) -> tuple[list[int], dict[int, BaseException]]:
    """The vehicles that answer (each within its own discovery time), and the others' errors."""
    from bridge.flight.fleet import FleetError

    try:
        fleet.wait_for_vehicles(ids)
    except FleetError as exc:
        return [sid for sid in ids if sid not in exc.errors], exc.errors
    return ids, {}


def _export(args: argparse.Namespace, config: BridgeConfig) -> int:
    from pymavlink.dialects.v20 import common as mavlink

    from bridge.missions.files import save_mission
    from bridge.missions.items import build_mission

    plans = _plans(args)
    if not plans or args.out is None:
        raise ValueError("export needs --target or --plans, and --out")
    _check_plans(plans, config)  # unknown vehicles and points outside the fence refused, naming the vehicle
    _check_separation(plans, config, args.min_separation_m)
    missions = {
        sid: build_mission(
            points,
            config.home,
            config.mission,
            config.geofence,
            getattr(mavlink, _AUTOPILOTS[args.autopilot]),
        )
        for sid, points in plans.items()
    }
    args.out.mkdir(parents=True, exist_ok=True)
    for sid, mission in sorted(missions.items()):
        path = args.out / f"vehicle_{sid}{_SUFFIX[args.format]}"
        save_mission(path, mission)
        print(f"vehicle {sid}: {len(mission.items)} items -> {path}")
    return 0


def _plan_builder(points: list[list[float]], config: BridgeConfig) -> MissionBuilder:
    """Build a plan's mission around the home the fleet gives (the config's or the vehicle's own)."""
    from bridge.missions.items import build_mission

    mission, fence = config.mission, config.geofence
    return lambda sid, autopilot, home: build_mission(points, home, mission, fence, autopilot)


def _file_builder(path: Path, config: BridgeConfig) -> MissionBuilder:
    """Load a mission file (absolute positions: its own home, or the config's for WPL) for its vehicle."""
    from pymavlink.dialects.v20 import common as mavlink

    from bridge.missions.files import load_mission

    def build(sid: int, autopilot: int, _home: object) -> Mission:
        mission = load_mission(path, config.home, autopilot)
        ardupilot = mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
        if (mission.autopilot == ardupilot) != (autopilot == ardupilot) and path.suffix == ".plan":
            raise ValueError(
                f"{path}: written for autopilot {mission.autopilot}, vehicle {sid} "
                f"runs {autopilot} (ArduPilot's home placeholder differs)"
            )
        return mission

    return build


def _upload(args: argparse.Namespace, config: BridgeConfig) -> int:
    from bridge.flight.fleet import Delivery, Fleet, FleetError

    plans = _plans(args)
    if bool(plans) == (args.from_dir is not None):
        raise ValueError("upload needs either --target/--plans or --from-dir")
    if plans:
        _check_plans(plans, config)
        _check_separation(plans, config, args.min_separation_m)
        builders = {sid: _plan_builder(points, config) for sid, points in plans.items()}
    else:
        files = _mission_files(args.from_dir)
        _check_ids(files, config)
        builders = {sid: _file_builder(path, config) for sid, path in files.items()}
    with Fleet(config) as fleet:
        try:
            done, errors = fleet.deliver(builders, verify=not args.no_verify, strict=args.strict,
                                         force=args.force), {}
        except FleetError as exc:
            done = {sid: d for sid, d in exc.results.items() if isinstance(d, Delivery)}  # all are
            errors = exc.errors
    for sid, delivery in sorted(done.items()):
        verified = ("not verified (--no-verify)" if delivery.verify_s is None
                    else f"verified (download and compare) in {delivery.verify_s:.3f} s")
        home = (f"; home from its {delivery.reported_home.source}" if config.home_source == "vehicle"
                and delivery.reported_home is not None else "")
        print(f"vehicle {sid}: uploaded {len(delivery.mission.items)} items in {delivery.upload_s:.3f} s, "
              f"{verified}{home}")
    return _report(args.action, errors)


def _download(args: argparse.Namespace, config: BridgeConfig) -> int:
    from bridge.flight.fleet import Fleet, FleetError
    from bridge.missions.files import save_mission
    from bridge.missions.items import Mission

    if args.out is None:
        raise ValueError("download needs --out")
    _check_ids(args.vehicle, config)
    with Fleet(config) as fleet:
        ids, errors = _present(fleet, args.vehicle or list(fleet.system_ids))
        try:
            missions = fleet.download(ids) if ids else {}
        except FleetError as exc:
            missions = {sid: m for sid, m in exc.results.items() if isinstance(m, Mission)}  # all are
            errors = {**errors, **exc.errors}
    args.out.mkdir(parents=True, exist_ok=True)
    for sid, mission in sorted(missions.items()):
        path = args.out / f"vehicle_{sid}{_SUFFIX[args.format]}"
        save_mission(path, mission)
        print(f"vehicle {sid}: {len(mission.items)} items -> {path}")
    return _report(args.action, errors)


def _clear(args: argparse.Namespace, config: BridgeConfig) -> int:
    from bridge.flight.fleet import Fleet, FleetError

    _check_ids(args.vehicle, config)
    with Fleet(config) as fleet:
        ids, errors = _present(fleet, args.vehicle or list(fleet.system_ids))
        try:
            if ids:
                fleet.clear(ids, force=args.force)
        except FleetError as exc:
            errors = {**errors, **exc.errors}
    for sid in sorted(set(ids) - set(errors)):
        print(f"vehicle {sid}: mission cleared")
    return _report(args.action, errors)


_ACTIONS = {"export": _export, "upload": _upload, "download": _download, "clear": _clear}
