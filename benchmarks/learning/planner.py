"""Replan latency of the learned planner in motion, against the expert, one world and 64 at a time.

What ``uav-swarm simulate`` does between two environment steps, on ``--n`` held-out Wi-Fi scenes
(``WifiTask.sample`` on the "test" split's seeds, several hundred pedestrians walking with their
velocities), 10 UAVs. Each scene is a short sequence: ``--repeats`` replans one second apart (the crowd
walks on, the UAVs fly halfway to their targets), so planning in motion (the default mode) follows,
keeps and re-judges as it does in flight. Rows, all in one process (ratios in one run):

- **S1 learned**: the shipped strategy-1 network on the engine chosen at load (every candidate's batch-1
  time printed), peaks, planning in motion; the stages' medians; the expert (optimiser + the same
  motion planning) on the first replan of each scene, and expert / learned. For reference, the same
  planner in eager bfloat16 (not exact), and on two threads (``--threads 1`` only).
- **S2 learned + refined**: the shipped strategy-2 network with the refinement on the live crowd.
- **S2 802.11 learned**: strategy 2 under the 802.11 radio as ``configs/simulate/wifi-s2-80211.toml`` flies
  it: the shipped ``wifi-s2-80211`` network, peaks, planning in motion, then the channel plan of the
  targets (:func:`uav_swarm.world.wifi.channels.plan_channels`, the plan in force kept while valid), timed
  together as one replan (wall time, and the process's CPU time: on a loaded machine the wall time waits
  for the CPU), with each stage's median. Its static QoS: on the first instant of each scene the
  network's peaks and the 802.11 expert's placement, each judged by the 802.11 model with its channel plan
  (``WifiTask.qos``), learned / expert over the scenes.
- **Batch 64**: 64 worlds replanned by one :func:`uav_swarm.planning.batch.plan_batch` call against
  64 single plans of the same worlds, ``--rounds`` rounds (each world's own sequence state).

Goals: S1 learned p50 <= 2 ms, p95 <= 4 ms; expert / learned >= 50x; S2 learned + refined
p50 <= 15 ms; S2 802.11 learned replan (channel plan included) p95 <= 20 ms, its network stage p50 <= 2 ms,
its static QoS S2 >= 95 % of the expert's; batch-64 throughput >= 10x that of 64 single plans.

Usage: python benchmarks/learning/planner.py [--n 30] [--repeats 5] [--threads 1] [--rounds 3]
       [--rows s1 s2 s2-80211 batch]
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np
import torch

from learning.data import sample_seed
from learning.peaks import find_peaks
from learning.precision import BF16_CPU_FLAGS, cpu_flags
from uav_swarm.missions.wifi.task import WifiConfig, WifiScene, WifiTask, crowd_raster
from uav_swarm.planning.batch import plan_batch
from uav_swarm.planning.planner import ExpertPlanner, LearnedPlanner, PlannerConfig
from uav_swarm.world.radio_config import RadioConfig
from uav_swarm.world.wifi.channels import plan_channels

N_UAVS = 10
GOALS = {"p50": 2.0, "p95": 4.0, "ratio": 50.0, "s2": 15.0, "batch": 10.0, "s2_80211_p95": 20.0,
         "network_p50": 2.0, "qos": 0.95}
ALT_M = 10.0
"""The UAVs' height above the users, metres (``[uav] alt_m``, the 802.11 task's ``altitude_m``)."""
WIFI_80211 = RadioConfig(propagation="802.11", altitude_m=ALT_M)


def scenes(strategy: int, n: int, seed: int, task_config: WifiConfig | None = None
           ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """``n`` held-out scenes: pedestrians, their velocities and random UAV positions."""
    task = WifiTask(task_config or WifiConfig(strategy=strategy))
    out = []
    for i in range(n):
        rng = np.random.default_rng(sample_seed(seed, "test", i))
        scene = task.sample(rng)
        out.append((scene.users_m.copy(), scene.velocities_m_s.copy(), rng.uniform(0.0, 200.0, (N_UAVS, 2))))
    return out


def sequence(planner, scene, repeats: int) -> list:
    """``repeats`` replans of one scene, one second apart; the plan results."""
    peds, vels, uavs = scene
    planner.reset()
    results = []
    for _ in range(repeats):
        result = planner.plan(peds, uavs, vels)
        results.append(result)
        peds, uavs = peds + vels, (uavs + result.targets_m) / 2.0
    return results


def stats(values_ms: list[float]) -> str:
    a = np.asarray(values_ms)
    return f"p50 {np.median(a):8.3f} ms   p95 {np.percentile(a, 95):8.3f} ms   max {a.max():8.3f} ms"


def verdict(ok: bool | np.bool_) -> str:
    return "meets" if ok else "MISSES"


def stages(planner: LearnedPlanner, scene) -> dict[str, float]:
    """Milliseconds of each stage of one replan (outside the planner's own timing)."""
    peds, vels, uavs = scene
    t0 = time.perf_counter()
    raster = crowd_raster(peds, planner.task.config, vels)
    t1 = time.perf_counter()
    utility = planner.utility_map(raster)
    t2 = time.perf_counter()
    peaks = planner.task.to_metres(find_peaks(utility, planner.peak_config, max_peaks=N_UAVS))
    t3 = time.perf_counter()
    planner.motion.plan(peds, vels, uavs, peaks)
    t4 = time.perf_counter()
    return {"raster": t1 - t0, "network": t2 - t1, "peaks": t3 - t2, "motion": t4 - t3}


def single_s1(args: argparse.Namespace, config: PlannerConfig) -> tuple[LearnedPlanner, float]:
    """The S1 rows; returns the planner and its p50."""
    learned = LearnedPlanner(N_UAVS, config=config)
    expert = ExpertPlanner(N_UAVS, config=config)
    choice = learned.engine_choice
    timings = ", ".join(f"{k} {v:.2f} ms" for k, v in choice.timings_ms.items())
    skipped = "; ".join(f"{k}: {v}" for k, v in choice.skipped.items()) or "none"
    print(f"S1 engine chosen at load: {choice.name} (batch-1 medians: {timings}; skipped: {skipped})")
    s1 = scenes(1, args.n, args.seed)
    for scene in s1[:2]:  # warm-up
        sequence(learned, scene, 2)
    learned_ms: list[float] = []
    expert_ms: list[float] = []
    parts: dict[str, list[float]] = {}
    for scene in s1:
        learned_ms += [r.latency_ms for r in sequence(learned, scene, args.repeats)]
        for name, seconds in stages(learned, scene).items():
            parts.setdefault(name, []).append(seconds * 1e3)
        expert_ms.append(sequence(expert, scene, 1)[0].latency_ms)
    peds = [len(s[0]) for s in s1]
    p50, p95 = np.median(learned_ms), np.percentile(learned_ms, 95)
    print(f"{args.n} held-out S1 scenes ({min(peds)}-{max(peds)} pedestrians), {N_UAVS} UAVs, "
          f"{args.repeats} replans each, planning in motion")
    print(f"S1 expert (optimiser + motion)             : {stats(expert_ms)}")
    print(f"S1 learned ({choice.name:<11} + peaks + motion): {stats(learned_ms)}   (goal p50 <= "
          f"{GOALS['p50']:.0f}, p95 <= {GOALS['p95']:.0f} ms: "
          f"{verdict(p50 <= GOALS['p50'] and p95 <= GOALS['p95'])})")
    print("  stages (median ms): " + ", ".join(f"{k} {np.median(v):.3f}" for k, v in parts.items()))
    ratio = np.median(expert_ms) / p50
    print(f"  expert / learned median = {ratio:6.1f}x   (goal >= {GOALS['ratio']:.0f}x: "
          f"{verdict(ratio >= GOALS['ratio'])})")
    bf16 = LearnedPlanner(N_UAVS, config=config.replace(precision="bfloat16"))
    for scene in s1[:2]:
        sequence(bf16, scene, 2)
    bf16_ms = [r.latency_ms for scene in s1 for r in sequence(bf16, scene, args.repeats)]
    print(f"S1 learned, eager bfloat16 (not exact; for reference)   : {stats(bf16_ms)}")
    if args.threads == 1:  # the developers' CPU has two cores: the same planner on both
        two = LearnedPlanner(N_UAVS, config=config.replace(torch_threads=2))
        for scene in s1[:2]:
            sequence(two, scene, 2)
        two_ms = [r.latency_ms for scene in s1 for r in sequence(two, scene, args.repeats)]
        torch.set_num_threads(args.threads)
        ratio_two = np.median(expert_ms) / np.median(two_ms)
        print(f"S1 learned on 2 threads ({two.engine}; {two.engine_choice.timings_ms[two.engine]:.2f} ms "
              f"at load)    : {stats(two_ms)}   (expert / learned {ratio_two:.1f}x)")
    return learned, float(p50)


def refined_s2(args: argparse.Namespace, config: PlannerConfig) -> None:
    """The S2 learned + refined row."""
    planner = LearnedPlanner(N_UAVS, WifiConfig(strategy=2), config=config.replace(refine=True))
    s2 = scenes(2, args.n, args.seed)
    for scene in s2[:2]:
        sequence(planner, scene, 2)
    values = [r.latency_ms for scene in s2 for r in sequence(planner, scene, args.repeats)]
    peds = [len(s[0]) for s in s2]
    print(f"S2 learned + refined ({planner.engine}; {min(peds)}-{max(peds)} pedestrians): {stats(values)}   "
          f"(goal p50 <= {GOALS['s2']:.0f} ms: {verdict(np.median(values) <= GOALS['s2'])})")


def s2_80211(args: argparse.Namespace, config: PlannerConfig) -> None:
    """The S2 802.11 learned row: replans with their channel plan, the stages, the static QoS."""
    task_config = WifiConfig(strategy=2, radio=WIFI_80211)
    planner = LearnedPlanner(N_UAVS, task_config, config=config)
    task = WifiTask(task_config)
    altitudes = np.full(N_UAVS, ALT_M)
    worlds = scenes(2, args.n, args.seed, task_config)
    timings = ", ".join(f"{k} {v:.2f} ms" for k, v in planner.engine_choice.timings_ms.items())
    print(f"S2 802.11 engine chosen at load: {planner.engine} (batch-1 medians: {timings})")
    for world in worlds[:2]:  # warm-up
        sequence(planner, world, 2)
    replan_ms: list[float] = []
    cpu_ms: list[float] = []
    parts: dict[str, list[float]] = {}
    for peds, vels, uavs in worlds:
        planner.reset()
        channels = None
        for _ in range(args.repeats):
            start, cpu = time.perf_counter(), time.process_time()
            result = planner.plan(peds, uavs, vels)
            channels = plan_channels(result.targets_m, WIFI_80211, altitudes, channels)
            replan_ms.append((time.perf_counter() - start) * 1e3)
            cpu_ms.append((time.process_time() - cpu) * 1e3)
            parts.setdefault("channels", []).append((time.perf_counter() - start) * 1e3 - result.latency_ms)
            peds, uavs = peds + vels, (uavs + result.targets_m) / 2.0
        for name, seconds in stages(planner, (peds, vels, uavs)).items():
            parts.setdefault(name, []).append(seconds * 1e3)
    peds_n = [len(w[0]) for w in worlds]
    p95, network = float(np.percentile(replan_ms, 95)), float(np.median(parts["network"]))
    print(f"{args.n} held-out S2 scenes under 802.11 ({min(peds_n)}-{max(peds_n)} pedestrians), {N_UAVS} "
          f"UAVs, {args.repeats} replans each, planning in motion, load average {_load()}")
    print(f"S2 802.11 learned ({planner.engine} + peaks + motion + channel plan): {stats(replan_ms)}   "
          f"(goal p95 <= {GOALS['s2_80211_p95']:.0f} ms: {verdict(p95 <= GOALS['s2_80211_p95'])})")
    print(f"  the same replans in the process's CPU time (the wait for a loaded machine's CPU is not "
          f"in it): {stats(cpu_ms)}")
    goal = GOALS["network_p50"]
    print("  stages (median ms): " + ", ".join(f"{k} {np.median(v):.3f}" for k, v in parts.items())
          + f"   (network goal p50 <= {goal:.0f} ms: {verdict(network <= goal)})")
    learned_qos, expert_qos, expert_s = [], [], []
    for peds, vels, _ in worlds:
        scene = WifiScene(peds, 0.0, vels)
        peaks_m = planner.propose(peds, vels)[0]
        learned_qos.append(task.qos(scene, task.to_pixels(peaks_m))["qos"])
        start = time.perf_counter()
        expert_m = task.expert_placement_m(peds, vels)
        expert_s.append(time.perf_counter() - start)
        expert_qos.append(task.qos(scene, task.to_pixels(expert_m))["qos"])
    ratio = float(np.mean(learned_qos) / np.mean(expert_qos))
    print(f"  static QoS S2 on the {args.n} scenes: learned peaks {np.mean(learned_qos):.3f}, 802.11 expert "
          f"{np.mean(expert_qos):.3f} ({np.median(expert_s):.2f} s median), learned / expert {ratio:.3f}   "
          f"(goal >= {GOALS['qos']:.2f}: {verdict(ratio >= GOALS['qos'])}); load average {_load()}")


def _load() -> str:
    return ", ".join(f"{v:.2f}" for v in os.getloadavg())


def batched(args: argparse.Namespace, learned: LearnedPlanner) -> None:
    """64 worlds: one plan_batch call against 64 single plans, ``--rounds`` rounds."""
    worlds = scenes(1, 64, args.seed + 1)
    together = [learned.fork() for _ in worlds]
    alone = [learned.fork() for _ in worlds]
    peds = [w[0] for w in worlds]
    vels = [w[1] for w in worlds]
    uavs = [w[2] for w in worlds]
    plan_batch(together[:2], peds[:2], uavs[:2], vels[:2])  # warm-up of the batch shapes
    for p in together[:2]:
        p.reset()
    batch_s, single_s = [], []
    for _ in range(args.rounds):
        start = time.perf_counter()
        results = plan_batch(together, peds, uavs, vels)
        batch_s.append(time.perf_counter() - start)
        start = time.perf_counter()
        for p, c, u, v in zip(alone, peds, uavs, vels, strict=True):
            p.plan(c, u, v)
        single_s.append(time.perf_counter() - start)
        peds = [c + v for c, v in zip(peds, vels, strict=True)]
        uavs = [(u + r.targets_m) / 2.0 for u, r in zip(uavs, results, strict=True)]
    batch_ms, single_ms = 1e3 * float(np.median(batch_s)), 1e3 * float(np.median(single_s))
    ratio = single_ms / batch_ms
    print(f"batch of 64 worlds ({learned.engine}): one plan_batch {batch_ms:8.1f} ms ({batch_ms / 64:.2f} ms "
          f"per world), 64 single plans {single_ms:8.1f} ms ({single_ms / 64:.2f} ms per world), median of "
          f"{args.rounds} rounds")
    print(f"  throughput batch / single = {ratio:5.2f}x   (goal >= {GOALS['batch']:.0f}x: "
          f"{verdict(ratio >= GOALS['batch'])})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=30, help="held-out scenes")
    parser.add_argument("--repeats", type=int, default=5, help="replans per scene (one second apart)")
    parser.add_argument("--rounds", type=int, default=3, help="rounds of the 64-world batch")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=1, help="PlannerConfig.torch_threads")
    parser.add_argument("--rows", nargs="+", choices=["s1", "s2", "s2-80211", "batch"],
                        default=["s1", "s2", "s2-80211", "batch"], help="the rows measured")
    args = parser.parse_args()
    config = PlannerConfig(torch_threads=args.threads)
    flags = ", ".join(sorted(BF16_CPU_FLAGS & cpu_flags())) or "none"
    print(f"python {platform.python_version()}, torch {torch.__version__}, {platform.machine()}, "
          f"{args.threads} inference thread(s); bfloat16 CPU flags: {flags}")
    if "s1" in args.rows or "batch" in args.rows:
        learned, _ = single_s1(args, config)
        if "batch" in args.rows:
            batched(args, learned)
    if "s2" in args.rows:
        refined_s2(args, config)
    if "s2-80211" in args.rows:
        s2_80211(args, config)


if __name__ == "__main__":
    main()
