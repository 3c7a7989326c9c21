"""``uav-swarm vehicles``: a simulated fleet of ArduCopter or PX4 autopilots on this machine, until Ctrl-C.

Each vehicle answers MAVLink as its autopilot does (modes, arming, take-off, reposition, missions, RTL and
LAND, its link-loss failsafe, its parameters at the autopilot's defaults) and flies as a point mass within
its autopilot's speed and acceleration limits (ArduCopter WPNAV_SPEED 10 m/s and WPNAV_ACCEL 2.5 m/s^2; PX4
MPC_XY_CRUISE 5 m/s, MPC_XY_VEL_MAX 12 m/s and MPC_ACC_HOR 3 m/s^2), each on its own home along a launch
line going East. Only 127.0.0.1 endpoints are served. Their link-loss failsafe is set to return home (as an
operator prepares a vehicle; --no-failsafe: the autopilot's default, off).

Without --bridge-config it writes a bridge config for --n vehicles on free UDP ports to OUT/bridge.toml;
with one it serves that config's vehicles (the first --n). Fly them from another terminal with
``uav-swarm fly --bridge-config`` and the same file.

Examples:
  uav-swarm vehicles --autopilot ardupilot --n 5 --out out/vehicles
  uav-swarm fly --bridge-config out/vehicles/bridge.toml --out out/fly          # in another terminal
  uav-swarm vehicles --autopilot px4 --bridge-config configs/bridge/px4_sitl_10.toml --n 3
  uav-swarm vehicles --autopilot ardupilot --wind-m-s 8 --gust-m-s 4 --gps-age-s 0.4 --gps-rate-hz 5
      --gps-noise-m 0.5 --command-latency-s 0.3 --command-loss 0.05 --param WPNAV_ACCEL=500

Exit codes: 0 stopped by Ctrl-C or SIGTERM, 2 bad flags or bridge config (nothing started or written).
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import tomllib
from pathlib import Path

from uav_swarm.cli.conventions import number, output_flag

__all__ = ["register", "run", "realism_flags", "parse_params"]

_NAMES = {"ardupilot": "ArduCopter", "px4": "PX4 quadrotor"}


def realism_flags(parser: argparse.ArgumentParser) -> None:
    """The fleet's imperfections (bridge.simulated.dynamics.Realism), all off by default."""
    add = parser.add_argument
    add("--wind-m-s", type=number(float, ge=0.0), default=0.0, help="steady wind (default: 0)")
    add("--gust-m-s", type=number(float, ge=0.0), default=0.0, help="largest gust on top of it (default: 0)")
    add("--gps-age-s", type=number(float, ge=0.0, le=10.0), default=0.0,
        help="reported positions are this old (default: 0)")
    add("--gps-rate-hz", type=number(float, gt=0.0, le=100.0), default=10.0,
        help="positions per second (default: 10)")
    add("--gps-noise-m", type=number(float, ge=0.0, le=100.0), default=0.0,
        help="standard deviation of the noise on each axis of a reported position (default: 0)")
    add("--command-latency-s", type=number(float, ge=0.0, le=10.0), default=0.0,
        help="commands are handled and answered this late (default: 0)")
    add("--command-loss", type=number(float, ge=0.0, lt=1.0), default=0.0,
        help="share of commands lost without an answer (default: 0)")


