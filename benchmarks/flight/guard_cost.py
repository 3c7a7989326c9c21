"""Cost of the separation guard for 10 vehicles, with holds, on one thread.

- ``FlightGuard.decide`` (the guard of a live flight: measurements in, next points out) on 10 vehicles in
  a 60 m square flying to crossing goals (many refused points: holds), fed the states of a simulated
  flight (:mod:`uav_swarm.runs.flight.guard_trial`'s vehicles), timed per decision;
- ``guard_commands`` (the env's guard, :mod:`uav_swarm.world.step_guard`) per step for 10 UAVs in a
  30 m and a 60 m square with crossing waypoints (holds on most steps), timed per step.

The reference, timed in the same rounds, is one kinematic step of the 10 UAVs
(:func:`uav_swarm.world.uav.waypoint_velocity` + :func:`uav_swarm.world.uav.fly_step`). Goals: the flight
guard within 2 ms per decision, the env's guard within 1 ms per step with holds.

Usage: python benchmarks/flight/guard_cost.py [--rounds 2000] [--seed 0]
"""

from __future__ import annotations

import os

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):  # one thread, before numpy
    os.environ[_name] = "1"

import argparse  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from bridge.simulated.dynamics import AutopilotLimits, PointMassCopter, Realism  # noqa: E402
from uav_swarm.runs.flight.guard import FlightGuard, GuardConfig  # noqa: E402
from uav_swarm.world.separation import draw_apart_m  # noqa: E402
from uav_swarm.world.step_guard import guard_commands  # noqa: E402
from uav_swarm.world.uav import UAVConfig, fly_step, waypoint_velocity  # noqa: E402

K = 10


def flight_guard(rng: np.random.Generator, rounds: int) -> tuple[list[float], list[float], int]:
    """Seconds per ``FlightGuard.decide`` over a simulated flight of 10 vehicles, and the holds seen.

    Timed by the wall clock and by this process's CPU time (what a busy machine's other processes do not add).
    """
    area = np.array([60.0, 60.0])
    starts = draw_apart_m(rng, K, area, np.full((K, K), 8.0))
    limits = AutopilotLimits(10.0, 2.5, climb_m_s=3.0, descent_m_s=1.5)
    copters = [PointMassCopter(np.array([*p, 10.0]), limits, Realism(command_latency_s=0.3),
                               np.random.default_rng(i)) for i, p in enumerate(starts)]
    guard = FlightGuard(GuardConfig(), min_separation_m=5.0, n_vehicles=K)
    goals = starts[rng.permutation(K)]
    times, cpu, holds, now_s = [], [], 0, 0.0
    for step in range(rounds):
        if step % 50 == 0:
            goals = draw_apart_m(rng, K, area, np.full((K, K), 8.0))
        rows = [(i, tuple(c.position_m[:2]), tuple(c.velocity_m_s[:2]), now_s, tuple(goals[i]), True)
                for i, c in enumerate(copters)]
        start, start_cpu = time.perf_counter(), time.process_time()
        decisions = guard.decide(rows, now_s)
        times.append(time.perf_counter() - start)
        cpu.append(time.process_time() - start_cpu)
        holds += sum(d.state == "held" for d in decisions)
        for i, d in enumerate(decisions):
            if d.point_m is not None:
                copters[i].send(now_s, np.array([*d.point_m, 10.0]))
                guard.acknowledged(i, d.seq, now_s)
        for c in copters:
            c.advance(0.1)
        now_s += 0.1
    return times, cpu, holds


def env_guard(rng: np.random.Generator, rounds: int, side_m: float) -> tuple[list[float], list[float], int]:
    """Seconds per ``guard_commands`` step and per reference step, and the steps with a hold."""
    config, dt_s, area = UAVConfig(min_separation_m=5.0), 0.1, np.array([side_m, side_m])
    p = draw_apart_m(rng, K, area, np.full((K, K), 6.0))
    v = np.zeros_like(p)
    targets = p[rng.permutation(K)]
    guard_s, reference_s, held_steps = [], [], 0
    for step in range(rounds):
        if step % 100 == 0:
            targets = p[rng.permutation(K)]
        start = time.perf_counter()
        wanted = waypoint_velocity(p, targets, dt_s, config)
        fly_step(p, v, wanted, dt_s, config, area)
        reference_s.append(time.perf_counter() - start)
        start = time.perf_counter()
        command, held = guard_commands(p, v, wanted, dt_s, config, upper_m=area)
        guard_s.append(time.perf_counter() - start)
        held_steps += int(held.any())
        p, v = fly_step(p, v, command, dt_s, config, area)
    return guard_s, reference_s, held_steps


def _ms(seconds: list[float]) -> str:
    a = np.asarray(seconds) * 1e3
    return f"median {np.median(a):.3f} ms, p95 {np.percentile(a, 95):.3f} ms, max {a.max():.3f} ms"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    print(f"{platform.node()} {platform.processor() or platform.machine()}, load {os.getloadavg()}")
    rng = np.random.default_rng(args.seed)
    env_guard(np.random.default_rng(args.seed), 5, 30.0)  # the compiled kernel loaded before timing
    times, cpu, holds = flight_guard(rng, args.rounds)
    print(f"FlightGuard.decide, 10 vehicles, 60 m: {_ms(times)} ({holds} vehicle-decisions held); "
          f"CPU time {_ms(cpu)}")
    for side in (30.0, 60.0):
        guard_s, reference_s, held = env_guard(rng, args.rounds, side)
        print(f"guard_commands, 10 UAVs, {side:.0f} m: {_ms(guard_s)} ({held}/{args.rounds} steps with a "
              f"hold); reference step {_ms(reference_s)}; "
              f"ratio {np.median(guard_s) / np.median(reference_s):.1f}")
    print(f"load after {os.getloadavg()}")


if __name__ == "__main__":
    main()
