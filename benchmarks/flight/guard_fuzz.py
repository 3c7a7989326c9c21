"""The separation guard fuzzed against simulated autopilots in simulated time, judged on true positions.

Each flight (:func:`uav_swarm.runs.flight.guard_trial.random_trial`, seeded): 2-10 vehicles flown by
``--autopilot`` (``pointmass``: :class:`bridge.simulated.dynamics.PointMassCopter`; ``arducopter`` and
``px4``: the jerk-limited models of :mod:`bridge.simulated.jerk_limited`, jerk 2-10 m/s^3), 5-20 m/s,
acceleration 2-5 m/s^2, command latency 0-1.5 s (5 % of commands lost in half the flights), positions
0-1 s old at 5 or 10 Hz (noise 0 or 0.2 m), square areas from the fleet check's limit to 200 m, a new goal
for each vehicle every 1-10 s; the guard decides 10 times a second on the reports and is told the limits
the vehicles report. With events (the default), five flights in six add one event for one vehicle: silent
(link down both ways) or without a fix for 5-20 s, joined in flight, stale first rows, or a reversal while
still accelerating away. Then the named cases (:data:`uav_swarm.runs.flight.guard_trial.NAMED_TRIALS` and
:data:`~uav_swarm.runs.flight.guard_trial.EVENT_TRIALS`), each with every worst bound, and a share of the
flights outside the bounds (the autopilots brake at 60 % of what the guard is told): whether the guard
detected it, and how close the vehicles came.

The judge (:func:`uav_swarm.runs.flight.guard_trial.fly_trial`): true positions every 0.05 s; pairs that came
under the minimum (``scipy.spatial.distance.pdist``); vehicles found outside the set the guard certified
for them (true position against ``centre_m`` / ``radius_m``); liveness, the share of separable goals
reached, and of those reached within 1.5 times the unguarded time (the module docstring of
:mod:`uav_swarm.runs.flight.guard_trial`; formation moves of 5 and 10 vehicles:
``benchmarks/flight/guard_liveness.py``).

Usage: python benchmarks/flight/guard_fuzz.py [--autopilot pointmass|arducopter|px4] [--flights 1000]
       [--duration 60] [--seed 0] [--no-events] [--outside-share 0.2] [--json results.json]
"""

from __future__ import annotations

import os

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):  # one thread, before numpy
    os.environ[_name] = "1"

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from uav_swarm.runs.flight.guard_trial import (  # noqa: E402
    AUTOPILOTS,
    EVENT_TRIALS,
    EVENTS,
    NAMED_TRIALS,
    WORST_BOUNDS,
    Trial,
    TrialResult,
    event_of,
    fly_trial,
    random_trial,
)


def _summary(name: str, results: list[TrialResult], seconds: float | None = None) -> dict[str, float]:
    """One line of figures for a set of flights; the figures."""
    goals, reached = sum(r.goals for r in results), sum(r.reached for r in results)
    timely = sum(r.timely for r in results)
    figures = {
        "flights": len(results),
        "closest_m": round(min((r.closest_m for r in results), default=float("inf")), 2),
        "pairs_under": sum(r.pairs_under for r in results),
        "flights_under": sum(r.pairs_under > 0 for r in results),
        "outside": sum(r.outside for r in results),
        "flights_outside": sum(r.outside > 0 for r in results),
        "outside_m": round(max((r.outside_m for r in results), default=0.0), 2),
        "goals": goals,
        "reached": reached,
        "liveness_pct": round(100.0 * reached / goals, 1) if goals else float("nan"),
        "timely": timely,
        "timely_pct": round(100.0 * timely / goals, 1) if goals else float("nan"),
        "breaches": sum(r.breaches for r in results),
    }
    took = "" if seconds is None else f" | {seconds:.0f} s"
    print(f"{name}: {len(results)} flights | closest {figures['closest_m']:.2f} m | under the minimum: "
          f"{figures['pairs_under']} pairs ({figures['flights_under']} flights) | outside their set: "
          f"{figures['outside']} vehicles ({figures['flights_outside']} flights, up to "
          f"{figures['outside_m']:.2f} m) | liveness {reached}/{goals} = {figures['liveness_pct']:.1f} % "
          f"({timely} in 1.5x the unguarded time: {figures['timely_pct']:.1f} %) | "
          f"guard breaches {figures['breaches']}{took}", flush=True)
    return figures


