"""``uav-swarm telemetry watch | record | ros2 | ros2-topics``: watch, record, republish a swarm's telemetry.

By default both connect to the publishing side on ``tcp/127.0.0.1:7447`` as a peer, with
multicast scouting off. ``--config FILE`` reads a ``[telemetry]`` table (the fields of
:class:`bridge.telemetry.config.TelemetryConfig`): the keys it sets override these defaults, and
command-line flags override both.
``--duration-s`` and ``--count`` bound a run (for scripts and tests); without them it runs until Ctrl-C,
its normal end (exit code 0; ``record`` writes what it received).

``ros2`` republishes the swarm on ROS 2 (the ``ros2`` extra), so that a ROS 2 machine can join a swarm
flown elsewhere: each UAV's pose, fix and target, the plans and the QoS, on the topics of ``--ros2``
(``docs/ros2.md``), stamped with the time each payload was produced; DDS stays on this machine unless
``--ros2-subnet``. ``ros2-topics`` lists a run's ROS 2 topics and their rates
(:mod:`uav_swarm.runs.outputs.ros2.rates`).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import logging
import sys
import time
from contextlib import ExitStack
from pathlib import Path
from typing import Any, TextIO

from uav_swarm.cli.conventions import number, output_flag

__all__ = ["register", "run"]


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``telemetry`` command: ``watch``, ``record``, ``ros2`` and ``ros2-topics``."""
    parser = subparsers.add_parser("telemetry", help="watch or record the swarm's Zenoh telemetry",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    actions = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    watch = actions.add_parser("watch", help="print a live table of the swarm",
                               description="Print a live table of the swarm: one row per UAV (position, "
                               "speed, battery, target), then the last plan and the last QoS.")
    watch.add_argument("--refresh-s", type=number(float, gt=0.0), default=0.5,
                       help="table refresh period, seconds")
    record = actions.add_parser("record", help="record every message to a JSON-lines file",
                                description="Record every telemetry message to a JSON-lines file (one "
                                "object per line: key, time received, payload); the file appears when "
                                "recording ends.")
    output_flag(record, "--out", "file", required=True, help="the .jsonl file to write")
    ros2 = actions.add_parser("ros2", help="republish the swarm on ROS 2 topics (needs the ros2 extra)",
                              description="Republish the swarm's states, plans and QoS on the ROS 2 topics "
                              "of --ros2 (docs/ros2.md), stamped when each payload was produced.")
    ros2.add_argument("--n-uavs", type=number(int, ge=1, le=10), default=10, metavar="N",
                      help="UAV ids 0..N-1 get topics, 1..10 (default: %(default)s)")
    ros2.add_argument("--namespace", default="",
                      help="ROS 2 namespace of the topics (default: /uav_swarm/<swarm>)")
    ros2.add_argument("--wait-for-subscriber-s", type=number(float, ge=0.0, le=600.0), default=0.0,
                      metavar="S", help="wait at most S s for a ROS 2 subscriber of the poses "
                      "(default: %(default)s)")
    ros2.add_argument("--ros2-subnet", action="store_true",
                      help="let DDS discover beyond this machine (default: this machine only)")
    topics = actions.add_parser(
        "ros2-topics", help="list a run's ROS 2 topics and their rates (needs the ros2 extra)",
        description="List the ROS 2 topics of a run (simulate --ros2, fly --ros2, telemetry ros2) with their "
        "types, and count what each delivers for --duration-s: ros2 topic list and ros2 topic hz with only "
        "the ros2 extra installed. Same ROS_DOMAIN_ID as the run; this machine only unless --ros2-subnet.")
    topics.add_argument("--swarm", default="default", help="swarm name (default: %(default)s)")
    topics.add_argument("--namespace", default="",
                        help="ROS 2 namespace of the topics (default: /uav_swarm/<swarm>)")
    topics.add_argument("--duration-s", type=number(float, gt=0.0), default=5.0, metavar="S",
                        help="count the messages for S seconds (default: %(default)s)")
    topics.add_argument("--wait-s", type=number(float, ge=0.0, le=600.0), default=10.0, metavar="S",
                        help="wait at most S s for the run's topics to appear (default: %(default)s)")
    topics.add_argument("--ros2-subnet", action="store_true",
                        help="let DDS discover beyond this machine (default: this machine only)")
    topics.set_defaults(func=_ros2_topics)
    for sub in (watch, record, ros2):
        sub.add_argument("--config", type=Path, help="TOML file with a [telemetry] table (default: none)")
        sub.add_argument("--swarm", help="swarm name (default: 'default')")
        sub.add_argument("--mode", choices=["peer", "client"], help="Zenoh session mode (default: peer)")
        sub.add_argument("--connect", action="append", metavar="ENDPOINT",
                         help="endpoint to connect to, repeatable (default: tcp/127.0.0.1:7447)")
        sub.add_argument("--listen", action="append", metavar="ENDPOINT",
                         help="endpoint to listen on, repeatable (default: none)")
        sub.add_argument("--multicast-scouting", action="store_true",
                         help="discover peers by UDP multicast (sends traffic to the network)")
        sub.add_argument("--duration-s", type=number(float, gt=0.0), metavar="S",
                         help="stop after S seconds (default: until interrupted)")
        sub.add_argument("--count", type=number(int, ge=1), metavar="N",
                         help="stop after N messages (default: until interrupted)")
        sub.set_defaults(func=run)


def _toml_table(path: Path, section: str) -> dict[str, Any]:
    from typed_config import ConfigError, read_toml

    data = read_toml(path)
    if not isinstance(data.get(section), dict):
        raise ConfigError(f"{path}: missing table [{section}]")
    return data[section]


def _config(args: argparse.Namespace) -> Any:
    """The subscriber's TelemetryConfig: watcher defaults, then the keys the TOML table sets, then flags."""
    from bridge.telemetry.config import DEFAULT_ENDPOINT, TelemetryConfig
    from typed_config import UnknownKeyError

    data: dict[str, Any] = {"listen": [], "connect": [DEFAULT_ENDPOINT]}
    if args.config is not None:
        data.update(_toml_table(args.config, "telemetry"))
    flags = {"swarm": args.swarm, "mode": args.mode, "connect": args.connect, "listen": args.listen,
             "multicast_scouting": args.multicast_scouting or None}
    data.update({key: value for key, value in flags.items() if value is not None})
    try:
        return TelemetryConfig.from_dict(data)
    except UnknownKeyError as exc:  # only the file's table has keys of its own
        raise exc.rooted(exc.root_cls, "[telemetry]", file=args.config) from None


def run(args: argparse.Namespace) -> int:
    """Subscribe and watch or record until interrupted or the bound is reached."""
    from bridge.telemetry import SwarmSubscriber
    from bridge.telemetry.config import TelemetryConnectionError
    from typed_config import ConfigError

    config = _config(args)
    bound = " or ".join(filter(None, (args.duration_s and f"for {args.duration_s:g} s",
                                      args.count and f"until {args.count} messages"))) or "until Ctrl-C"
    where = ", ".join(config.connect or config.listen)
    with ExitStack() as stack:
        try:
            ros = _ros_node(args, config.swarm, stack) if args.action == "ros2" else None
            subscriber = stack.enter_context(SwarmSubscriber(config))
        except (TelemetryConnectionError, ConfigError) as exc:
            print(f"uav-swarm telemetry: {exc}", file=sys.stderr)
            return 2
        print(f"uav-swarm telemetry {args.action}: listening for swarm {config.swarm!r} on {where} (Zenoh) "
              f"{bound}; nothing shows until a run publishes: start uav-swarm simulate or uav-swarm fly "
              "(another terminal)", file=sys.stderr, flush=True)
        if ros is not None:
            count = _republish(subscriber, ros, args)
            print(f"republished {count} messages on ROS 2 under {ros.namespace}", file=sys.stderr)
        elif args.action == "record":
            count = _record(subscriber, args.out, args)
            print(f"recorded {count} messages to {args.out}", file=sys.stderr)
        else:
            with contextlib.suppress(KeyboardInterrupt):  # Ctrl-C: the watch's normal end
                _watch(subscriber, args, sys.stdout)
    return 0


def _ros2_topics(args: argparse.Namespace) -> int:
    """Print the run's topics and their rates; 1 when no topic of the namespace is found."""
    import os

    from uav_swarm.runs.outputs.ros2 import check_ros2
    from uav_swarm.runs.outputs.ros2.config import Ros2Config

    config = Ros2Config(enabled=True, namespace=args.namespace, localhost_only=not args.ros2_subnet)
    check_ros2()
    from uav_swarm.runs.outputs.ros2.rates import format_rates, topic_rates

    namespace = config.namespace_for(args.swarm)
    rates = topic_rates(namespace, args.duration_s, config, wait_s=args.wait_s)
    if not rates:
        print(f"uav-swarm telemetry ros2-topics: no topic under {namespace} in ROS_DOMAIN_ID "
              f"{os.environ.get('ROS_DOMAIN_ID', '0')}: is a run with --ros2 going in this domain?",
              file=sys.stderr)
        return 1
    print(format_rates(rates, args.duration_s))
    return 0


def _ros_node(args: argparse.Namespace, swarm: str, stack: ExitStack) -> Any:
    """The republishing ROS 2 node, open until ``stack`` closes (ConfigError: no ros2 extra)."""
    from uav_swarm.runs.outputs.ros2 import check_ros2
    from uav_swarm.runs.outputs.ros2.config import Ros2Config

    config = Ros2Config(enabled=True, namespace=args.namespace, localhost_only=not args.ros2_subnet)
    check_ros2()
    from uav_swarm.runs.outputs.ros2.node import RunNode

    node = RunNode(config, swarm=swarm, n_uavs=args.n_uavs, node_name="uav_swarm_telemetry", sim_time=False)
    node.open()
    stack.callback(node.close)
    if args.wait_for_subscriber_s and not node.wait_for_subscriber(args.wait_for_subscriber_s):
        logging.getLogger(__name__).warning("no ROS 2 subscriber after %.1f s: republishing anyway",
                                            args.wait_for_subscriber_s)
    return node


def _republish(subscriber: Any, ros: Any, args: argparse.Namespace) -> int:
    """Each Zenoh payload on its ROS 2 topic, with the stamp it was produced at; the count republished."""
    from bridge.telemetry.schema import Plan, Qos, UavState

    count = 0
    with contextlib.suppress(KeyboardInterrupt):  # Ctrl-C: its normal end
        for item in subscriber.messages(duration_s=args.duration_s, count=args.count):
            if isinstance(item, UavState):
                ros.state(item)
            elif isinstance(item, Plan):
                ros.plan(None, item)
            elif isinstance(item, Qos):
                ros.qos(None, item)
            else:
                continue
            count += 1
    return count


def _record(subscriber: Any, out: Path, args: argparse.Namespace) -> int:
    """Write one JSON object per line; the file appears (atomically) when recording ends."""
    from bridge.telemetry.keys import alive_key
    from bridge.telemetry.schema import Presence
    from typed_config.files import atomic_path

    swarm = subscriber.config.swarm
    out.parent.mkdir(parents=True, exist_ok=True)
    count = 0
    with (atomic_path(out) as partial, partial.open("w", encoding="utf-8") as stream,
          contextlib.suppress(KeyboardInterrupt)):  # Ctrl-C ends the recording; the file is kept
        for item in subscriber.messages(duration_s=args.duration_s, count=args.count):
            if isinstance(item, Presence):
                line = {"key": alive_key(swarm, item.uav_id), "received_s": item.received_s,
                        "presence": "alive" if item.alive else "lost", "uav_id": item.uav_id}
            else:
                line = {"key": item.key(swarm), "received_s": time.time(), "payload": item.to_dict()}
            stream.write(json.dumps(line, separators=(",", ":")) + "\n")
            count += 1
    return count


def _watch(subscriber: Any, args: argparse.Namespace, stream: TextIO) -> None:
    """Print the swarm table every ``--refresh-s`` seconds (redrawn in place on a terminal)."""
    from bridge.telemetry.schema import Presence

    snapshot = subscriber.latest()
    alive = subscriber.alive()
    next_draw = 0.0
    for item in subscriber.messages(duration_s=args.duration_s, count=args.count):
        if isinstance(item, Presence):
            (alive.add if item.alive else alive.discard)(item.uav_id)
        else:
            snapshot.add(item)
        if time.monotonic() >= next_draw:
            _draw(snapshot, alive, subscriber.config.swarm, stream)
            next_draw = time.monotonic() + args.refresh_s
    _draw(snapshot, alive, subscriber.config.swarm, stream)


def _draw(snapshot: Any, alive: set[int], swarm: str, stream: TextIO) -> None:
    def opt(value: float | None, fmt: str) -> str:
        return "-" if value is None else format(value, fmt)

    lines = [f"swarm {swarm}: {len(alive)} alive, {len(snapshot.states)} with state",
             f"{'uav':>4} {'alive':>5} {'src':>7} {'seq':>7} {'age_s':>6} {'east_m':>8} {'north_m':>8} "
             f"{'up_m':>6} {'speed_m_s':>9} {'batt_%':>6} {'target_enu_m':>22}"]
    now = time.time()
    for uav_id in sorted(set(snapshot.states) | alive):
        state = snapshot.states.get(uav_id)
        if state is None:
            lines.append(f"{uav_id:>4} {'yes':>5}")
            continue
        if state.position_enu_m is None or state.velocity_enu_m_s is None:
            alive_text = "yes" if uav_id in alive else "no"
            lines.append(f"{uav_id:>4} {alive_text:>5} {state.source:>7} {state.seq:>7} "
                         f"{now - state.stamp_s:>6.1f} {'no position fix':>34}")
            continue
        east, north, up = state.position_enu_m
        speed = sum(v * v for v in state.velocity_enu_m_s) ** 0.5
        target = "-" if state.target_enu_m is None else ", ".join(f"{v:.1f}" for v in state.target_enu_m)
        lines.append(f"{uav_id:>4} {'yes' if uav_id in alive else 'no':>5} {state.source:>7} {state.seq:>7} "
                     f"{now - state.stamp_s:>6.1f} {east:>8.1f} {north:>8.1f} {up:>6.1f} {speed:>9.2f} "
                     f"{opt(state.battery_pct, '.0f'):>6} {target:>22}")
    if snapshot.plan is not None:
        plan = snapshot.plan
        lines.append(f"plan seq {plan.seq} by {plan.planner}: {len(plan.targets)} targets, "
                     f"latency {opt(plan.latency_ms, '.1f')} ms")
    if snapshot.qos is not None:
        qos = snapshot.qos
        lines.append(f"qos seq {qos.seq}: S1 {qos.qos_s1:.3f}  S2 {qos.qos_s2:.3f}  "
                     f"mean {qos.mean_throughput_mbps:.2f} Mbit/s  users {qos.n_users}")
    clear = "\x1b[H\x1b[2J" if stream.isatty() else ""
    stream.write(clear + "\n".join(lines) + "\n\n")
    stream.flush()
