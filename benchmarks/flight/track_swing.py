"""How far the simulated autopilots fly from the straight segment they are sent along (the tube's width).

A certified set shaped along a committed segment (a tube) needs a bound on how far a vehicle swings across
the segment and runs on past its end. This measures both on the guard trial's autopilot models
(:mod:`uav_swarm.runs.flight.guard_trial`: the point mass, the jerk-limited ArduCopter-like and the per-axis
PX4-like), without wind, latency or noise (the controller's own swing), drawn within the fuzz's bounds
(5-20 m/s, 2-5 m/s^2, jerk 2-10 m/s^3), the segment in any direction, 10-100 m long:

- **from rest**: a vehicle at rest sent a point;
- **on the line**: flying along the segment's line at 30-100 % of its speed, sent a point 10-100 m ahead;
- **turned**: flying at 30-100 % of its speed in a direction 5-90 degrees off the segment, sent a point
  along it (its new segment starts where the point arrives).

For each flight, until the vehicle is at rest at the point (or 120 s): the largest distance across the
line through the segment (**swing**), the furthest past its end along it (**overshoot**) and behind its
start (**back**). Beside them, the bounds a tube would use: the one-sided swing bound
``(V + U) / a * |v_across|`` (``U`` the larger of the start speed and ``V``: the swing of a vehicle that
does not cross the line, :mod:`uav_swarm.world.guard`'s liveness paragraph) and, along the path, what braking
at ``a`` from the start speed cannot avoid (``v^2 / 2a`` beyond the segment's length) plus the jerk run-on
``2 v a / j + a^3 / j^2``. The counts of flights beyond each are printed.

Usage: python benchmarks/flight/track_swing.py [--flights 200] [--seed 0]
       [--autopilot pointmass arducopter px4]
"""

from __future__ import annotations

import os

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):  # one thread, before numpy
    os.environ[_name] = "1"

import argparse  # noqa: E402
import math  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from bridge.simulated.dynamics import AutopilotLimits, PointMassCopter, Realism  # noqa: E402
from bridge.simulated.jerk_limited import ArduCopterLikeCopter, JerkLimits, PX4LikeCopter  # noqa: E402

AUTOPILOTS = ("pointmass", "arducopter", "px4")
KINDS = ("from rest", "on the line", "turned")
_DT_S = 0.05
_ALT_M = 30.0


def _copter(autopilot: str, speed: float, accel: float, jerk: float, rng: np.random.Generator
            ) -> PointMassCopter:
    limits = AutopilotLimits(speed, accel, climb_m_s=3.0, descent_m_s=1.5)
    start = np.array([0.0, 0.0, _ALT_M])
    if autopilot == "pointmass":
        return PointMassCopter(start, limits, Realism(), rng)
    kind = ArduCopterLikeCopter if autopilot == "arducopter" else PX4LikeCopter
    return kind(start, limits, Realism(), rng, JerkLimits(jerk_m_s3=jerk, vertical_jerk_m_s3=jerk))


def _go(copter: PointMassCopter, point: np.ndarray) -> None:
    while not copter.send(copter.now_s, np.array([*point, _ALT_M])):
        pass


def fly_one(autopilot: str, kind: str, rng: np.random.Generator) -> dict[str, float]:
    """One flight (module docstring): its swing, overshoot and back-run, and the bounds beside them."""
    speed, accel = float(rng.uniform(5.0, 20.0)), float(rng.uniform(2.0, 5.0))
    jerk = float(rng.uniform(2.0, 10.0)) if autopilot != "pointmass" else math.inf
    heading, length = float(rng.uniform(0.0, 2.0 * math.pi)), float(rng.uniform(10.0, 100.0))
    along = np.array([math.cos(heading), math.sin(heading)])
    copter = _copter(autopilot, speed, accel, jerk, rng)
    if kind != "from rest":
        turn = 0.0 if kind == "on the line" else float(rng.choice([-1.0, 1.0]) * rng.uniform(5.0, 90.0))
        angle = heading + math.radians(turn)
        _go(copter, 1e4 * np.array([math.cos(angle), math.sin(angle)]))
        wanted = float(rng.uniform(0.3, 1.0)) * speed
        while float(np.hypot(*copter.velocity_m_s[:2])) < wanted and copter.now_s < 60.0:
            copter.advance(_DT_S)
    start = copter.position_m[:2].copy()
    velocity = copter.velocity_m_s[:2].copy()
    end = start + along * length
    _go(copter, end)
    across = np.array([-along[1], along[0]])
    swing = overshoot = back = 0.0
    t0 = copter.now_s
    while copter.now_s - t0 < 120.0:
        copter.advance(_DT_S)
        offset = copter.position_m[:2] - start
        swing = max(swing, abs(float(offset @ across)))
        overshoot = max(overshoot, float(offset @ along) - length)
        back = max(back, -float(offset @ along))
        if (float(np.hypot(*(copter.position_m[:2] - end))) < 0.05
                and float(np.hypot(*copter.velocity_m_s[:2])) < 0.05):
            break
    v0 = float(np.hypot(*velocity))
    fastest = max(v0, speed)
    run_on = 0.0 if not math.isfinite(jerk) else 2.0 * v0 * accel / jerk + accel**3 / jerk**2
    braking = max(0.0, v0 * v0 / (2.0 * accel) - length)  # too close to stop at the point at all
    return {"swing": swing, "swing_bound": (speed + fastest) / accel * abs(float(velocity @ across)),
            "overshoot": overshoot, "run_on": braking + run_on, "back": back}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--autopilot", choices=AUTOPILOTS, nargs="+", default=list(AUTOPILOTS))
    parser.add_argument("--flights", type=int, default=200, help="flights per autopilot and kind")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    print(f"{platform.node()} {platform.processor() or platform.machine()}, load "
          f"{tuple(round(x, 2) for x in os.getloadavg())}", flush=True)
    print("| autopilot | flights | swing p50 / p95 / max | beyond the one-sided swing bound (worst excess) "
          "| overshoot p95 / max | beyond the run-on (worst excess) | back max |")
    print("|---|---|---|---|---|---|---|")
    for autopilot in args.autopilot:
        for kind in KINDS:
            rng = np.random.default_rng([args.seed, AUTOPILOTS.index(autopilot), KINDS.index(kind)])
            begun = time.perf_counter()
            rows = [fly_one(autopilot, kind, rng) for _ in range(args.flights)]
            swing = np.array([r["swing"] for r in rows])
            over = np.array([r["overshoot"] for r in rows])
            swing_excess = np.array([r["swing"] - r["swing_bound"] for r in rows])
            run_excess = over - np.array([r["run_on"] for r in rows])
            worst_swing, worst_run = max(0.0, float(swing_excess.max())), max(0.0, float(run_excess.max()))
            print(f"| {autopilot}, {kind} | {len(rows)} | {np.median(swing):.2f} / "
                  f"{np.percentile(swing, 95):.2f} / {swing.max():.2f} m | "
                  f"{int((swing_excess > 0.01).sum())} ({worst_swing:.2f} m) | "
                  f"{np.percentile(over, 95):.2f} / {over.max():.2f} m | "
                  f"{int((run_excess > 0.01).sum())} ({worst_run:.2f} m) | "
                  f"{max(r['back'] for r in rows):.2f} m | ({time.perf_counter() - begun:.0f} s)", flush=True)
    print(f"load after {tuple(round(x, 2) for x in os.getloadavg())}", flush=True)


if __name__ == "__main__":
    main()
