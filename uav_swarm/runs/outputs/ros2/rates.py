"""Which topics a run publishes on ROS 2, of which type, and how often: a check with only the ``ros2`` extra.

``uav-swarm telemetry ros2-topics`` prints :func:`topic_rates`: what ``ros2 topic list -t`` and
``ros2 topic hz`` of a ROS installation would say of a run's topics, with nothing but the wheels. It
joins the ROS graph as a node of its own (the run's domain, this machine only unless told), waits at
most ``wait_s`` for a topic under the namespace to appear (and :data:`SETTLE_S` more for the run's
others), then counts what each one delivers for ``duration_s``. Its subscriptions are best effort and
volatile, which every publisher matches: a latched topic (``scene``, ``uav_<id>/target``) counts only
what is published meanwhile.
"""

from __future__ import annotations

import importlib
import time
from dataclasses import dataclass

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from uav_swarm.runs.outputs.ros2.config import Ros2Config, ros2_environment

__all__ = ["TopicRate", "topic_rates", "format_rates", "SETTLE_S"]

SETTLE_S = 1.0
"""How long the graph is watched after the namespace's first topic appeared: a node's topics come together."""

_LISTEN_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                         reliability=ReliabilityPolicy.BEST_EFFORT, durability=DurabilityPolicy.VOLATILE)


@dataclass(frozen=True)
class TopicRate:
    """One topic: its name, its type (``package/msg/Name``), the messages received and their rate.

    ``messages`` is None when the type is not installed here (nothing could be subscribed).
    """

    topic: str
    type_name: str
    messages: int | None
    rate_hz: float


def _message_class(type_name: str) -> type | None:
    """The Python class of ``package/msg/Name``, None when its package is not installed."""
    package, kind, name = type_name.split("/")
    try:
        return getattr(importlib.import_module(f"{package}.{kind}"), name)
    except (ImportError, AttributeError):
        return None


def topic_rates(namespace: str, duration_s: float, config: Ros2Config, wait_s: float = 10.0
                ) -> list[TopicRate]:
    """The topics under ``namespace`` (and ``/clock``) with what each delivered in ``duration_s`` seconds.

    Args:
        namespace: The run's namespace, e.g. ``/uav_swarm/default``.
        duration_s: How long to count, wall-clock seconds.
        config: Its ``localhost_only`` keeps discovery on this machine (as the run's default).
        wait_s: How long to wait for the namespace's first topic to appear in the graph (none found:
            an empty list).
    """
    ros2_environment(config)
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node("uav_swarm_topics", context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        topics: dict[str, str] = {}
        prefix, deadline_s = namespace.rstrip("/") + "/", time.monotonic() + wait_s
        while time.monotonic() < deadline_s:
            executor.spin_once(timeout_sec=0.05)
            topics |= {name: types[0] for name, types in node.get_topic_names_and_types()
                       if name.startswith(prefix) or name == "/clock"}
            if any(name.startswith(prefix) for name in topics):
                deadline_s = min(deadline_s, time.monotonic() + SETTLE_S)
        if not any(name.startswith(prefix) for name in topics):
            topics = {}
        counts: dict[str, int] = {}
        for name, type_name in topics.items():
            kind = _message_class(type_name)
            if kind is not None:
                counts[name] = 0
                node.create_subscription(kind, name, lambda _, n=name: counts.__setitem__(n, counts[n] + 1),
                                         _LISTEN_QOS)
        start_s = time.monotonic()
        while (now_s := time.monotonic()) < start_s + duration_s:
            executor.spin_once(timeout_sec=min(0.05, start_s + duration_s - now_s))
        executor.shutdown()
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)
    return [TopicRate(name, type_name, counts.get(name), counts.get(name, 0) / duration_s)
            for name, type_name in sorted(topics.items())]


def format_rates(rates: list[TopicRate], duration_s: float) -> str:
    """A table of ``rates``: topic, type, messages received in ``duration_s``, rate.

    Examples:
        >>> print(format_rates([TopicRate("/uav_swarm/default/qos", "diagnostic_msgs/msg/DiagnosticArray", 50,
        ...                               10.0)], 5.0))
        topic                    type                                  messages in 5 s   rate, Hz
        /uav_swarm/default/qos   diagnostic_msgs/msg/DiagnosticArray                50       10.0
    """
    width = max([len("topic"), *(len(r.topic) for r in rates)])
    type_width = max([len("type"), *(len(r.type_name) for r in rates)])
    head = f"messages in {duration_s:g} s"
    lines = [f"{'topic':<{width}}   {'type':<{type_width}}   {head:>{len(head)}}   rate, Hz"]
    for r in rates:
        received = "type not installed here" if r.messages is None else str(r.messages)
        lines.append(f"{r.topic:<{width}}   {r.type_name:<{type_width}}   {received:>{len(head)}}   "
                     f"{r.rate_hz:8.1f}")
    return "\n".join(lines)
