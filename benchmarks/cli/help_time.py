"""How long ``uav-swarm --help`` and each command's ``--help`` take, the whole process timed.

Each help is run ``--runs`` times as a fresh process (``python -m uav_swarm COMMAND --help``), after one
warm-up run that writes the bytecode cache (into a temporary ``PYTHONPYCACHEPREFIX``, as an installed
package has its ``.pyc`` files); the median wall time is printed with the machine, its load average before
the runs, and the start of a bare interpreter (``python -c pass``), the floor of any command; beside it the
median CPU time (user + system) of the process, which a loaded machine does not inflate. Goal: each help
within 0.5 s of wall time on the reference machine at load < 1.

Usage: python benchmarks/cli/help_time.py [--runs 5] [--commands [simulate fly ...]]
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
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


def main() -> None:
    """Time each help and print a markdown table."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=5, help="timed runs of each help (default: 5)")
    parser.add_argument("--commands", nargs="*",
                        help="commands to time; given alone, the top level only (default: the top level and "
                             "all)")
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
