"""``uav-swarm fly``: the planner flies real or SITL autopilots over the simulated crowd, live.

Every vehicle of the bridge config is waited for (heartbeat, then its position fix and its home, each
vehicle on its own, for at most --wait-ready-s, saying what it waits for) and checked before any is
armed: take-off positions at least ``[uav] min_separation_m`` apart (its own home, or the ``[launch]``
grid), its link-loss failsafe on (ArduPilot FS_GCS_ENABLE, PX4 NAV_DLL_ACT; --set-failsafe sets it
instead of refusing), its return altitude set to its own layer. One at a time, each is switched to its
guided mode, armed and taken off to ``[uav] alt_m`` above its home; then the planner replans every
``--replan-every-s`` from the vehicles' measured positions and sends each one its target while it
flies (``--mode guided``: MAV_CMD_DO_REPOSITION; ``--mode mission``: a new mission flown in AUTO),
through the separation guard, which holds a vehicle whose predicted track comes closer than the
minimum to another's (``[guard]``).
At the end (``--duration-s`` of crowd time, Ctrl-C or SIGTERM) every vehicle is sent RTL
(``--end land``: LAND). Vehicle states, plans and QoS go out over Zenoh (tcp/127.0.0.1:7447).
Outputs in ``--out``: qos.png, timeseries.csv, track.csv, summary.json (and bridge.toml with
--simulated); ``--record flight.mcap`` also records the flight for Foxglove, and ``--live 8765`` streams
it to Foxglove while it flies.

--simulated ardupilot (or px4) starts a simulated fleet of that autopilot in this process (the vehicles of
``uav-swarm vehicles``, link-loss failsafe set to return home): --n-uavs of them (default 5) on loopback
ports of their own, or the vehicles of --bridge-config when one is given.

Examples (each flies --duration-s of crowd time, 300 s by default, plus the take-offs and the return;
all but the first need vehicles running: SITL, real autopilots, or uav-swarm vehicles in another terminal):
  uav-swarm fly --simulated ardupilot --duration-s 60 --speedup 2 --out out/fly   # about 70 s
  uav-swarm fly --bridge-config configs/bridge/ardupilot_sitl_10.toml --duration-s 60 --out out/fly-sitl
  uav-swarm fly --bridge-config configs/bridge/ardupilot_sitl_10.toml --wait-ready-s 120   # just booted
  uav-swarm fly --bridge-config fleet.toml --duration-s 600 --mode mission --end land
  uav-swarm fly --bridge-config fleet.toml --ros2   # on ROS 2, with operator targets (docs/ros2.md)

Telemetry left at its default endpoint moves to a free port of 127.0.0.1 when another run holds
tcp/127.0.0.1:7447, and says where. A vehicle not heard after 3 s is named, with why when its connection
was refused.

Exit codes: 0 flown and ended, 1 no vehicle could be launched (a vehicle never heard is "not found";
nothing written when none flew; the message says what to start), 2 bad flags, configuration, checkpoint,
output path (an --out holding another run's files: give --overwrite) or telemetry endpoint given in
--config (before anything is sent to a vehicle), or a pre-flight refusal (before any vehicle is armed;
nothing written); 130 Ctrl-C (143 SIGTERM): the vehicles are sent their end action and what flew is
written, or, before any vehicle flew, nothing.
"""

from __future__ import annotations

import argparse
import logging
import signal
import sys
import tempfile
import threading
from contextlib import ExitStack
from pathlib import Path
from typing import Any

from uav_swarm.cli.conventions import config_flag, number, output_flag, run_folder_flag
from uav_swarm.cli.simulate import CHECKPOINT_HELP, telemetry_endpoint

__all__ = ["register", "run"]

logger = logging.getLogger(__name__)


NEXT_STEPS = ("next: open track.png and qos.png in the output folder (the flight from above; QoS against the "
              "static reference: docs/glossary.md)\n"
              "next: uav-swarm vehicles starts a fleet that stays up (one terminal), uav-swarm fly "
              "--bridge-config out/vehicles/bridge.toml --duration-s 60 flies it (another): docs/fly.md")
