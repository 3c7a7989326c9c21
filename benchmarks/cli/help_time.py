"""How long ``uav-swarm --help`` and each command's ``--help`` take, the whole process timed.

Each help is run ``--runs`` times as a fresh process (``python -m uav_swarm COMMAND --help``), after one
warm-up run that writes the bytecode cache (into a temporary ``PYTHONPYCACHEPREFIX``, as an installed
package has its ``.pyc`` files); the median wall time is printed with the machine, its load average before
the runs, and the start of a bare interpreter (``python -c pass``), the floor of any command; beside it the
median CPU time (user + system) of the process, which a loaded machine does not inflate. Goal: each help
within 0.5 s of wall time on the reference machine at load < 1.

With ``--first-lines`` it times instead how long ``simulate``, ``fly`` and ``telemetry watch`` take to print
their first line (what they load or wait for, before the heavy imports): each run as a fresh process, stopped
as soon as that line arrives. They touch nothing outside a temporary folder: ``simulate`` and ``fly`` run
without telemetry into it, ``fly`` against a bridge config of loopback ports nobody serves, ``telemetry
watch`` connects to a loopback port nobody serves. Goal: within 5 s of Enter at load < 1.

Usage: python benchmarks/cli/help_time.py [--runs 5] [--commands [simulate fly ...]] [--first-lines]
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import socket
import statistics
import subprocess
import sys
import tempfile
import time

from uav_swarm.cli import build_parser
from uav_swarm.cli.conventions import iter_parsers


def wall_s(argv: list[str], env: dict[str, str]) -> float:
    """One run of ``argv`` as a process: its wall time (s); its output is discarded."""
    return timed(argv, env)[0]


def timed(argv: list[str], env: dict[str, str]) -> tuple[float, float]:
    """One run of ``argv`` as a process: its wall time and its CPU time (user + system), in seconds.

    The CPU time is what the process itself spent; on a loaded machine the wall time adds the waits for a
    core, so both are printed.
    """
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run(argv, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def first_line_s(argv: list[str], env: dict[str, str]) -> tuple[float, str]:
    """One run of ``argv`` as a process, stopped at its first line (either stream): the wait and the line."""
    start = time.perf_counter()
    process = subprocess.Popen(argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        assert process.stdout is not None
        line = process.stdout.readline()
        return time.perf_counter() - start, line.strip()
    finally:
        process.kill()
        process.wait(timeout=60)


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def first_lines(runs: int, env: dict[str, str]) -> None:
    """Print the median wait for the first line of ``simulate``, ``fly`` and ``telemetry watch``."""
    print("| command | first line s, median | max | the line |\n|---|---|---|---|")
    with tempfile.TemporaryDirectory() as folder:
        bridge = os.path.join(folder, "bridge.toml")
        with open(bridge, "w", encoding="utf-8") as stream:
            stream.write(f'[[vehicles]]\nsystem_id = 1\nurl = "tcp:127.0.0.1:{_free_port()}"\n')
        commands = {
            "simulate": ["simulate", "--duration-s", "5", "--no-telemetry", "--out"],
            "fly": ["fly", "--bridge-config", bridge, "--duration-s", "5", "--no-telemetry", "--out"],
            "telemetry watch": ["telemetry", "watch", "--duration-s", "2", "--connect",
                                f"tcp/127.0.0.1:{_free_port()}"],
        }
        for name, words in commands.items():
            waits, line = [], ""
            for run in range(runs + 1):  # the first run writes the bytecode cache
                out = [os.path.join(folder, f"{name.split()[0]}-{run}")] if words[-1] == "--out" else []
                wait, line = first_line_s([sys.executable, "-m", "uav_swarm", *words, *out], env)
                waits.append(wait)
            print(f"| uav-swarm {name} | {statistics.median(waits[1:]):.2f} | {max(waits[1:]):.2f} | "
                  f"{line[:90]} |")


def main() -> None:
    """Time each help and print a markdown table."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=5, help="timed runs of each help (default: 5)")
    parser.add_argument("--commands", nargs="*",
                        help="commands to time; given alone, the top level only (default: the top level and "
                             "all)")
    parser.add_argument("--first-lines", action="store_true",
                        help="time the first line of simulate, fly and telemetry watch instead of the helps")
    args = parser.parse_args()
    if args.commands is None:
        commands = [path for path, _ in iter_parsers(build_parser())]
    else:
        commands = [(c,) for c in args.commands] or [()]
    with tempfile.TemporaryDirectory() as cache:
        env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        env["PYTHONPYCACHEPREFIX"] = cache
        load = os.getloadavg()
        print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, Python "
              f"{platform.python_version()}; load average before: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
        bare = [sys.executable, "-c", "pass"]
        wall_s(bare, env)
        bare_s = statistics.median(wall_s(bare, env) for _ in range(args.runs))
        print(f"bare interpreter (python -c pass): median {bare_s:.3f} s\n")
        if args.first_lines:
            first_lines(args.runs, env)
            print(f"\nload average after: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
            return
        print("| command | wall s, median | wall s, max | CPU s, median |\n|---|---|---|---|")
        for path in commands:
            argv = [sys.executable, "-m", "uav_swarm", *path, "--help"]
            wall_s(argv, env)  # warm-up: the bytecode cache
            runs = [timed(argv, env) for _ in range(args.runs)]
            walls, cpus = [w for w, _ in runs], [c for _, c in runs]
            name = " ".join(("uav-swarm", *path, "--help"))
            print(f"| {name} | {statistics.median(walls):.3f} | {max(walls):.3f} | "
                  f"{statistics.median(cpus):.3f} |")
        print(f"\nload average after: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
