"""What ``simulate --ros2`` costs: wall time of one run with ROS 2 (subscribed or not) and without ROS 2.

The default sequence (``SimulateConfig()``: 10 UAVs, seed 0, the learned planner with the shipped
checkpoint, replanning every 10 steps, every step published) for ``--duration-s`` simulated seconds,
``--rounds`` times each of three kinds, interleaved (without ROS 2, with ROS 2 and nobody subscribed,
with ROS 2 and a subscriber; so that a changing machine load hits all alike), as fast as it computes.
``--scope loop`` times the flown planner's loop alone (the run's node opened beforehand); ``--scope
command`` times the whole job as ``uav-swarm simulate [--ros2]`` runs it (both planners, the static
reference, the pictures, Zenoh telemetry on a free loopback port, the ROS 2 node's start and its wait for
the subscriber), writing into a temporary folder. The subscriber is a separate process on this machine
only, in a ROS domain of its own, that takes what a viewer takes (the swarm's ``poses``, the targets, the
plans, the QoS, the markers, the crowd, the scene, ``/clock``; ``--per-uav-poses`` adds every UAV's own
``pose`` topic) and counts what it received; the run without a subscriber is in another domain, where
nobody listens. Printed: the machine and ``/proc/loadavg`` before and after, the median wall time of each
kind, the ratios (goals <= 1.10 with a subscriber, <= 1.05 without), the same ratios of the run process's
CPU time (its own work, which other load on the machine does not change) and the messages the subscriber
received per round.

Usage: python benchmarks/bridge/ros2_cost.py [--scope loop|command] [--duration-s 60] [--rounds 5]
       [--domain-id 77]
    [--per-uav-poses]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import socket
import subprocess
import sys
import tempfile
import time
from contextlib import ExitStack
from pathlib import Path

import numpy as np

from uav_swarm.runs.outputs.ros2.config import Ros2Config, ros2_environment

_NAMESPACE = "/uav_swarm/benchmark"


def _subscriber(n_uavs: int, per_uav_poses: bool) -> None:
    """The subscriber process: every topic, until the run's poses have no publisher left; prints counts."""
    ros2_environment(Ros2Config())
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import PoseArray, PoseStamped
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import PointCloud2
    from visualization_msgs.msg import MarkerArray

    best_effort = QoSProfile(depth=100, reliability=ReliabilityPolicy.BEST_EFFORT)
    reliable = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    counts: dict[str, int] = {}

    def count(topic: str):
        return lambda _: counts.__setitem__(topic, counts.get(topic, 0) + 1)

    rclpy.init()
    node = rclpy.create_node("ros2_cost_subscriber")
    topics = [(PoseArray, "poses", best_effort)]
    topics += [(PoseStamped, f"uav_{i}/pose", best_effort) for i in range(n_uavs) if per_uav_poses]
    topics += [(PoseStamped, f"uav_{i}/target", latched) for i in range(n_uavs)]
    topics += [(PoseArray, "plan", reliable), (DiagnosticArray, "plan/info", reliable),
               (DiagnosticArray, "qos", reliable), (MarkerArray, "markers", reliable),
               (PointCloud2, "crowd", reliable),
               (MarkerArray, "scene", latched)]
    for kind, topic, qos in topics:
        node.create_subscription(kind, f"{_NAMESPACE}/{topic}", count(topic), qos)
    node.create_subscription(Clock, "/clock", count("/clock"), best_effort)
    print("ready", flush=True)
    for line in sys.stdin:  # one line per round from the benchmark: "go", then "end"
        if line.strip() == "end":
            break
        counts.clear()
        seen = False  # the run's poses publisher in the graph (it shows there after its first data)
        while True:
            rclpy.spin_once(node, timeout_sec=0.05)
            publishers = node.count_publishers(f"{_NAMESPACE}/poses")
            seen = seen or (publishers > 0 and counts.get("poses", 0) > 0)
            if seen and publishers == 0:
                break
        print(json.dumps(counts), flush=True)
    node.destroy_node()
    rclpy.shutdown()


def _round(config, planner, kind: str, subscriber: subprocess.Popen, scope: str, domain_id: int
           ) -> tuple[float, float, dict]:
    """One run of ``kind`` (``plain``, ``unsubscribed``, ``subscribed``): wall time, CPU time, messages.

    The CPU time is this process's (every thread: the loop, the ROS 2 executor, DDS); the messages are what
    the subscriber received.
    """
    from uav_swarm.runs.outputs.fanout import RunOutputs
    from uav_swarm.runs.outputs.ros2 import open_run_node
    from uav_swarm.runs.simulate import run_sequence, simulate

    with_ros, subscribed = kind != "plain", kind == "subscribed"
    os.environ["ROS_DOMAIN_ID"] = str(domain_id if subscribed else domain_id + 1)  # + 1: nobody listens
    ros2 = config.ros2.replace(enabled=with_ros, wait_for_subscriber_s=120.0 if subscribed else 0.0)
    config = config.replace(ros2=ros2)
    if subscribed:
        subscriber.stdin.write("go\n")
        subscriber.stdin.flush()
    if scope == "command":
        with tempfile.TemporaryDirectory() as folder:
            start_s, start_cpu_s = time.perf_counter(), time.process_time()
            simulate(config, folder, progress=False)
            wall_s, cpu_s = time.perf_counter() - start_s, time.process_time() - start_cpu_s
        return wall_s, cpu_s, json.loads(subscriber.stdout.readline()) if subscribed else {}
    with ExitStack() as stack:
        outputs = steering = None
        if with_ros:
            ros, steering = open_run_node(config.ros2, stack, swarm=config.telemetry.swarm,
                                          n_uavs=config.n_uavs, command="simulate", sim_time=True,
                                          task=config.task, uav=config.uav, geofence=None)
            outputs = RunOutputs(ros=ros)
        start_s, start_cpu_s = time.perf_counter(), time.process_time()
        run_sequence(config, planner, "learned", outputs=outputs, steering=steering)
        wall_s, cpu_s = time.perf_counter() - start_s, time.process_time() - start_cpu_s
    counts = json.loads(subscriber.stdout.readline()) if subscribed else {}
    return wall_s, cpu_s, counts


