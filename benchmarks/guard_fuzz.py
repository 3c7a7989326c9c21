"""The separation guard fuzzed against simulated autopilots in simulated time: >= 1,000 randomised flights.

Each flight (:func:`uav_swarm.runs.guard_trial.random_trial`, seeded): 2-10 vehicles, 5-20 m/s, braking
2-5 m/s^2 (acceleration and braking share it), command latency 0-1.5 s (5 % of commands lost in half the
flights), positions 0-1 s old at 5 or 10 Hz (noise 0 or 0.2 m), square areas from the fleet check's limit
to 200 m, a new goal for each vehicle every 1-10 s; the guard decides 10 times a second on the reports.
The judge: the true positions every 0.05 s, ``scipy.spatial.distance.pdist``. Then the named cases of
``tests/runs/test_guard_trial.py`` and the same flights outside the bounds (the autopilots brake at
60 % of what the guard is told): whether the guard detected it, and how close the vehicles came.

Usage: python benchmarks/guard_fuzz.py [--flights 1000] [--duration 60] [--seed 0]
"""

from __future__ import annotations

import os

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):  # one thread, before numpy
    os.environ[_name] = "1"

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from uav_swarm.runs.guard_trial import NAMED_TRIALS, WORST_BOUNDS, Trial, TrialResult, fly_trial, random_trial  # noqa: E402


def _summary(name: str, results: list[TrialResult], seconds: float) -> None:
    closest = min(r.closest_m for r in results)
    under = sum(r.closest_m < 5.0 for r in results)
    goals, reached = sum(r.goals for r in results), sum(r.reached for r in results)
    breaches = sum(r.breaches for r in results)
    detected = sum(r.breaches > 0 for r in results)
    print(f"{name}: {len(results)} flights, closest pair {closest:.2f} m, flights under 5 m: {under}, "
          f"goals reached {reached}/{goals} ({100 * reached / max(goals, 1):.1f} %), flights with a "
          f"breach detected {detected} ({breaches} breaches), {seconds:.0f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--flights", type=int, default=1000)
    parser.add_argument("--duration", type=float, default=60.0, help="simulated seconds per flight")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    print(f"{platform.node()} {platform.processor() or platform.machine()}, load {os.getloadavg()}")
    rng = np.random.default_rng(args.seed)
    trials = [random_trial(rng, args.seed * 100_000 + i, args.duration) for i in range(args.flights)]
    start = time.perf_counter()
    results = [fly_trial(t) for t in trials]
    _summary("within the bounds", results, time.perf_counter() - start)
    for bucket, (low, high) in {"n 2-4": (2, 4), "n 5-7": (5, 7), "n 8-10": (8, 10)}.items():
        picked = [r for t, r in zip(trials, results, strict=True) if low <= t.n_uavs <= high]
        goals, reached = sum(r.goals for r in picked), sum(r.reached for r in picked)
        if not picked:
            continue
        print(f"  {bucket}: {len(picked)} flights, closest {min(r.closest_m for r in picked):.2f} m, goals "
              f"reached {100 * reached / max(goals, 1):.1f} %")
    named = [fly_trial(Trial(**{**case.__dict__, **worst}))
             for case in NAMED_TRIALS.values() for worst in WORST_BOUNDS.values()]
    _summary("named cases", named, 0.0)
    outside = [dataclasses.replace(t, accel_m_s2=0.6 * t.accel_m_s2, stated_accel_m_s2=t.accel_m_s2)
               for t in trials[: max(1, args.flights // 5)]]
    start = time.perf_counter()
    _summary("braking at 60 % of the stated", [fly_trial(t) for t in outside], time.perf_counter() - start)
    print(f"load after {os.getloadavg()}")


if __name__ == "__main__":
    main()