def _write_json(path: Path, payload: dict[str, object]) -> None:
    """Write atomically: a temporary file beside it, then renamed over it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile("w", dir=path.parent, delete=False, suffix=".tmp") as handle:
        json.dump(payload, handle, indent=1, default=str)
    os.replace(handle.name, path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--autopilot", choices=AUTOPILOTS, default="pointmass")
    parser.add_argument("--flights", type=int, default=1000)
    parser.add_argument("--duration", type=float, default=60.0, help="simulated seconds per flight")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-events", action="store_true", help="random flights without events")
    parser.add_argument("--outside-share", type=float, default=0.2,
                        help="share of the flights flown again outside the bounds (0: none)")
    parser.add_argument("--json", type=Path, default=None, help="write the figures here too")
    args = parser.parse_args()
    if args.flights < 1 or not args.duration > 0.0 or not 0.0 <= args.outside_share <= 1.0:
        parser.error("--flights must be >= 1, --duration > 0 and --outside-share in [0, 1]")
    warnings.simplefilter("ignore", RuntimeWarning)  # a guard's inf - inf is its own business here
    load_before = os.getloadavg()
    print(f"{platform.node()} {platform.processor() or platform.machine()}, autopilot {args.autopilot}, "
          f"load {tuple(round(x, 2) for x in load_before)}", flush=True)
    rng = np.random.default_rng(args.seed)
    trials = [random_trial(rng, args.seed * 100_000 + i, args.duration, args.autopilot, not args.no_events)
              for i in range(args.flights)]
    start = time.perf_counter()
    results = [fly_trial(t) for t in trials]
    report: dict[str, object] = {"autopilot": args.autopilot, "flights": args.flights, "seed": args.seed,
                                 "duration_s": args.duration, "load_before": load_before}
    report["random"] = _summary("within the bounds", results, time.perf_counter() - start)
    by_event = {}
    for kind in ("none", *EVENTS):
        picked = [r for t, r in zip(trials, results, strict=True) if event_of(t) == kind]
        if picked:
            by_event[kind] = _summary(f"  event {kind}", picked)
    report["by_event"] = by_event
    by_size = {}
    for bucket, (low, high) in {"n 2-4": (2, 4), "n 5-7": (5, 7), "n 8-10": (8, 10)}.items():
        picked = [r for t, r in zip(trials, results, strict=True) if low <= t.n_uavs <= high]
        if picked:
            by_size[bucket] = _summary(f"  {bucket}", picked)
    report["by_size"] = by_size
    start = time.perf_counter()
    named: dict[str, object] = {}
    all_named = []
    for case_name, case in {**NAMED_TRIALS, **EVENT_TRIALS}.items():
        flown = [fly_trial(Trial(**{**case.__dict__, **worst, "autopilot": args.autopilot}))
                 for worst in WORST_BOUNDS.values()]
        all_named += flown
        named[case_name] = _summary(f"  named {case_name} (x {len(WORST_BOUNDS)} bounds)", flown)
    named["all"] = _summary("named cases", all_named, time.perf_counter() - start)
    report["named"] = named
    count = int(round(args.outside_share * len(trials)))
    if count:
        outside = [dataclasses.replace(t, accel_m_s2=0.6 * t.accel_m_s2, stated_accel_m_s2=t.accel_m_s2)
                   for t in trials[:count]]
        start = time.perf_counter()
        report["braking_60_pct"] = _summary("braking at 60 % of the stated (outside the bounds)",
                                            [fly_trial(t) for t in outside], time.perf_counter() - start)
    load_after = os.getloadavg()
    report["load_after"] = load_after
    print(f"load after {tuple(round(x, 2) for x in load_after)}", flush=True)
    if args.json is not None:
        _write_json(args.json, report)


if __name__ == "__main__":
    main()
