"""`uav-swarm place` on real outlines: refined guards against the exact reference, per building and task.

For each building (the six OpenStreetMap footprints of ``tests/data/buildings/``, the parts of a
MultiPolygon and a courtyard building counted one by one, and generated outlines: a comb-shaped hall
with three 20 m slots, a U-shaped block, a courtyard block and a wall with near-collinear jogs) and each
task (AGP, FP), the shipped network proposes guards on its raster and the repair makes them see every
witness of the real outline (``refined``, timed: network and repair, as ``place`` runs them); the exact
reference solves the same outline from scratch (``uav_swarm.missions.monitoring.outline_guards``).
Both are judged on the outline in metres at the default witness spacing (0.5 m), margin (0.5 m) and
standoff (1 m). Printed: guards (refined / reference), coverage, times and their ratio, then the
totals against the goals of issue 28 (guards <= 1.05x the reference, >= 10x faster, 100 % seen,
<= 1 s per building of <= 64 vertices). The first line gives the machine and its load average.

Usage: python benchmarks/place.py [--tasks agp fp]
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np

from uav_swarm.cli.place import load_network, place_building
from uav_swarm.missions.monitoring.footprint import Footprint, read_site
from uav_swarm.missions.monitoring.outline_guards import SightConfig, judge
from uav_swarm.missions.registry import build_task

BUILDINGS = Path(__file__).resolve().parents[1] / "tests" / "data" / "buildings"


def generated() -> list[Footprint]:
    """The generated outlines (metres)."""
    comb = [(0, 0), (150, 0), (150, 60), (130, 60), (130, 20), (110, 20), (110, 60), (85, 60), (85, 20),
            (65, 20), (65, 60), (50, 60), (50, 20), (30, 20), (30, 60), (0, 60)]
    u_block = [(0, 0), (120, 0), (120, 80), (90, 80), (90, 25), (30, 25), (30, 80), (0, 80)]
    square = [(0, 0), (60, 0), (60, 50), (0, 50)]
    courtyard = [(20, 15), (20, 35), (40, 35), (40, 15)]
    jogs = [(0, 0), (40, 0), (40, 0.6), (80, 0.6), (80, 30), (41, 30), (41, 29.4), (0, 29.4)]
    return [Footprint(np.array(comb, float), name="comb hall 150 x 60 m, three 20 m slots"),
            Footprint(np.array(u_block, float), name="U-shaped block 120 x 80 m"),
            Footprint(np.array(square, float), name="courtyard block 60 x 50 m",
                      holes_m=(np.array(courtyard, float),)),
            Footprint(np.array(jogs, float), name="hall with 0.6 m jogs (near-collinear walls)")]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tasks", nargs="+", default=["agp", "fp"], choices=["agp", "fp"])
    args = parser.parse_args()
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    print(f"machine: {platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}; "
          f"load average {load}")
    buildings = [b for path in sorted(BUILDINGS.glob("*.geojson")) for b in read_site(path)] + generated()
    sight = SightConfig()
    print("| task | building | vertices | guards refined / reference | seen refined / reference % "
          "| refined ms | reference ms | speed-up |")
    print("|---|---|---|---|---|---|---|---|")
    for task_name in args.tasks:
        task = build_task(task_name)
        network = load_network(task, None)
        totals = np.zeros(4)
        slowest = 0.0
        for footprint in buildings:
            refined = place_building(task, footprint, "refined", network, sight, 10.0)
            reference = place_building(task, footprint, "expert", None, sight, 10.0)
            check = judge(footprint.outline(), task.region, refined.placement.guards_m, sight)  # re-judged
            n_ref, n_exp = len(refined.placement.guards_m), len(reference.placement.guards_m)
            vertices = footprint.outline().n_vertices
            print(f"| {task_name} | {footprint.name} | {vertices} | {n_ref} / {n_exp} | "
                  f"{100 * check.seen_fraction:.1f} / {100 * reference.placement.seen_fraction:.1f} | "
                  f"{1e3 * refined.seconds:.0f} | {1e3 * reference.seconds:.0f} | "
                  f"{reference.seconds / refined.seconds:.1f}x |", flush=True)
            totals += (n_ref, n_exp, refined.seconds, reference.seconds)
            slowest = max(slowest, refined.seconds)
        print(f"| {task_name} | **all {len(buildings)}** | | {totals[0]:.0f} / {totals[1]:.0f} "
              f"(**{totals[0] / totals[1]:.3f}x**) | | {1e3 * totals[2]:.0f} (slowest {1e3 * slowest:.0f}) | "
              f"{1e3 * totals[3]:.0f} | **{totals[3] / totals[2]:.1f}x** |", flush=True)
    print(f"load average at the end: {', '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    start = time.perf_counter()
    main()
    print(f"wall time {time.perf_counter() - start:.0f} s")