def parse_params(pairs: list[str], autopilot: str) -> dict[str, float]:
    """``NAME=VALUE`` texts to parameter values, refusing names the autopilot does not serve."""
    from bridge.simulated.ardupilot import ARDUPILOT_PARAMS
    from bridge.simulated.px4 import PX4_PARAMS
    from typed_config import ConfigError

    known = ARDUPILOT_PARAMS if autopilot == "ardupilot" else PX4_PARAMS
    values = {}
    for pair in pairs:
        name, _, text = pair.partition("=")
        try:
            value = float(text)
        except ValueError:
            raise ConfigError(f"--param {pair!r}: give NAME=VALUE with a number") from None
        if name not in known:
            raise ConfigError(f"--param {pair!r}: {name} is not among the {autopilot} parameters "
                              f"{sorted(known)}")
        values[name] = value
    return values


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``vehicles`` subcommand."""
    parser = subparsers.add_parser(
        "vehicles", help="a simulated fleet of ArduCopter or PX4 autopilots on this machine, for fly",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add = parser.add_argument
    add("--autopilot", choices=("ardupilot", "px4"), required=True, help="the autopilot they answer as")
    add("--n", type=number(int, ge=1, le=10), help="vehicles (default: 5, or all of --bridge-config's)")
    add("--bridge-config", type=Path, help="serve this bridge config's vehicles (default: none, write one)")
    output_flag(parser, "--out", "folder", default="out/vehicles",
        help="folder of the bridge config written without --bridge-config")
    add("--spacing-m", type=number(float, gt=0.0, le=1000.0), default=10.0,
        help="distance between neighbouring homes along the launch line (default: 10)")
    add("--seed", type=number(int, ge=0), default=0, help="seed of the vehicles' random draws (default: 0)")
    add("--param", action="append", default=[], metavar="NAME=VALUE",
        help="a parameter of every vehicle, instead of the autopilot's default (repeat it; default: none)")
    add("--no-failsafe", action="store_true",
        help="leave the link-loss failsafe at the autopilot's default, off (default: set to return home)")
    realism_flags(parser)
    parser.set_defaults(func=run)


def realism_from(args: argparse.Namespace):  # -> bridge.simulated.dynamics.Realism
    """The :class:`~bridge.simulated.dynamics.Realism` the flags of :func:`realism_flags` describe."""
    from bridge.simulated.dynamics import Realism

    return Realism(command_latency_s=args.command_latency_s, command_loss=args.command_loss,
                   position_age_s=args.gps_age_s, position_rate_hz=args.gps_rate_hz,
                   position_noise_m=args.gps_noise_m, wind_m_s=args.wind_m_s, gust_m_s=args.gust_m_s)


def run(args: argparse.Namespace) -> int:
    """Check the flags, start the fleet, serve until Ctrl-C or SIGTERM."""
    from bridge.config import BridgeConfig
    from bridge.simulated.fleet import SimulatedFleet, fleet_bridge_config
    from typed_config import ConfigError, load_toml
    from typed_config.files import write_bytes_atomic

    params = parse_params(args.param, args.autopilot)
    if args.bridge_config is not None:
        bridge = load_toml(BridgeConfig, args.bridge_config)
        if args.n is not None and args.n > len(bridge.vehicles):
            raise ConfigError(f"--n {args.n}: {args.bridge_config} has {len(bridge.vehicles)} vehicles")
        config_path, text = args.bridge_config, None
    else:
        text = fleet_bridge_config(args.n or 5)
        bridge, config_path = BridgeConfig.from_dict(tomllib.loads(text)), args.out / "bridge.toml"
    try:
        fleet = SimulatedFleet(args.autopilot, bridge, n=args.n, spacing_m=args.spacing_m,
                               realism=realism_from(args), params=params, failsafe=not args.no_failsafe,
                               seed=args.seed)
    except ValueError as exc:
        raise ConfigError(str(exc)) from None
    stop = threading.Event()
    previous = {sig: signal.signal(sig, lambda *_: stop.set()) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        with fleet:
            if text is not None:
                config_path.parent.mkdir(parents=True, exist_ok=True)
                write_bytes_atomic(config_path, text.encode())
            ids = [v.system_id for v in fleet.vehicles]
            print(f"{len(ids)} simulated {_NAMES[args.autopilot]}s (system ids {', '.join(map(str, ids))}) "
                  f"on 127.0.0.1, homes {args.spacing_m:g} m apart going East from [home] of {config_path}")
            print(f"fly them: uav-swarm fly --bridge-config {config_path}   (Ctrl-C here stops the vehicles)")
            sys.stdout.flush()
            stop.wait()
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    print("vehicles stopped")
    return 0
