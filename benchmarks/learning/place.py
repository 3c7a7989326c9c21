"""`uav-swarm place` on real outlines: refined guards against the exact reference, per building and task.

For each building (the six OpenStreetMap footprints of ``tests/data/buildings/``, the parts of a
MultiPolygon and a courtyard building counted one by one, and generated outlines: a comb-shaped hall
with three 20 m slots, a U-shaped block, a courtyard block and a wall with near-collinear jogs) and each
task (AGP, FP), the shipped network proposes guards on its raster and the repair makes them see every
witness of the real outline (``refined``, timed: network and repair, as ``place`` runs them). Two exact
references solve the same outline from scratch on the 1 m lattice:

* ``lazy``: :func:`uav_swarm.missions.monitoring.outline_guards.reference_guards` (what ``--method expert``
  runs): the set cover on witnesses added lazily, then positions aimed at what the lattice misses;
* ``dense``: the plain set cover the issue describes: the visibility of every lattice point from every
  witness, then one HiGHS solve (fewest guards, no reductions), stopped after ``--dense-limit-s``
  seconds of solving (then only a lower bound of its time is known, printed with ``>``).

All are judged on the outline in metres at the default witness spacing (0.5 m), margin (0.5 m) and
standoff (1 m). Printed: guards (refined / lazy / dense), coverage, wall and CPU times and the CPU-time
ratios (the machine is shared: CPU time is what the code costs, wall time what a user waited), then the
totals against the goals of issue 28 (guards <= 1.05x the reference, >= 10x faster, 100 % seen,
<= 1 s per building of <= 64 vertices). The first lines give the machine, its load average and the time
to load (or, in a fresh environment, compile) the visibility kernel.

Usage: python benchmarks/learning/place.py [--tasks agp fp] [--dense-limit-s 60]
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np
from scipy.optimize import Bounds, LinearConstraint, milp
from scipy.sparse import csr_array

from uav_swarm.cli.place import load_network, place_building
from uav_swarm.missions.monitoring.footprint import Footprint, read_site
from uav_swarm.missions.monitoring.outline import Outline, Region, candidates, visibility, witnesses
from uav_swarm.missions.monitoring.outline_guards import SightConfig, judge
from uav_swarm.missions.registry import build_task

BUILDINGS = Path(__file__).resolve().parents[2] / "tests" / "data" / "buildings"


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


def dense_reference(outline: Outline, region: Region, sight: SightConfig, limit_s: float
                    ) -> tuple[int | None, int, float, float]:
    """The plain set cover: every lattice point against every witness, one HiGHS solve.

    Returns:
        Guards (None when HiGHS stopped at ``limit_s``), witnesses no lattice point sees (left out of the
        cover), wall and CPU seconds.
    """
    start, cpu = time.perf_counter(), time.process_time()
    targets = witnesses(outline, region, sight.witness_spacing_m)
    lattice = candidates(outline, region, sight.reference_spacing_m, sight.standoff_m, sight.reach_m)
    sees = visibility(outline, lattice, targets, sight.min_clearance_m, region)
    seen = np.any(sees, axis=0)
    result = milp(np.ones(len(lattice)), integrality=np.ones(len(lattice)), bounds=Bounds(0.0, 1.0),
                  constraints=LinearConstraint(csr_array(sees[:, seen].T.astype(np.float64)), lb=1.0),
                  options={"mip_rel_gap": 0.0, "time_limit": limit_s})
    guards = int(np.count_nonzero(result.x > 0.5)) if result.status == 0 else None
    return guards, int(np.count_nonzero(~seen)), time.perf_counter() - start, time.process_time() - cpu


def timed_place(task, footprint, method, network, sight) -> tuple:  # noqa: ANN001
    """``place_building`` and its CPU seconds (all threads of this process)."""
    cpu = time.process_time()
    placed = place_building(task, footprint, method, network, sight, 10.0)
    return placed, time.process_time() - cpu


def kernel_load_s() -> float:
    """Seconds of the first visibility call: loading the compiled kernel (compiling it in a fresh one)."""
    start = time.perf_counter()
    square = Outline.from_rings(np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]]))
    visibility(square, np.array([[2.0, 2.0]]), witnesses(square, "interior", 1.0), 0.5)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tasks", nargs="+", default=["agp", "fp"], choices=["agp", "fp"])
    parser.add_argument("--dense-limit-s", type=float, default=60.0,
                        help="HiGHS time limit of the dense reference, s (default: %(default)s)")
    args = parser.parse_args()
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    print(f"machine: {platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}; "
          f"load average {load}")
    print(f"visibility kernel: first call {1e3 * kernel_load_s():.0f} ms (load from the cache, or compile)")
    buildings = [b for path in sorted(BUILDINGS.glob("*.geojson")) for b in read_site(path)] + generated()
    sight = SightConfig()
    print("| task | building | vertices | guards refined / lazy / dense | seen refined / lazy % "
          "| refined ms wall (CPU) | lazy ms wall (CPU) | dense ms wall (CPU) | lazy / refined CPU "
          "| dense / refined CPU |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for task_name in args.tasks:
        task = build_task(task_name)
        network = load_network(task, None)
        totals = np.zeros(6)  # guards refined, lazy; CPU refined, lazy, dense (finished ones); refined wall
        slowest = slowest_cpu = 0.0
        dense_open = 0
        for footprint in buildings:
            refined, refined_cpu = timed_place(task, footprint, "refined", network, sight)
            lazy, lazy_cpu = timed_place(task, footprint, "expert", None, sight)
            outline = footprint.outline()
            n_dense, blind, dense_s, dense_cpu = dense_reference(outline, task.region, sight,
                                                                 args.dense_limit_s)
            check = judge(outline, task.region, refined.placement.guards_m, sight)  # re-judged
            n_ref, n_lazy = len(refined.placement.guards_m), len(lazy.placement.guards_m)
            dense = "stopped" if n_dense is None else str(n_dense) + (f" (+{blind} blind)" if blind else "")
            more = ">" if n_dense is None else ""
            print(f"| {task_name} | {footprint.name} | {outline.n_vertices} | {n_ref} / {n_lazy} / {dense} | "
                  f"{100 * check.seen_fraction:.1f} / {100 * lazy.placement.seen_fraction:.1f} | "
                  f"{1e3 * refined.seconds:.0f} ({1e3 * refined_cpu:.0f}) | "
                  f"{1e3 * lazy.seconds:.0f} ({1e3 * lazy_cpu:.0f}) | "
                  f"{more}{1e3 * dense_s:.0f} ({more}{1e3 * dense_cpu:.0f}) | "
                  f"{lazy_cpu / refined_cpu:.1f}x | {more}{dense_cpu / refined_cpu:.1f}x |", flush=True)
            totals += (n_ref, n_lazy, refined_cpu, lazy_cpu, dense_cpu, refined.seconds)
            dense_open += n_dense is None
            slowest, slowest_cpu = max(slowest, refined.seconds), max(slowest_cpu, refined_cpu)
        more = ">" if dense_open else ""
        print(f"| {task_name} | **all {len(buildings)}** | | {totals[0]:.0f} / {totals[1]:.0f} "
              f"(**{totals[0] / totals[1]:.3f}x**) | | {1e3 * totals[5]:.0f} (CPU {1e3 * totals[2]:.0f}; "
              f"slowest {1e3 * slowest:.0f} wall, {1e3 * slowest_cpu:.0f} CPU) | CPU {1e3 * totals[3]:.0f} | "
              f"CPU {more}{1e3 * totals[4]:.0f} ({dense_open} stopped) | **{totals[3] / totals[2]:.1f}x** | "
              f"**{more}{totals[4] / totals[2]:.1f}x** |", flush=True)
    print(f"load average at the end: {', '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    start = time.perf_counter()
    main()
    print(f"wall time {time.perf_counter() - start:.0f} s")
