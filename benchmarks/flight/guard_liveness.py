"""The separation guard's liveness: separable goals reached within 1.5x the unguarded time, 5 and 10 UAVs.

For each autopilot (``pointmass``, ``arducopter``, ``px4``: :mod:`uav_swarm.runs.flight.guard_trial`) and each
fleet size (5 and 10 vehicles):

- **formation moves** (:func:`uav_swarm.runs.flight.guard_trial.formation_trial`, drawn by the seed: a grid
  translated, a circle expanded, a launch line spread), kept only when separable (the same vehicles flown
  unguarded keep the minimum plus both hover tolerances plus 1 m at every instant), flown under the guard;
- for 5 vehicles also **random goals** (the fuzz's :func:`~uav_swarm.runs.flight.guard_trial.random_trial`
  with 5 vehicles, no events): a new goal for each vehicle every 1-10 s.

A goal counts when it is reached within ``within_factor`` (1.5) times what the same vehicle needed
unguarded (:class:`~uav_swarm.runs.flight.guard_trial.TrialResult`'s ``timely``); the fuzz's old measure
(reached at all) is printed beside it. The goal: at least 95 % in time for 5 and for 10 vehicles.

Usage: python benchmarks/flight/guard_liveness.py [--moves 20] [--random 20] [--seed 0]
       [--autopilot pointmass arducopter px4] [--json results.json]
"""

from __future__ import annotations

import os

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):  # one thread, before numpy
    os.environ[_name] = "1"

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from uav_swarm.runs.flight.guard_trial import (  # noqa: E402
    AUTOPILOTS,
    FORMATIONS,
    TrialResult,
    fly_trial,
    formation_trial,
    random_trial,
    separable,
)


def _line(name: str, results: list[TrialResult], drawn: int, seconds: float) -> dict[str, float]:
    goals = sum(r.goals for r in results)
    timely, reached = sum(r.timely for r in results), sum(r.reached for r in results)
    figures = {"drawn": drawn, "flights": len(results), "goals": goals, "timely": timely, "reached": reached,
               "timely_pct": round(100.0 * timely / goals, 1) if goals else float("nan"),
               "reached_pct": round(100.0 * reached / goals, 1) if goals else float("nan"),
               "closest_m": round(min((r.closest_m for r in results), default=float("inf")), 2),
               "pairs_under": sum(r.pairs_under for r in results),
               "outside": sum(r.outside for r in results), "seconds": round(seconds, 1)}
    print(f"{name}: {len(results)} of {drawn} separable | in time (1.5x) {timely}/{goals} = "
          f"{figures['timely_pct']:.1f} % | reached {figures['reached_pct']:.1f} % | closest "
          f"{figures['closest_m']:.2f} m | under the minimum {figures['pairs_under']} | outside their set "
          f"{figures['outside']} | {seconds:.0f} s", flush=True)
    return figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--autopilot", choices=AUTOPILOTS, nargs="+", default=list(AUTOPILOTS))
    parser.add_argument("--moves", type=int, default=20, help="formation moves drawn per autopilot and size")
    parser.add_argument("--random", type=int, default=20, help="random 5-vehicle flights per autopilot")
    parser.add_argument("--duration", type=float, default=60.0, help="simulated seconds per flight")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=Path, default=None, help="write the figures here too")
    args = parser.parse_args()
    if args.moves < 0 or args.random < 0 or not args.duration > 0.0:
        parser.error("--moves and --random must be >= 0 and --duration > 0")
    warnings.simplefilter("ignore", RuntimeWarning)  # a guard's inf - inf is its own business here
    print(f"{platform.node()} {platform.processor() or platform.machine()}, load "
          f"{tuple(round(x, 2) for x in os.getloadavg())}", flush=True)
    report: dict[str, object] = {"seed": args.seed, "load_before": os.getloadavg()}
    for autopilot in args.autopilot:
        for n in (5, 10):
            rng = np.random.default_rng([args.seed, n, AUTOPILOTS.index(autopilot)])
            start = time.perf_counter()
            trials = [formation_trial(rng, args.seed * 100_000 + m, n, FORMATIONS[m % len(FORMATIONS)],
                                      autopilot, args.duration) for m in range(args.moves)]
            kept = [t for t in trials if separable(t)]
            report[f"{autopilot} formation n={n}"] = _line(f"{autopilot}, {n} vehicles, formation moves",
                                                           [fly_trial(t) for t in kept], len(trials),
                                                           time.perf_counter() - start)
        rng = np.random.default_rng([args.seed, 5, 100 + AUTOPILOTS.index(autopilot)])
        start = time.perf_counter()
        trials = [dataclasses.replace(random_trial(rng, args.seed * 100_000 + m, args.duration, autopilot),
                                      n_uavs=5) for m in range(args.random)]
        report[f"{autopilot} random n=5"] = _line(f"{autopilot}, 5 vehicles, random goals",
                                                  [fly_trial(t) for t in trials], len(trials),
                                                  time.perf_counter() - start)
    report["load_after"] = os.getloadavg()
    print(f"load after {tuple(round(x, 2) for x in os.getloadavg())}", flush=True)
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