def main() -> None:
    """Run the comparison and print it."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scope", choices=("loop", "command"), default="loop",
                        help="time the flown loop or the whole simulate job (default: %(default)s)")
    parser.add_argument("--duration-s", type=float, default=60.0, help="simulated seconds per run")
    parser.add_argument("--rounds", type=int, default=5, help="runs of each kind")
    parser.add_argument("--domain-id", type=int, default=77,
                        help="ROS_DOMAIN_ID of the run and its subscriber")
    parser.add_argument("--per-uav-poses", action="store_true",
                        help="the subscriber also takes every UAV's own pose topic")
    parser.add_argument("--subscriber", type=int, metavar="N_UAVS", help=argparse.SUPPRESS)
    args = parser.parse_args()
    os.environ["ROS_DOMAIN_ID"] = str(args.domain_id)
    if args.subscriber is not None:
        _subscriber(args.subscriber, args.per_uav_poses)
        return
    from uav_swarm.planning.planner import make_planner
    from uav_swarm.runs.simulate_config import SimulateConfig

    with socket.socket() as probe:  # Zenoh telemetry of the command scope: a free loopback port
        probe.bind(("127.0.0.1", 0))
        endpoint = f"tcp/127.0.0.1:{probe.getsockname()[1]}"
    config = SimulateConfig.from_dict({"duration_s": args.duration_s,
                                       "telemetry": {"listen": [endpoint], "swarm": "benchmark"},
                                       "ros2": {"enabled": True, "wait_for_subscriber_s": 120.0}})
    planner = make_planner("learned", config.n_uavs, config.task, config=config.planning)
    load_before = Path("/proc/loadavg").read_text().strip()
    command = [sys.executable, __file__, "--subscriber", str(config.n_uavs), "--domain-id",
               str(args.domain_id)]
    subscriber = subprocess.Popen(command + (["--per-uav-poses"] if args.per_uav_poses else []),
                                  stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    assert subscriber.stdout.readline().strip() == "ready"
    kinds = ("plain", "unsubscribed", "subscribed")
    wall_s: dict[str, list[float]] = {kind: [] for kind in kinds}
    cpu_s: dict[str, list[float]] = {kind: [] for kind in kinds}
    received = []
    try:
        _round(config, planner, "plain", subscriber, "loop", args.domain_id)  # warm-up: the first calls
        for _ in range(args.rounds):
            for kind in kinds:
                seconds, cpu, counts = _round(config, planner, kind, subscriber, args.scope, args.domain_id)
                wall_s[kind].append(seconds)
                cpu_s[kind].append(cpu)
                if kind == "subscribed":
                    received.append(sum(counts.values()))
    finally:
        subscriber.stdin.write("end\n")
        subscriber.stdin.flush()
        subscriber.wait(timeout=60)
    median = {kind: float(np.median(times)) for kind, times in wall_s.items()}
    cpu = {kind: float(np.median(times)) for kind, times in cpu_s.items()}
    load_after = Path("/proc/loadavg").read_text().strip()
    print(f"python {platform.python_version()}, {platform.machine()}, {os.cpu_count()} CPUs; /proc/loadavg "
          f"before {load_before}, after {load_after}")
    print(f"scope {args.scope}: {config.n_uavs} UAVs, {args.duration_s:g} s simulated ({config.n_steps} "
          f"steps, every one published), {args.rounds} rounds interleaved, ROS_DOMAIN_ID {args.domain_id}, "
          f"loopback only; the subscriber takes {'every UAV pose, ' if args.per_uav_poses else ''}poses, "
          "targets, plans, QoS, markers, crowd, scene, /clock")
    labels = {"plain": "without ROS 2", "unsubscribed": "with ROS 2, nobody subscribed",
              "subscribed": "with ROS 2, subscribed"}
    for kind in kinds:
        runs = ", ".join(f"{t:.2f}" for t in wall_s[kind])
        print(f"{labels[kind]:<30}: {median[kind]:6.2f} s (median; runs {runs}); CPU time of the run's "
              f"process {cpu[kind]:.2f} s")
    print(f"ratio, subscribed         : {median['subscribed'] / median['plain']:.3f} (goal <= 1.10); the "
          f"subscriber received {', '.join(map(str, received))} messages per round")
    print(f"ratio, nobody subscribed  : {median['unsubscribed'] / median['plain']:.3f} (goal <= 1.05)")
    print(f"CPU time ratios           : subscribed {cpu['subscribed'] / cpu['plain']:.3f}, nobody subscribed "
          f"{cpu['unsubscribed'] / cpu['plain']:.3f} (the run's own work, whatever else loads the machine)")


if __name__ == "__main__":
    main()
