"""What the minimum separation costs the static placements: QoS with ``min_separation_m`` against without.

On ``--n`` held-out crowds (split ``test`` of seed ``--seed``; the shipped checkpoints were trained on
seed 1 and evaluated on seeds 2, 3 and 5, so the default seed 9 is new to every one of them), each
placement is solved twice, with the UAVs' minimum separation (``--min-separation-m``, default 5 m, the
shipped ``[uav] min_separation_m``) and without (0), and judged by the task's QoS on the same crowd:

- strategy 1: the learned planner's proposal (``wifi-s1.pt``: network, peaks) and the search expert;
- strategy 2 under admission control: the capacitated expert and the learned planner refined on the crowd
  (``wifi-s2-ac.pt``: network, peaks, the strategy's refinement), what ``simulate`` flies.

The learned rows go through :meth:`uav_swarm.planning.planner.LearnedPlanner.propose` (the product's
path, eager float32, one torch thread), the experts through
:meth:`uav_swarm.missions.wifi.task.WifiTask.expert_placement_m`. Printed per placement: mean QoS without
and with the minimum, the relative cost ``1 - with / without`` (goal: <= 1 %), the crowds where the
unconstrained placement had a pair closer than the minimum, the closest pair with the minimum (pdist,
independent of the optimisers) and the seconds per crowd.

The planners in motion add a projection (:func:`uav_swarm.planning.spacing.separate_targets`: followers
that drifted together, proposals aimed where their users walk, spares). With ``--sequences K`` it is
measured too: ``K`` held-out crowds per strategy walk ``--replans`` seconds, the learned planner replans in
motion every second (the UAVs fly toward their targets at most ``max_speed_m_s`` per second), and each
replan's horizon QoS with the projected targets is compared with the targets before the projection.

Usage: python benchmarks/flight/separation_cost.py [--n 300] [--seed 9] [--min-separation-m 5]
       [--sequences 20]
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time

import numpy as np
import torch
from scipy.spatial.distance import pdist

from learning.data import sample_seed
from uav_swarm.missions.wifi.task import WifiConfig, WifiTask
from uav_swarm.planning.planner import PlannerConfig, make_planner
from uav_swarm.world.comms import RadioConfig
from uav_swarm.world.crowd import CrowdSim
from uav_swarm.world.scenario import random_scenario
from uav_swarm.world.uav import UAVConfig

STRATEGIES = {
    "s1": WifiConfig(strategy=1),
    "s2-ac": WifiConfig(strategy=2, radio=RadioConfig(station_limit="auto")),
}
"""The tasks, as ``simulate`` builds them (strategy 2 under admission control)."""


def _placers(task_config: WifiConfig, minimum_m: float, refine: bool) -> dict[str, object]:
    """The placements of one strategy at one minimum: ``name -> f(users, velocities) -> (k, 2) metres``."""
    task_config = task_config.replace(min_separation_m=minimum_m)
    expert = WifiTask(task_config)
    planner = make_planner("learned", n_uavs=10, task_config=task_config,
                           config=PlannerConfig(mode="snapshot", refine=refine, engine="torch-eager"),
                           uav_config=UAVConfig(min_separation_m=minimum_m))
    learned = "learned + refinement" if refine else "learned"
    return {learned: lambda users, vels: planner.propose(users, vels)[0],
            "expert": expert.expert_placement_m}


def _closest(placement: np.ndarray) -> float:
    return float(pdist(placement).min()) if len(placement) > 1 else np.inf


def run(strategy: str, n: int, seed: int, minimum_m: float, progress: int = 0) -> list[dict[str, float]]:
    """One row per placement of ``strategy`` (module docstring); running means every ``progress`` crowds."""
    config = STRATEGIES[strategy]
    refine = strategy != "s1"
    task = WifiTask(config)
    without, with_min = _placers(config, 0.0, refine), _placers(config, minimum_m, refine)
    rows = {name: {"qos0": [], "qos": [], "pulled": 0, "closest": np.inf, "seconds": 0.0} for name in without}
    for i in range(n):
        scene = task.sample(np.random.default_rng(sample_seed(seed, "test", i)))
        users, vels = np.asarray(scene.users_m), np.asarray(scene.velocities_m_s)
        for name, row in rows.items():
            loose = without[name](users, vels)
            start = time.perf_counter()
            kept = with_min[name](users, vels)
            row["seconds"] += time.perf_counter() - start
            row["qos0"].append(task.qos(scene, task.to_pixels(loose))["qos"])
            row["qos"].append(task.qos(scene, task.to_pixels(kept))["qos"])
            row["pulled"] += int(_closest(loose) < minimum_m)
            row["closest"] = min(row["closest"], _closest(kept))
        if progress and (i + 1) % progress == 0:
            print(f"{strategy}: {i + 1} crowds: " + "; ".join(
                f"{name} {100 * np.mean(r['qos0']):.2f} -> {100 * np.mean(r['qos']):.2f} %"
                for name, r in rows.items()), file=sys.stderr, flush=True)
    out = []
    for name, row in rows.items():
        qos0, qos = float(np.mean(row["qos0"])), float(np.mean(row["qos"]))
        out.append({"strategy": strategy, "placement": name, "n": n, "qos_without": qos0, "qos_with": qos,
                    "cost": 1.0 - qos / qos0 if qos0 > 0 else 0.0, "pulled": row["pulled"],
                    "closest_m": row["closest"], "seconds_per_crowd": row["seconds"] / n})
    return out


def motion(strategy: str, sequences: int, replans: int, seed: int, minimum_m: float) -> dict[str, float]:
    """What the projection of planning in motion moves and costs (module docstring)."""
    config = STRATEGIES[strategy].replace(min_separation_m=minimum_m)
    uav = UAVConfig(min_separation_m=minimum_m)
    planner = make_planner("learned", n_uavs=10, task_config=config, uav_config=uav,
                           config=PlannerConfig(mode="motion", refine=strategy != "s1", engine="torch-eager"))
    area = np.array([config.scenario.width_m, config.scenario.height_m])
    steps = round(1.0 / config.crowd.dt_s)
    qos, qos_before, shifts, moved, count = [], [], [], 0, 0
    for k in range(sequences):
        rng = np.random.default_rng(sample_seed(seed, "test", 100_000 + k))
        crowd = CrowdSim(random_scenario(rng, config.scenario), config.crowd, rng)
        crowd.step(round(rng.uniform(config.warmup_min_s, config.warmup_max_s) / config.crowd.dt_s))
        uavs = rng.uniform(0.0, area, size=(10, 2))
        planner.reset()
        for _ in range(replans):
            peds, vels = np.array(crowd.positions_m), np.array(crowd.velocities_m_s)
            plan = planner.motion.plan(peds, vels, uavs, planner.propose(peds, vels)[0])
            shift = np.linalg.norm(plan.separation_shift_m, axis=1)
            count += 1
            if np.any(shift > 1e-9):
                moved += 1
                shifts.extend(shift[shift > 1e-9].tolist())
                before = plan.targets_m - plan.separation_shift_m
                qos.append(planner.motion.horizon_qos(peds, vels, uavs, plan.targets_m))
                qos_before.append(planner.motion.horizon_qos(peds, vels, uavs, before))
            step = plan.targets_m - uavs
            reach = np.minimum(1.0, uav.max_speed_m_s / np.maximum(np.linalg.norm(step, axis=1), 1e-9))
            uavs = uavs + step * reach[:, None]
            crowd.step(steps)
    cost = 1.0 - float(np.mean(qos)) / float(np.mean(qos_before)) if qos else 0.0
    return {"replans": count, "moved": moved, "mean_shift_m": float(np.mean(shifts)) if shifts else 0.0,
            "max_shift_m": float(np.max(shifts)) if shifts else 0.0, "cost_when_moved": cost}


def main() -> None:
    """Run the benchmark and print one markdown row per placement."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n", type=int, default=300, help="held-out crowds per strategy")
    parser.add_argument("--seed", type=int, default=9, help="seed of the held-out crowds (split 'test')")
    parser.add_argument("--min-separation-m", type=float, default=UAVConfig().min_separation_m)
    parser.add_argument("--strategies", nargs="+", default=list(STRATEGIES), choices=list(STRATEGIES))
    parser.add_argument("--progress", type=int, default=50, help="running means on stderr every N crowds")
    parser.add_argument("--sequences", type=int, default=0, help="crowd sequences per strategy in motion")
    parser.add_argument("--replans", type=int, default=10, help="replans (seconds) per sequence")
    args = parser.parse_args()
    torch.set_num_threads(1)
    load = " ".join(f"{x:.2f}" for x in os.getloadavg())
    print(f"{platform.machine()}, {os.cpu_count()} CPUs, load average {load}; torch 1 thread; "
          f"{args.n} crowds per strategy (seed {args.seed}, split test); minimum {args.min_separation_m:g} m")
    print("| strategy | placement | mean QoS without | mean QoS with | cost (goal <= 1 %) "
          "| crowds pulling a pair closer | closest pair with the minimum | s per crowd (with) |")
    print("|---|---|---|---|---|---|---|---|")
    for strategy in args.strategies if args.n else []:
        for r in run(strategy, args.n, args.seed, args.min_separation_m, args.progress):
            print(f"| {r['strategy']} | {r['placement']} | {100 * r['qos_without']:.2f} % "
                  f"| {100 * r['qos_with']:.2f} % | {100 * r['cost']:.2f} % | {r['pulled']} / {r['n']} "
                  f"| {r['closest_m']:.2f} m | {r['seconds_per_crowd']:.3f} |", flush=True)
    if args.sequences:
        print("\n| strategy | replans in motion | replans the projection moved a target | mean / max shift "
              "| horizon QoS cost on those replans |\n|---|---|---|---|---|")
        for strategy in args.strategies:
            r = motion(strategy, args.sequences, args.replans, args.seed, args.min_separation_m)
            print(f"| {strategy} | {r['replans']} | {r['moved']} | {r['mean_shift_m']:.2f} / "
                  f"{r['max_shift_m']:.2f} m | {100 * r['cost_when_moved']:.2f} % |", flush=True)
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
