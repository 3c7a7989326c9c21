"""The strategy-2 experts side by side: the group expert (the default) against the search expert.

On ``--n`` held-out crowds (``test`` seed namespace of ``--seed``, a namespace no dataset uses), each
warmed up as ``WifiTask.sample`` does, both experts place up to 10 UAVs, and this script reports, with
the paper's radio model on the real pedestrians:

- static QoS S2 (share of users served with >= 5 Mbps) and its ratio group / search;
- median solve time (one process, one thread);
- held still while the crowd walks: QoS S2 after 0.5, 1 and 2 s, absolute and as a share of the
  placement's own QoS at once;
- self-agreement under 5 cm of jitter (the paper's matching rule, corr and precision, as
  ``uav-swarm expert-stability --probe jitter``).

Usage: python benchmarks/radio/wifi_s2_expert.py [--n 100] [--seed 2]
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

from learning.data import sample_seed
from learning.metrics import MATCH_FRACTION, aggregate, score_sample
from uav_swarm.missions.wifi.expert import WifiExpertConfig
from uav_swarm.missions.wifi.task import WifiConfig, WifiTask
from uav_swarm.world.comms import evaluate_coverage
from uav_swarm.world.crowd import CrowdSim
from uav_swarm.world.scenario import random_scenario

LATER_S = (0.5, 1.0, 2.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=100)
    parser.add_argument("--seed", type=int, default=2)
    args = parser.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs; "
          f"load average at start {os.getloadavg()}")
    tasks = {method: WifiTask(WifiConfig(strategy=2, expert=WifiExpertConfig(method=method)))
             for method in ("groups", "search")}
    config = tasks["groups"].config
    eps = MATCH_FRACTION * tasks["groups"].mission_dimension_px
    stats = {m: {"qos": [], "time": [], "later": {t: [] for t in LATER_S}, "scores": []} for m in tasks}
    for i in range(args.n):
        rng = np.random.default_rng(sample_seed(args.seed, "test", i))
        scenario = random_scenario(rng, config.scenario)
        crowd = CrowdSim(scenario, config.crowd, rng)
        warmup_s = float(rng.uniform(config.warmup_min_s, config.warmup_max_s))
        crowd.step(int(round(warmup_s / config.crowd.dt_s)))
        users, vels = np.array(crowd.positions_m), np.array(crowd.velocities_m_s)
        jittered = users + np.random.default_rng((args.seed, i)).normal(0.0, 0.05, users.shape)
        jittered = np.clip(jittered, 0.0, np.nextafter(config.scenario.width_m, 0.0))
        placements = {}
        for method, task in tasks.items():
            start = time.perf_counter()
            placements[method] = task.expert_placement_m(users, vels)
            stats[method]["time"].append(time.perf_counter() - start)
            stats[method]["qos"].append(evaluate_coverage(users, placements[method], config.radio).qos_s2)
            other = task.expert_placement_m(jittered, vels)
            stats[method]["scores"].append(score_sample(task.to_pixels(placements[method]),
                                                        task.to_pixels(other), eps))
        elapsed = 0.0
        for later in LATER_S:
            crowd.step(int(round((later - elapsed) / config.crowd.dt_s)))
            elapsed = later
            for method in tasks:
                qos = evaluate_coverage(np.array(crowd.positions_m), placements[method], config.radio).qos_s2
                stats[method]["later"][later].append(qos)
    print(f"{args.n} held-out crowds (seed {args.seed}, test namespace); "
          f"load average at end {os.getloadavg()}\n")
    print("| expert | QoS S2 | median solve (ms) | QoS after " + " / ".join(f"{t:g} s" for t in LATER_S)
          + " (share of its own) | jitter corr / precision |")
    print("|---|---|---|---|---|")
    for method, s in stats.items():
        qos = float(np.mean(s["qos"]))
        later = " / ".join(f"{np.mean(s['later'][t]):.1%} ({np.mean(s['later'][t]) / qos:.0%})"
                           for t in LATER_S)
        agreement = aggregate(s["scores"])
        print(f"| {method} | {qos:.1%} | {1e3 * np.median(s['time']):.0f} | {later} | "
              f"{agreement['corr']:.1%} / {agreement['precision']:.1%} |")
    ratio = np.mean(stats["groups"]["qos"]) / np.mean(stats["search"]["qos"])
    speed = np.median(stats["search"]["time"]) / np.median(stats["groups"]["time"])
    print(f"\ngroup / search: static QoS S2 {ratio:.1%}, solve speed {speed:.2f}x")


if __name__ == "__main__":
    main()
