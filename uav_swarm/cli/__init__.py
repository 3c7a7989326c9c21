"""The ``uav-swarm`` command.

Each subcommand lives in its own module of this package with a
``register(subparsers)`` function that adds its parser and sets ``func``.
Modules import their heavy dependencies inside the command function so that
``uav-swarm --help`` stays fast.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from collections.abc import Sequence

from typed_config import ConfigError
from uav_swarm import __version__

__all__ = ["main", "build_parser"]

COMMAND_MODULES: tuple[str, ...] = (
    "uav_swarm.cli.env_demo",
    "uav_swarm.cli.telemetry",
    "uav_swarm.cli.mission",
    "uav_swarm.cli.learn",
    "uav_swarm.cli.search",
    "uav_swarm.cli.stability",
    "uav_swarm.cli.check_calibration",
    "uav_swarm.cli.calibrate_mission",
    "uav_swarm.cli.simulate",
    "uav_swarm.cli.fly",
    "uav_swarm.cli.place",
    "uav_swarm.cli.rl",
)


def build_parser() -> argparse.ArgumentParser:
    """The top-level parser with every registered subcommand."""
    parser = argparse.ArgumentParser(
        prog="uav-swarm",
        description="Place and fly a swarm of up to 10 UAVs over a moving crowd.",
    )
    parser.add_argument("--version", action="version", version=f"uav-swarm {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log debug messages")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.INFO,
        format="%(levelname)s %(name)s: %(message)s",
    )
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except ConfigError as exc:
        print(f"uav-swarm: configuration error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("uav-swarm: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
