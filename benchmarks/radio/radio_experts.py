"""The Wi-Fi experts under the 802.11 radio: what the paper's placements lose, what a channel plan adds.

On ``--n`` held-out crowds (split ``test`` of seed ``--seed``: the Wi-Fi task's random scenes), every
placement is judged by the 802.11 model (:mod:`uav_swarm.world.wifi.coverage`: path loss, SINR, MCS,
airtime, admission on rate) with the channel plan of :func:`uav_swarm.world.wifi.channels.plan_channels`,
the UAVs ``--altitude-m`` above the users:

- strategy 2 (share of users with at least 5 Mbps): the 802.11 expert
  (:mod:`uav_swarm.missions.wifi.ieee80211_expert`), the same expert restricted to one channel (all APs on
  channel 36: what the plan adds), and the paper's two strategy-2 experts, the search expert (paper's radio,
  the paper's table) and the capacitated expert (admission control at 40 stations per UAV), whose positions
  are judged under the 802.11 radio with their own channel plan;
- strategy 1 (share with a usable rate, no admission on rate): the 802.11 expert and the paper's search
  expert.

Printed per placement: the mean QoS, its ratio to the 802.11 expert's, the UAVs used and the seconds per
crowd. The QoS is computed by the model, not by the optimisers (``evaluate_coverage``).

Usage: python benchmarks/radio/radio_experts.py [--n 30] [--seed 9] [--altitude-m 10]
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from collections.abc import Callable

import numpy as np

from learning.data import sample_seed
from uav_swarm.missions.registry import build_task
from uav_swarm.world.comms import evaluate_coverage
from uav_swarm.world.radio_config import RadioConfig
from uav_swarm.world.wifi.channels import plan_channels


def _qos(users_m: np.ndarray, uavs_m: np.ndarray, radio: RadioConfig, strategy: int) -> float:
    if len(uavs_m) == 0:
        return 0.0
    coverage = evaluate_coverage(users_m, uavs_m, radio, channels=plan_channels(uavs_m, radio))
    return coverage.qos_s1 if strategy == 1 else coverage.qos_s2


def main() -> None:
    """Run the comparison and print its table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=30, help="held-out crowds")
    parser.add_argument("--seed", type=int, default=9, help="seed of the crowds (split test)")
    parser.add_argument("--altitude-m", type=float, default=10.0, help="UAV height above the users")
    args = parser.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs; "
          f"load average before: {os.getloadavg()[0]:.2f}")
    wifi = {"propagation": "802.11", "altitude_m": args.altitude_m}
    radio_s2 = RadioConfig.from_dict(wifi)
    radio_s1 = RadioConfig.from_dict({**wifi, "ieee80211": {"rate_admission": False}})
    one_channel = RadioConfig.from_dict({**wifi, "ieee80211": {"channels": [36]}})
    tasks = {
        "802.11 expert, S2": (build_task("wifi-s2", {"radio": wifi}), radio_s2, 2),
        "802.11 expert, S2, one channel": (build_task("wifi-s2", {"radio": one_channel.to_dict()}),
                                           one_channel, 2),
        "paper search expert, S2": (build_task("wifi-s2", {"expert": {"method": "search"}}), radio_s2, 2),
        "paper capacitated expert, S2 (AC)": (build_task("wifi-s2", {"radio": {"station_limit": "auto"}}),
                                              radio_s2, 2),
        "802.11 expert, S1": (build_task("wifi-s1", {"radio": radio_s1.to_dict()}), radio_s1, 1),
        "paper search expert, S1": (build_task("wifi-s1", {}), radio_s1, 1),
    }
    sampler = build_task("wifi-s2", {})
    rows: dict[str, list[tuple[float, int, float]]] = {name: [] for name in tasks}
    for i in range(args.n):
        scene = sampler.sample(np.random.default_rng(sample_seed(args.seed, "test", i)))
        for name, (task, radio, strategy) in tasks.items():
            solve: Callable[[np.ndarray], np.ndarray] = task.expert_placement_m
            start = time.perf_counter()
            uavs_m = solve(scene.users_m)
            spent_s = time.perf_counter() - start
            judge = one_channel if "one channel" in name else radio
            rows[name].append((_qos(scene.users_m, uavs_m, judge, strategy), len(uavs_m), spent_s))
        print(f"crowd {i + 1}/{args.n} ({len(scene.users_m)} users) done", flush=True)
    reference = {2: float(np.mean([r[0] for r in rows["802.11 expert, S2"]])),
                 1: float(np.mean([r[0] for r in rows["802.11 expert, S1"]]))}
    print(f"\n{args.n} held-out crowds (seed {args.seed}, split test), UAVs {args.altitude_m:g} m above the "
          "users; QoS judged by the 802.11 model with each placement's channel plan")
    print(f"{'placement':38s} {'QoS':>7s} {'/ 802.11 expert':>16s} {'UAVs':>6s} {'s/crowd':>8s}")
    for name, (_, _, strategy) in tasks.items():
        qos = np.array([r[0] for r in rows[name]])
        uavs = np.array([r[1] for r in rows[name]])
        seconds = np.array([r[2] for r in rows[name]])
        print(f"{name:38s} {qos.mean():7.3f} {qos.mean() / reference[strategy]:16.3f} {uavs.mean():6.2f} "
              f"{seconds.mean():8.2f}")
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
