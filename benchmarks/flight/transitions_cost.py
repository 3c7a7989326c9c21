"""Cost of a transition per replan: 10 UAVs in a 60 m square, replans in flight, reassignments included.

Seeded replans of 10 UAVs (minimum 5 m, the default limits, env step 0.1 s) every second, the UAVs flying
the previous transition in between (the env's waypoint controller and kinematics, no guard), so every
replan starts in flight. Two kinds, interleaved:

- ``follow``: every target moves 0-4 m, staying 6 m from the others (planning in motion following its users);
- ``reassign``: three targets are drawn anywhere (apart from the others), every UAV is assigned again by
  the least sum of squared distances (:func:`uav_swarm.planning.transitions.squared_assignment`).

Each replan times :func:`uav_swarm.planning.transitions.plan_transition` and, on the same input in the same
round, the reference: the transition planner of ``--reference`` (a git commit; default the one before the
flown-kinematics planner), loaded from git into a temporary folder. Each is timed ``--repeats`` times in a
row and the least time kept (what the code costs, not what other processes on a busy machine take from
it; the single first timings are printed too). Goal: <= 0.5 ms per replan.

Usage: python benchmarks/flight/transitions_cost.py [--replans 300] [--seed 0] [--reference 5c0ace9]
       [--repeats 3]
"""

from __future__ import annotations

import os

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):  # one thread, before numpy
    os.environ[_name] = "1"

import argparse  # noqa: E402
import importlib.util  # noqa: E402
import platform  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from types import ModuleType  # noqa: E402

import numpy as np  # noqa: E402

from uav_swarm.planning.transitions import plan_transition, squared_assignment, warm_up  # noqa: E402
from uav_swarm.world.uav import UAVConfig, fly_step, waypoint_velocity  # noqa: E402

CONFIG = UAVConfig(min_separation_m=5.0)
AREA_M = np.array([60.0, 60.0])
DT_S = 0.1
STEPS_PER_REPLAN = 10
REPO = Path(__file__).resolve().parents[2]


def reference_planner(commit: str, folder: Path) -> ModuleType:
    """The ``transitions`` module of ``commit`` (with its ``trajectory``), importable apart from this tree."""
    package = folder / "reference_planning"
    package.mkdir()
    (package / "__init__.py").write_text("")
    for name in ("trajectory", "transitions"):
        source = subprocess.run(["git", "-C", str(REPO), "show", f"{commit}:uav_swarm/planning/{name}.py"],
                                check=True, capture_output=True, text=True).stdout
        source = source.replace("uav_swarm.planning.trajectory", "reference_planning.trajectory")
        (package / f"{name}.py").write_text(source.replace("cache=True", "cache=False"))
    sys.path.insert(0, str(folder))
    spec = importlib.util.find_spec("reference_planning.transitions")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["reference_planning.transitions"] = module
    spec.loader.exec_module(module)
    return module


def spread(rng: np.random.Generator, n: int, others: np.ndarray, gap_m: float = 6.0) -> np.ndarray:
    """``n`` points in the area at least ``gap_m`` from each other and from ``others``."""
    points = list(others)
    start = len(points)
    while len(points) < start + n:
        point = rng.uniform(0.0, AREA_M)
        if all(np.hypot(*(point - q)) >= gap_m for q in points):
            points.append(point)
    return np.array(points[start:]).reshape(-1, 2)


