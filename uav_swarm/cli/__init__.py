"""The ``uav-swarm`` command.

Each subcommand lives in its own module of this package with a
``register(subparsers)`` function that adds its parser and sets ``func``.
Modules import their heavy dependencies inside the command function so that
``uav-swarm --help`` stays fast.

May import: ``typed_config``, ``learning``, ``bridge``, ``uav_swarm``.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from collections.abc import Sequence

from typed_config import ConfigError
from uav_swarm import __version__
from uav_swarm.cli.conventions import CliParser, add_verbosity, iter_parsers, run_folder_problem

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
    "uav_swarm.cli.vehicles",
    "uav_swarm.cli.place",
    "uav_swarm.cli.rl",
)


def build_parser() -> argparse.ArgumentParser:
    """The top-level parser with every registered subcommand (conventions: docs/cli.md)."""
    parser = CliParser(
        prog="uav-swarm",
        description="Place and fly a swarm of up to 10 UAVs over a moving crowd.\n\n"
                    "uav-swarm COMMAND --help describes a command; docs/cli.md lists them all.",
    )
    parser.add_argument("--version", action="version", version=f"uav-swarm {__version__}")
    add_verbosity(parser, top_level=True)
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(subparsers)
    for path, sub in iter_parsers(parser):
        if path and not any(isinstance(a, argparse._SubParsersAction) for a in sub._actions):
            add_verbosity(sub)  # -v and -q after the subcommand too
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the process exit code (2: a usage or configuration error)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, or a usage error already printed
        return exc.code if isinstance(exc.code, int) else 2
    level = logging.DEBUG if args.verbose else logging.WARNING if args.quiet else logging.INFO
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    command = " ".join(filter(None, (args.command, getattr(args, "action", None))))
    problem = run_folder_problem(args)
    if problem is not None:
        print(f"uav-swarm {command}: {problem}", file=sys.stderr)
        return 2
    try:
        return int(args.func(args) or 0)
    except ConfigError as exc:
        print(f"uav-swarm {command}: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("uav-swarm: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
