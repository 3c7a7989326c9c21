"""Env-steps per second of uav_swarm_v0 against MPE2's simple_spread_v3 (N = 10), in one run.

uav_swarm_v0 runs with 10 UAVs and crowds of 200 and 1,000 pedestrians (render off,
velocity actions drawn uniformly in the action box, one crowd step per env step);
simple_spread_v3 with N = 10 agents (parallel API, continuous actions). The three
environments are measured in interleaved rounds, so a machine whose load changes
during the run affects them alike. Goal: ratio >= 3 with 200 pedestrians and >= 1 with 1,000.

Usage: python benchmarks/env/env_step.py [--seconds S] [--rounds R]
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np
from mpe2 import simple_spread_v3

from uav_swarm.env.parallel import parallel_env


def crowd_of(n_pedestrians: int) -> dict:
    """Scenario settings that give exactly ``n_pedestrians`` in 10 groups."""
    size = n_pedestrians // 10
    return {"n_groups_min": 10, "n_groups_max": 10, "group_size_min": size, "group_size_max": size}


class Runner:
    """Steps one parallel env with pre-drawn random actions and counts steps and time."""

    def __init__(self, par_env, seed: int = 0) -> None:
        self.env = par_env
        par_env.reset(seed=seed)
        rng = np.random.default_rng(seed)
        agents = list(par_env.possible_agents)
        spaces = [par_env.action_space(a) for a in agents]

        def draw(space):
            return (space.low + rng.random(space.shape) * (space.high - space.low)).astype(space.dtype)

        self.actions = [{a: draw(s) for a, s in zip(agents, spaces, strict=True)} for _ in range(64)]
        self.steps, self.seconds = 0, 0.0
        self.run(0.2)  # warm-up, not counted
        self.steps, self.seconds = 0, 0.0

    def run(self, seconds: float) -> None:
        """Step for about ``seconds``; reset when the episode ends."""
        steps, start = 0, time.perf_counter()
        while steps % 20 or time.perf_counter() - start < seconds:
            if not self.env.agents:
                self.env.reset()
            self.env.step(self.actions[steps % 64])
            steps += 1
        self.steps += steps
        self.seconds += time.perf_counter() - start

    @property
    def rate(self) -> float:
        """Env-steps per second so far."""
        return self.steps / self.seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=6.0, help="measuring time per environment")
    parser.add_argument("--rounds", type=int, default=12, help="interleaved rounds")
    args = parser.parse_args()
    print(f"python {platform.python_version()}, numpy {np.__version__}, {platform.machine()}")
    runners = {"mpe2": Runner(simple_spread_v3.parallel_env(N=10, max_cycles=10**9, continuous_actions=True))}
    for n_peds in (200, 1000):
        runners[n_peds] = Runner(parallel_env(n_uavs=10, max_cycles=10**6, scenario=crowd_of(n_peds)))
        assert runners[n_peds].env.coverage.covered.shape[0] == n_peds
    for _ in range(args.rounds):
        for runner in runners.values():
            runner.run(args.seconds / args.rounds)
    mpe = runners["mpe2"].rate
    print(f"mpe2 simple_spread_v3 N=10            : {mpe:7.0f} env-steps/s")
    for n_peds, goal in ((200, 3.0), (1000, 1.0)):
        ours = runners[n_peds].rate
        verdict = "meets" if ours / mpe >= goal else "MISSES"
        print(f"uav_swarm_v0 10 UAVs, {n_peds:4d} pedestrians: {ours:7.0f} env-steps/s, "
              f"ratio {ours / mpe:5.2f}x (goal >= {goal:.0f}x: {verdict})")


if __name__ == "__main__":
    main()
