"""Cost of keeping 10 UAVs apart: the transition per replan and the step guard per step, on one thread.

Seeded replans of 10 UAVs in a 200 m square (minimum separation 5 m), three kinds, interleaved:

- ``follow``: every UAV moves on 0-4 m from where it flies (planning in motion following its users);
- ``reassign``: three UAVs get new targets anywhere, the others follow;
- ``permute``: every UAV is sent to another UAV's target, unassigned (the worst case: many crossings).

For each, :func:`uav_swarm.planning.transitions.plan_transition` (the check of every pair's closest approach
and the departure delays) is timed per replan, and :func:`uav_swarm.world.step_guard.guard_commands` per
step of the flight that follows. The reference, timed in the same rounds, is one kinematic step of the 10
UAVs (:func:`uav_swarm.world.uav.waypoint_velocity` + :func:`uav_swarm.world.uav.fly_step`). Goal: a replan's
separation step (transition) within 0.5 ms for 10 UAVs.

Usage: python benchmarks/flight/separation_step.py [--replans 200] [--seed 0]
"""

from __future__ import annotations

import os

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):  # one thread, before numpy
    os.environ[_name] = "1"

import argparse  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from uav_swarm.planning.transitions import plan_transition, warm_up  # noqa: E402
from uav_swarm.world.step_guard import guard_commands  # noqa: E402
from uav_swarm.world.uav import UAVConfig, fly_step, waypoint_velocity  # noqa: E402

CONFIG = UAVConfig(min_separation_m=5.0)
AREA_M = np.array([200.0, 200.0])
DT_S = 0.1
STEPS_PER_REPLAN = 10
KINDS = ("follow", "reassign", "permute")


def spread(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` points in the area at least 8 m apart (rejection sampling)."""
    points: list[np.ndarray] = []
    while len(points) < n:
        point = rng.uniform(10.0, 190.0, 2)
        if all(np.hypot(*(point - other)) >= 8.0 for other in points):
            points.append(point)
    return np.array(points)


def next_targets(kind: str, rng: np.random.Generator, targets: np.ndarray) -> np.ndarray:
    """The next plan's targets of one replan ``kind`` (module docstring)."""
    if kind == "permute":
        return targets[np.roll(np.arange(len(targets)), int(rng.integers(1, len(targets))))]
    moved = targets + rng.uniform(-4.0, 4.0, targets.shape) * rng.uniform(0.0, 1.0, (len(targets), 1))
    if kind == "reassign":
        for k in rng.choice(len(targets), 3, replace=False):
            moved[k] = spread(rng, 1)[0]
    return np.clip(moved, 0.0, AREA_M)


def run(kind: str, replans: int, seed: int) -> tuple[list[float], list[float], list[float], int, int]:
    """Times (ms) of the transitions, the guard steps and the reference steps; holds, unresolved pairs."""
    rng = np.random.default_rng(seed)
    targets = spread(rng, 10)
    p, v = targets.copy(), np.zeros_like(targets)
    transition_ms, guard_ms, reference_ms = [], [], []
    holds = unresolved = 0
    for _ in range(replans):
        targets = next_targets(kind, rng, targets)
        start = time.perf_counter()
        transition = plan_transition(p, v, targets, CONFIG)
        transition_ms.append(1e3 * (time.perf_counter() - start))
        holds += int(transition.held.sum())
        unresolved += len(transition.unresolved)
        for step in range(STEPS_PER_REPLAN):
            start = time.perf_counter()
            wanted = waypoint_velocity(p, transition.targets_at(step * DT_S), DT_S, CONFIG)
            fly_step(p, v, wanted, DT_S, CONFIG, AREA_M)
            reference_ms.append(1e3 * (time.perf_counter() - start))
            start = time.perf_counter()
            command, _ = guard_commands(p, v, wanted, DT_S, CONFIG, upper_m=AREA_M)
            guard_ms.append(1e3 * (time.perf_counter() - start))
            p, v = fly_step(p, v, command, DT_S, CONFIG, AREA_M)
    return transition_ms, guard_ms, reference_ms, holds, unresolved


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--replans", type=int, default=200, help="replans per kind (default: %(default)s)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, one thread; "
          f"numpy {np.__version__}; load average at start {os.getloadavg()}")
    warm_up()  # the compiled kernels, loaded before timing
    for kind in KINDS:
        run(kind, 2, args.seed + 1)
    print(f"10 UAVs, minimum {CONFIG.min_separation_m:g} m, {args.replans} replans per kind, "
          f"{STEPS_PER_REPLAN} steps of {DT_S:g} s after each")
    print(f"{'kind':<9} {'transition p50':>14} {'p95':>7} {'max':>7} {'guard p50':>9} {'p95':>7} "
          f"{'ref step p50':>12} {'transition/ref':>14} {'holds':>6} {'unresolved':>10}")
    for kind in KINDS:
        transition, guard, reference, holds, unresolved = run(kind, args.replans, args.seed)
        ref = float(np.median(reference))
        print(f"{kind:<9} {np.median(transition):>11.3f} ms {np.percentile(transition, 95):>7.3f} "
              f"{np.max(transition):>7.3f} {np.median(guard):>6.3f} ms {np.percentile(guard, 95):>7.3f} "
              f"{ref:>9.3f} ms {np.median(transition) / ref:>13.1f}x {holds:>6} {unresolved:>10}")
    print(f"load average at end {os.getloadavg()}")


if __name__ == "__main__":
    main()