"""What to try after a flight: two lines printed at the end of a finished one."""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``fly`` subcommand."""
    parser = subparsers.add_parser(
        "fly", help="closed loop: the planner flies real or SITL autopilots over the simulated crowd",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add = parser.add_argument
    cfg = "uav_swarm.runs.fly_config:FlyConfig."
    flight = "bridge.flight.guided:FlightConfig."
    config_flag(parser, "--bridge-config", cfg + "bridge_config",
                help="bridge TOML: home, geofence, protocol and the vehicles (required here or in --config, "
                     "unless --simulated)")
    add("--simulated", choices=("ardupilot", "px4"),
        help="fly a simulated fleet of this autopilot, started here (default: none, real vehicles)")
    run_folder_flag(parser, "--out", default="out/fly", help="output folder")
    add("--config", type=Path, help="TOML of FlyConfig (keys and tables [task], [uav], [planning], "
                                    "[telemetry], [flight]); flags override it (default: none)")
    config_flag(parser, "--planner", cfg + "planner", choices=("learned", "expert"))
    add("--checkpoint", help=CHECKPOINT_HELP)
    config_flag(parser, "--mode", cfg + "mode", choices=("guided", "mission"),
                help="how targets reach the vehicles")
    config_flag(parser, "--end", flight + "end_action", choices=("rtl", "land"))
    config_flag(parser, "--wait-ready-s", flight + "ready_timeout_s",
                help="wait at most this long for each vehicle's heartbeat, then for its position fix and "
                     "home ([flight] ready_timeout_s)")
    config_flag(parser, "--duration-s", cfg + "duration_s")
    config_flag(parser, "--speedup", cfg + "speedup")
    config_flag(parser, "--replan-every-s", cfg + "replan_every_s")
    config_flag(parser, "--n-uavs", cfg + "n_uavs")
    config_flag(parser, "--seed", cfg + "seed")
    add("--no-telemetry", action="store_true", help="do not publish over Zenoh")
    add("--set-failsafe", action="store_true",
        help="set a vehicle's missing link-loss failsafe to return to launch (and ArduPilot's SYSID_MYGCS to "
             "this bridge) instead of refusing the flight (default: off, refuse)")
    add("--ros2", action="store_true",
        help="publish the flight on ROS 2 (/uav_swarm/<swarm>/...) and take operator targets; needs the ros2 "
             "extra; DDS stays on this machine unless [ros2] localhost_only = false (default: off)")
    output_flag(parser, "--record", "file", metavar="FLIGHT.mcap",
        help="record the flight (scene, vehicle states, plans, QoS) as MCAP for Foxglove (default: none)")
    add("--live", metavar="[HOST:]PORT",
        help="stream the flight to Foxglove (Open connection, Foxglove WebSocket) from a server on this "
             "address; HOST defaults to 127.0.0.1 (this machine only); works with --record (default: none)")
    add("--live-wait-s", type=number(float, ge=0.0), metavar="SECONDS",
        help="with --live: wait at most this long for a Foxglove client before the first step (default: 0)")
    parser.set_defaults(func=run)


def _overrides(args: argparse.Namespace) -> dict[str, Any]:
    values = {"bridge_config": args.bridge_config, "planner": args.planner, "checkpoint": args.checkpoint,
              "mode": args.mode, "duration_s": args.duration_s, "speedup": args.speedup,
              "replan_every_s": args.replan_every_s, "n_uavs": args.n_uavs, "seed": args.seed}
    overrides: dict[str, Any] = {key: value for key, value in values.items() if value is not None}
    pairs = (("end_action", args.end), ("ready_timeout_s", args.wait_ready_s))
    flight = {key: value for key, value in pairs if value is not None}
    if flight:
        overrides["flight"] = flight
    if args.no_telemetry:
        overrides["publish_telemetry"] = False
    if args.set_failsafe:
        overrides["set_failsafe"] = True
    if args.ros2:
        overrides["ros2"] = {"enabled": True}
    return overrides


NO_VEHICLES = ("no vehicles to fly{why}: give --simulated ardupilot|px4 to fly a fleet started here, or "
               "--bridge-config FILE for vehicles already running (SITL, real autopilots, or uav-swarm "
               "vehicles --autopilot ardupilot --out out/vehicles in another terminal, which writes "
               "out/vehicles/bridge.toml)")
"""The refusal of a flight that names no vehicles, ``why`` filled in."""


def _no_vehicles(args: argparse.Namespace) -> str | None:
    """The refusal when neither the flags nor --config name vehicles (read before any heavy import)."""
    if args.simulated or args.bridge_config:
        return None
    if args.config is None:
        return NO_VEHICLES.format(why="")
    from typed_config import ConfigError, read_toml

    try:
        if read_toml(args.config).get("bridge_config"):
            return None
    except ConfigError as exc:
        return str(exc)
    return NO_VEHICLES.format(why=f" ({args.config} sets no bridge_config)")


def run(args: argparse.Namespace) -> int:
    """Validate (and start the simulated fleet), then fly."""
    refusal = _no_vehicles(args)
    if refusal is not None:  # a usage error: before the first line, in one line
        print(f"uav-swarm fly: {refusal}", file=sys.stderr)
        return 2
    fleet = f"a simulated {args.simulated} fleet started here" if args.simulated else (
        f"the vehicles of {args.bridge_config or 'the bridge config of --config'}")
    wait = f"{args.wait_ready_s:g} s" if args.wait_ready_s is not None else "60 s by default"
    print(f"uav-swarm fly: loading the planner, then flying {fleet} (waiting up to --wait-ready-s, {wait}, "
          f"for each); outputs into {args.out}; Ctrl-C ends the flight safely", flush=True)
    from typed_config import ConfigError
    from uav_swarm.runs.fly_config import load_fly_config
    from uav_swarm.runs.outputs.live_view import live_view_option

    with ExitStack() as stack:
        try:
            live = live_view_option(args.live, args.live_wait_s)
            overrides = _overrides(args)
            if args.simulated and args.bridge_config is None:
                overrides["bridge_config"] = _fleet_config(stack, args.n_uavs or 5)
            config = telemetry_endpoint(load_fly_config(args.config, overrides), args.config)
            if args.simulated:
                kept = f"{args.out / 'bridge.toml'}, with the outputs"
                shown = config.bridge_config if args.bridge_config else kept
                _start_fleet(stack, args.simulated, config.bridge_config, config.n_uavs, shown)
        except ConfigError as exc:
            print(f"uav-swarm fly: {exc}", file=sys.stderr)
            return 2
        return _fly(args, config, live)


def _fleet_config(stack: ExitStack, n: int) -> str:
    """A bridge config for ``n`` simulated vehicles, in a folder removed after the flight."""
    from bridge.simulated.fleet import fleet_bridge_config

    path = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="uav-swarm-fleet-"))) / "bridge.toml"
    path.write_text(fleet_bridge_config(n), encoding="utf-8")
    return str(path)


def _start_fleet(stack: ExitStack, autopilot: str, bridge_config: str, n_uavs: int, shown: str) -> None:
    """Simulated vehicles serving the bridge config's first ``n_uavs`` (0: all) endpoints.

    ``shown``: where the log line says their bridge config is.
    """
    from bridge.config import BridgeConfig
    from bridge.simulated.fleet import SimulatedFleet
    from typed_config import ConfigError, load_toml

    try:
        fleet = SimulatedFleet(autopilot, load_toml(BridgeConfig, bridge_config), n=n_uavs or None)
    except ValueError as exc:
        raise ConfigError(f"--simulated {autopilot}: {exc}") from None
    stack.enter_context(fleet)
    logger.info("%d simulated %s vehicles on 127.0.0.1 (their bridge config: %s)", len(fleet.vehicles),
                autopilot, shown)


def _fly(args: argparse.Namespace, config: Any, live: Any) -> int:
    """Fly until the end or a stop signal, print the outcome per vehicle."""
    from bridge.errors import BridgeError
    from bridge.telemetry.config import TelemetryConnectionError
    from learning.checkpoint import CheckpointError
    from typed_config import ConfigError
    from uav_swarm.runs.flight.status import end_report
    from uav_swarm.runs.fly import fly

    stop = threading.Event()
    received: list[int] = []  # the stop signals, in order: Ctrl-C (SIGINT) ends in exit code 130

    def on_signal(number: int, _frame: Any) -> None:
        received.append(number)
        stop.set()

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        made = bool(args.simulated) and args.bridge_config is None  # a fleet config of this flight only
        result = fly(config, args.out, stop_event=stop, record=args.record, live=live,
                     keep_bridge_config=made)
    except (ConfigError, CheckpointError) as exc:
        print(f"uav-swarm fly: {exc}", file=sys.stderr)
        return 2
    except TelemetryConnectionError as exc:
        print(f"uav-swarm fly: {exc}; use --no-telemetry, or another [telemetry] listen endpoint",
              file=sys.stderr)
        return 2
    except BridgeError as exc:
        print(f"uav-swarm fly: {exc}", file=sys.stderr)
        return 2 if isinstance(exc, ValueError) else 1
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    summary = result.summary
    for line in end_report(summary):
        print(line)
    if "mean_qos_s1" in summary:
        print("QoS S1/S2, the static reference, holds and the planner's name: docs/glossary.md")
    print(f"wrote {', '.join(summary['files'])} in {args.out}")
    if "recording" in summary:
        print(f"recorded the flight in {summary['recording']}")
    if received:
        name = "Ctrl-C" if received[0] == signal.SIGINT else signal.Signals(received[0]).name
        flown = f" after {summary['duration_s']:.0f} s of crowd time" if "duration_s" in summary else ""
        print(f"uav-swarm fly: interrupted ({name}){flown}: the vehicles were sent their end action and the "
              "files above cover the flight until then", file=sys.stderr)
        return 128 + received[0]
    print(NEXT_STEPS)
    return 0