def next_targets(kind: str, rng: np.random.Generator, targets: np.ndarray, p: np.ndarray) -> np.ndarray:
    """The next plan's targets, assigned to the UAVs (module docstring)."""
    moved = targets.copy()
    for k in range(len(moved)):  # each target moves unless that brings it within 6 m of another
        step = np.clip(moved[k] + rng.uniform(-4.0, 4.0, 2), 0.0, AREA_M)
        if np.hypot(*(np.delete(moved, k, axis=0) - step).T).min() >= 6.0:
            moved[k] = step
    keep = np.ones(len(moved), bool)
    if kind == "reassign":
        keep[rng.choice(len(moved), 3, replace=False)] = False
        moved[~keep] = spread(rng, 3, moved[keep])
        rows, cols = squared_assignment(p, moved)
        moved = moved[cols[np.argsort(rows)]]
    return moved


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--replans", type=int, default=300, help="replans per kind (default: %(default)s)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--reference", default="5c0ace9", help="git commit of the reference planner")
    parser.add_argument("--repeats", type=int, default=3, help="timings per replan, the least kept")
    args = parser.parse_args()
    print(f"machine: {platform.machine()}, {os.cpu_count()} CPUs, one thread; numpy {np.__version__}; "
          f"load average at start {os.getloadavg()}")
    with tempfile.TemporaryDirectory() as folder:
        reference = reference_planner(args.reference, Path(folder))
        warm_up()
        reference.plan_transition(np.zeros((2, 2)), np.zeros((2, 2)), np.ones((2, 2)), CONFIG)
        print(f"10 UAVs in a {AREA_M[0]:g} x {AREA_M[1]:g} m area, minimum {CONFIG.min_separation_m:g} m, "
              f"{args.replans} replans per kind every {STEPS_PER_REPLAN * DT_S:g} s, in flight")
        print(f"least of {args.repeats} timings per replan")
        print(f"{'kind':<9} {'now p50':>8} {'p95':>7} {'max':>7} {'reference p50':>13} {'p95':>7} "
              f"{'ratio':>6} {'holds':>6} {'unresolved':>10}")
        rng = np.random.default_rng(args.seed)
        targets = spread(rng, 10, np.zeros((0, 2)))
        p, v = targets.copy(), np.zeros_like(targets)
        times: dict[str, tuple[list[float], list[float], list[int]]] = {}
        first: list[float] = []
        for replan in range(2 * args.replans):
            kind = ("follow", "reassign")[replan % 2]
            targets = next_targets(kind, rng, targets, p)
            now_ms, ref_ms = [], []
            for _ in range(args.repeats):
                start = time.perf_counter()
                transition = plan_transition(p, v, targets, CONFIG, step_s=DT_S, area_m=AREA_M)
                now_ms.append(1e3 * (time.perf_counter() - start))
                start = time.perf_counter()
                reference.plan_transition(p, v, targets, CONFIG, area_m=AREA_M)
                ref_ms.append(1e3 * (time.perf_counter() - start))
            now, ref, counts = times.setdefault(kind, ([], [], [0, 0]))
            now.append(min(now_ms))
            ref.append(min(ref_ms))
            first.append(now_ms[0])
            counts[0] += int(transition.held.sum())
            counts[1] += len(transition.unresolved)
            for step in range(STEPS_PER_REPLAN):
                command = waypoint_velocity(p, transition.targets_at(step * DT_S), DT_S, CONFIG)
                p, v = fly_step(p, v, command, DT_S, CONFIG, AREA_M)
        for kind, (now, ref, counts) in times.items():
            print(f"{kind:<9} {np.median(now):>5.3f} ms {np.percentile(now, 95):>7.3f} {np.max(now):>7.3f} "
                  f"{np.median(ref):>10.3f} ms {np.percentile(ref, 95):>7.3f} "
                  f"{np.median(ref) / np.median(now):>5.1f}x {counts[0]:>6} {counts[1]:>10}")
        every = times["follow"][0] + times["reassign"][0]
        over = float(np.mean(np.array(every) > 0.5))
        print(f"all replans: p50 {np.median(every):.3f} ms, p95 {np.percentile(every, 95):.3f} ms, max "
              f"{np.max(every):.3f} ms, mean {np.mean(every):.3f} ms; over 0.5 ms: {over:.1%} (goal 0.5 ms)")
        print(f"single first timings: p50 {np.median(first):.3f} ms, p95 {np.percentile(first, 95):.3f} ms, "
              f"max {np.max(first):.3f} ms")
    print(f"load average at end {os.getloadavg()}")


if __name__ == "__main__":
    main()
