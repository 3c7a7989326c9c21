"""Is a transition reported resolved true when flown? A fuzz judged on the env's positions with scipy.

Each case draws a fleet (2-10 UAVs), an area (30-200 m), limits (speed 5-20 m/s, acceleration 2-8 m/s²,
env step 0.05-0.2 s, minimum 3-8 m, altitude layers in a quarter of the cases), start positions apart,
and flies two replans in a row: the first from rest or from random velocities, the second from wherever
the first left the UAVs after a random time (a replan in flight, with momentum in any direction). The
targets are drawn apart, one case in five with a pair planned exactly at the minimum and one in ten with
two coincident targets. Each transition of :func:`uav_swarm.planning.transitions.plan_transition` is flown
with :func:`uav_swarm.world.uav.waypoint_velocity` and :func:`uav_swarm.world.uav.fly_step`, no guard; the
judge is ``scipy.spatial.distance.pdist`` on the positions after every step (3-D with layers).

Fails (exit 1) when a pair the transition reported resolved comes under the minimum. Also reported: the
worst distance between the flown positions and the transition's prediction (``tracks_m``).

``--reference COMMIT`` flies the same cases with the transition planner of that commit instead (loaded from
git as in ``transitions_cost.py``; it predates ``step_s``), for a before/after comparison.

Usage: python benchmarks/flight/transitions_fuzz.py [--cases 1000] [--seed 0] [--reference 5c0ace9]
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile
import time
from pathlib import Path
from types import ModuleType

import numpy as np
from scipy.spatial.distance import pdist, squareform
from transitions_cost import reference_planner

from uav_swarm.planning.transitions import Transition, plan_transition
from uav_swarm.world.separation import check_fleet_fits, draw_apart_m, required_distances_m
from uav_swarm.world.uav import UAVConfig, fly_step, waypoint_velocity

JUDGE_TOLERANCE_M = 1e-9  # rounding of a UAV landing on its target


def flown_closest_m(transition: Transition, p: np.ndarray, v: np.ndarray, config: UAVConfig, step_s: float,
                    area_m: np.ndarray, altitudes_m: np.ndarray | None, steps: int
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Fly ``steps`` steps with no guard.

    Returns the closest distance of every pair (K, K), the positions and velocities after, and the worst
    deviation of the flown positions from the transition's prediction (m).
    """
    k = len(p)
    lifted = np.zeros((k, 1)) if altitudes_m is None else altitudes_m[:, None]
    closest = squareform(pdist(np.hstack([p, lifted])))
    np.fill_diagonal(closest, np.inf)
    deviation = 0.0
    tracks = getattr(transition, "tracks_m", None)
    for n in range(steps):
        command = waypoint_velocity(p, transition.targets_at(n * step_s), step_s, config)
        p, v = fly_step(p, v, command, step_s, config, area_m)
        closest = np.minimum(closest, squareform(pdist(np.hstack([p, lifted]))) + np.diag(np.full(k, np.inf)))
        if tracks is not None:
            deviation = max(deviation, float(np.abs(p - tracks[:, min(n + 1, tracks.shape[1] - 1)]).max()))
    return closest, p, v, deviation


def draw_targets(rng: np.random.Generator, k: int, area_m: np.ndarray, required: np.ndarray,
                 min_separation_m: float) -> tuple[np.ndarray, str]:
    """Targets apart, sometimes a pair exactly at the minimum or coincident (the case's label)."""
    targets = draw_apart_m(rng, k, area_m, required)
    kind = rng.uniform()
    if kind < 0.2:  # a pair planned exactly at the minimum
        angle = rng.uniform(0, 2 * np.pi)
        moved = targets[0] + min_separation_m * np.array([np.cos(angle), np.sin(angle)])
        if np.all((moved >= 0) & (moved <= area_m)):
            targets[1] = moved
            return targets, "at-minimum"
    elif kind < 0.3:
        targets[1] = targets[0]
        return targets, "coincident"
    return targets, "apart"


