"""``simulate`` under the 802.11 radio, strategy 2: what the channel plan adds over one channel, in flight.

The expert planner flies ``--n-uavs`` UAVs over the same dynamic sequences (seeds ``--seeds``,
``--duration-s`` of simulated time, a replan every second) twice: with the channel plan (the band's
usable channels, one per UAV at every replan, :func:`uav_swarm.world.wifi.channels.plan_channels`) and
with every UAV on channel 36 (``[task.radio.ieee80211] channels = [36]``). Both runs place the UAVs with
the 802.11 expert, which judges its placements with the channels it may use; the crowd walks the same in
both (it does not react to the UAVs).

Printed per seed and setting: the mean QoS S2 (users with at least 5 Mbps), QoS S1, the users' mean median
SINR, the co-channel pairs sharing airtime (mean per step) and the wall time of the run; then the mean QoS S2
of each setting and their ratio (plan / one channel), with the load average before and after.

Usage: python benchmarks/radio/radio_simulate.py [--seeds 0 1 2] [--duration-s 60] [--n-uavs 10]
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

from uav_swarm.planning.planner import make_planner
from uav_swarm.runs.simulate import run_sequence
from uav_swarm.runs.simulate_config import SimulateConfig
from uav_swarm.runs.summary import summarise_run

SETTINGS = {"channel plan": {}, "one channel (36)": {"channels": [36]}}
"""``[task.radio.ieee80211]`` of each setting."""


def main() -> None:
    """Fly both settings over every seed and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="sequence seeds")
    parser.add_argument("--duration-s", type=float, default=60.0, help="simulated seconds per run")
    parser.add_argument("--n-uavs", type=int, default=10, help="UAVs flown")
    args = parser.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs; "
          f"load average before: {os.getloadavg()[0]:.2f}", flush=True)
    means: dict[str, list[float]] = {name: [] for name in SETTINGS}
    print(f"{'seed':>4s} {'setting':18s} {'QoS S2':>7s} {'QoS S1':>7s} {'SINR dB':>8s} {'pairs':>6s} "
          f"{'wall s':>7s}", flush=True)
    for seed in args.seeds:
        for name, wifi in SETTINGS.items():
            config = SimulateConfig.from_dict({
                "seed": seed, "duration_s": args.duration_s, "n_uavs": args.n_uavs, "planner": "expert",
                "compare_expert": False, "static_reference": False, "gif": False, "publish_telemetry": False,
                "replan_every": 10,
                "task": {"strategy": 2, "radio": {"propagation": "802.11", "ieee80211": wifi}}})
            planner = make_planner("expert", config.n_uavs, config.task, config=config.planning,
                                   uav_config=config.uav)
            start = time.perf_counter()
            run = run_sequence(config, planner, "expert")
            wall_s = time.perf_counter() - start
            figures = summarise_run(run, config)
            radio = figures["wifi_80211"]
            means[name].append(figures["mean_qos_s2"])
            print(f"{seed:>4d} {name:18s} {figures['mean_qos_s2']:7.3f} {figures['mean_qos_s1']:7.3f} "
                  f"{radio['median_sinr_db']:8.1f} {radio['co_channel_pairs_mean']:6.2f} {wall_s:7.1f}",
                  flush=True)
    plan, one = (float(np.mean(means[name])) for name in SETTINGS)
    print(f"\n{len(args.seeds)} sequences of {args.duration_s:g} s, {args.n_uavs} UAVs, expert planner, S2 "
          f"under 802.11: mean QoS S2 with the channel plan {plan:.3f}, on one channel {one:.3f}, ratio "
          f"{plan / one if one > 0 else float('nan'):.3f}")
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