def run_case(rng: np.random.Generator, reference: ModuleType | None = None) -> dict:
    """One case (module docstring): the judge's figures of both replans."""
    while True:
        k = int(rng.integers(2, 11))
        side = rng.uniform(30.0, 200.0, 2)
        minimum = float(rng.uniform(3.0, 8.0))
        try:
            check_fleet_fits(k, 2.0 * minimum, float(side[0]), float(side[1]))
            break
        except ValueError:
            continue
    config = UAVConfig(min_separation_m=minimum, max_speed_m_s=float(rng.uniform(5.0, 20.0)),
                       max_accel_m_s2=float(rng.uniform(2.0, 8.0)),
                       layer_step_m=float(rng.choice([0.0, 0.0, 0.0, rng.uniform(0.5, 4.0)])))
    step_s = float(rng.choice([0.05, 0.1, 0.1, 0.2]))
    altitudes = config.altitudes_m(k) if config.layer_step_m > 0 else None
    required = required_distances_m(minimum, altitudes, k)
    p = draw_apart_m(rng, k, side, required)
    v = np.zeros((k, 2))
    if rng.uniform() < 0.5:
        angle = rng.uniform(0, 2 * np.pi, k)
        v = rng.uniform(0, config.max_speed_m_s, (k, 1)) * np.stack([np.cos(angle), np.sin(angle)], 1)
    out = {"k": k, "bad_pairs": 0, "resolved_pairs": 0, "unresolved_pairs": 0, "transitions": 0,
           "resolved_transitions": 0, "deviation_m": 0.0, "closest_resolved_m": np.inf, "plan_ms": [],
           "kinds": []}
    for replan in range(2):
        targets, kind = draw_targets(rng, k, side, required, minimum)
        start = time.perf_counter()
        if reference is None:
            transition = plan_transition(p, v, targets, config, altitudes, step_s=step_s, area_m=side)
            steps = transition.tracks_m.shape[1] + 20
        else:
            transition = reference.plan_transition(p, v, targets, config, altitudes, area_m=side)
            flight_s = 2.0 * float(np.hypot(*side)) / config.max_speed_m_s + 4.0 * config.max_speed_m_s / (
                config.max_accel_m_s2) + 5.0
            steps = int((float(transition.delays_s.max()) + flight_s) / step_s)
        out["plan_ms"].append(1e3 * (time.perf_counter() - start))
        if replan == 0:
            steps = int(rng.integers(1, steps))  # the next replan comes in flight
        closest, p_next, v_next, deviation = flown_closest_m(transition, p, v, config, step_s, side,
                                                             altitudes, steps)
        unresolved = np.zeros((k, k), bool)
        unresolved[tuple(transition.unresolved.T)] = True
        unresolved |= unresolved.T
        pairs = np.triu(np.ones((k, k), bool), 1)
        resolved = pairs & ~unresolved
        bad = resolved & (closest < minimum - JUDGE_TOLERANCE_M)
        out["bad_pairs"] += int(bad.sum())
        out["resolved_pairs"] += int(resolved.sum())
        out["unresolved_pairs"] += int((pairs & unresolved).sum())
        out["transitions"] += 1
        out["resolved_transitions"] += int(not unresolved.any())
        out["deviation_m"] = max(out["deviation_m"], deviation)
        if resolved.any():
            ratio = float(closest[resolved].min()) / minimum
            out["closest_resolved_m"] = min(out["closest_resolved_m"], ratio)
        out["kinds"].append(kind)
        p, v = p_next, v_next
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--reference", default=None, help="git commit of a transition planner to fly instead")
    args = parser.parse_args()
    print(f"machine: {platform.machine()}, {os.cpu_count()} CPUs; load average at start {os.getloadavg()}")
    rng = np.random.default_rng(args.seed)
    folder = tempfile.TemporaryDirectory()
    reference = None if args.reference is None else reference_planner(args.reference, Path(folder.name))
    print(f"planner: {'reference ' + args.reference if reference else 'this tree'}")
    plan_transition(np.zeros((2, 2)), np.zeros((2, 2)), np.ones((2, 2)), UAVConfig())  # compile first
    totals: dict = {"bad_pairs": 0, "resolved_pairs": 0, "unresolved_pairs": 0, "transitions": 0,
                    "resolved_transitions": 0, "deviation_m": 0.0, "closest_resolved_m": np.inf}
    plan_ms: list[float] = []
    kinds: dict[str, int] = {}
    start = time.perf_counter()
    for _ in range(args.cases):
        case = run_case(rng, reference)
        for key in ("bad_pairs", "resolved_pairs", "unresolved_pairs", "transitions", "resolved_transitions"):
            totals[key] += case[key]
        totals["deviation_m"] = max(totals["deviation_m"], case["deviation_m"])
        totals["closest_resolved_m"] = min(totals["closest_resolved_m"], case["closest_resolved_m"])
        plan_ms += case["plan_ms"]
        for kind in case["kinds"]:
            kinds[kind] = kinds.get(kind, 0) + 1
    print(f"{args.cases} cases (seed {args.seed}), {totals['transitions']} transitions flown without the "
          f"guard ({kinds}) in {time.perf_counter() - start:.0f} s")
    print(f"transitions reported resolved: {totals['resolved_transitions']}; pairs resolved "
          f"{totals['resolved_pairs']}, unresolved {totals['unresolved_pairs']}")
    deviation = "n/a" if reference else f"{totals['deviation_m']:.2e} m"
    print(f"resolved pairs under the minimum when flown: {totals['bad_pairs']}; closest resolved pair "
          f"{totals['closest_resolved_m']:.4f} x the minimum; flown vs predicted: worst {deviation}")
    print(f"plan_transition p50 {np.median(plan_ms):.3f} ms, p95 {np.percentile(plan_ms, 95):.3f} ms")
    print(f"load average at end {os.getloadavg()}")
    raise SystemExit(1 if totals["bad_pairs"] else 0)


if __name__ == "__main__":
    main()
