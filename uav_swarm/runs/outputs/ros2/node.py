"""The ROS 2 node of a run: it publishes the run and takes operator targets (``--ros2``).

Topics, under the run's namespace (``/uav_swarm/<swarm>`` unless ``[ros2] namespace`` says otherwise;
``docs/ros2.md`` has the table with rates and QoS):

- ``poses`` (``geometry_msgs/PoseArray``, ``map``), best effort: ``simulate``'s swarm at each published
  step, pose ``i`` is UAV ``i``'s (one message a step, whatever the swarm's size);
- ``uav_<id>/pose`` (``geometry_msgs/PoseStamped``, ``map``), best effort: each state of a vehicle
  (``fly``, ``telemetry ros2``); in ``simulate`` each published step while the topic has a subscriber;
- ``uav_<id>/fix`` (``sensor_msgs/NavSatFix``), best effort: a real vehicle's WGS84 fix;
- ``uav_<id>/target`` (``geometry_msgs/PoseStamped``), reliable, transient local: its current target;
- ``plan`` (``geometry_msgs/PoseArray``) and ``plan/info`` (``diagnostic_msgs/DiagnosticArray``), reliable;
- ``qos`` (``diagnostic_msgs/DiagnosticArray``), reliable;
- ``radio`` (``diagnostic_msgs/DiagnosticArray``), reliable: per UAV, its users and their throughput, while
  subscribed (a run's per-user radio figures reach ROS 2 only as these per-UAV aggregates);
- ``markers`` (``visualization_msgs/MarkerArray``): the UAVs, their coverage and separation circles;
- ``crowd`` (``sensor_msgs/PointCloud2``): the people, field ``served``;
- ``scene`` (``visualization_msgs/MarkerArray``), reliable, transient local: the area and the obstacles;
- ``operator/status`` (``diagnostic_msgs/DiagnosticArray``), reliable: each operator target accepted,
  refused (with the reason) or released;
- ``/clock`` (``rosgraph_msgs/Clock``) for ``simulate``, whose stamps are simulated time.

It subscribes to ``uav_<id>/operator_target`` (``geometry_msgs/PoseStamped``, frame ``map``) and serves
``uav_<id>/release`` (``std_srvs/Trigger``): the UAV goes back to the planner
(:class:`uav_swarm.runs.steering.OperatorTargets` validates and holds the targets). Callbacks run on the
node's own executor thread; publishing never waits on a subscriber.
"""

from __future__ import annotations

import functools
import logging
import os
import threading
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseArray, PoseStamped
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.type_support import check_for_type_support
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import NavSatFix, PointCloud2
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

import uav_swarm.runs.outputs.ros2.messages as msg
from bridge.telemetry.schema import Plan, Qos, UavState
from uav_swarm.runs.outputs.radio_report import uav_service
from uav_swarm.runs.outputs.ros2.config import Ros2Config, ros2_environment

if TYPE_CHECKING:
    from uav_swarm.runs.steering import OperatorTargets

__all__ = ["RunNode", "load_interfaces", "STATE_QOS", "LATCHED_QOS", "RELIABLE_QOS", "MARKER_QOS",
           "CLOCK_QOS"]

logger = logging.getLogger(__name__)

STATE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.BEST_EFFORT,
                       durability=DurabilityPolicy.VOLATILE)
"""High-rate streams (poses, fixes): a late sample is worth less than the next one."""

LATCHED_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
"""The static scene and each UAV's target: a subscriber that joins late gets the latest at once."""

RELIABLE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=50, reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.VOLATILE)
"""Plans, QoS and operator statuses: every one is delivered to a subscriber that keeps up."""

MARKER_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.VOLATILE)
"""The swarm's markers and the crowd: reliable (RViz's default), only the newest kept for a slow viewer."""

CLOCK_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.BEST_EFFORT,
                       durability=DurabilityPolicy.VOLATILE)
"""``/clock``, as ROS 2's time source subscribes to it."""


INTERFACES = (PoseStamped, PoseArray, NavSatFix, DiagnosticArray, MarkerArray, PointCloud2, Clock, Trigger)
"""Every message and service type the node publishes, takes or serves."""


def load_interfaces() -> None:
    """Load the C type support of every one of :data:`INTERFACES` (what a node loads when it starts).

    Raises:
        rosidl_generator_py.import_type_support_impl.UnsupportedTypeSupport: A type's library does not
            load (e.g. another ROS 2's library of the same name took its place).
    """
    for interface in INTERFACES:
        check_for_type_support(interface)


class RunNode:
    """A run's ROS 2 node: its publishers, the operator's subscriptions and services, its executor thread.

    Args:
        config: The ``[ros2]`` table (namespace, discovery range, pace).
        swarm: The swarm's name (the default namespace).
        n_uavs: UAV ids ``0 .. n_uavs - 1`` get their topics.
        node_name: The node's name (``uav_swarm_simulate``, ``uav_swarm_fly``, ...).
        sim_time: Stamps are the run times handed in, and ``/clock`` is published; else UNIX time.
        width_m: East extent of the area (metres from the home).
        height_m: North extent of the area.
        coverage_radius_m: Radius of a UAV's coverage disc.
        min_separation_m: ``uav.min_separation_m``, drawn as each UAV's separation circle.
        association: Which radio association the QoS uses (in words).
        steering: Operator targets to fill, or None (no operator topics).

    Use :func:`uav_swarm.runs.outputs.ros2.open_run_node`, which says which extra to install when ``rclpy`` is
    missing.
    """

    def __init__(self, config: Ros2Config, *, swarm: str, n_uavs: int, node_name: str, sim_time: bool,
                 width_m: float = 0.0, height_m: float = 0.0, coverage_radius_m: float = 0.0,
                 min_separation_m: float = 0.0, association: str = "",
                 steering: OperatorTargets | None = None) -> None:
        self.config = config
        self.namespace = config.namespace_for(swarm)
        self.n_uavs, self.node_name, self.sim_time = n_uavs, node_name, sim_time
        self.width_m, self.height_m = width_m, height_m
        self.coverage_radius_m, self.min_separation_m = coverage_radius_m, min_separation_m
        self.association = association
        self.steering = steering
        self._context: Any = None
        self._node: Any = None
        self._executor: Any = None
        self._thread: threading.Thread | None = None
        self._pub: dict[str, Any] = {}
        self._targets: dict[int, tuple[float, float, float]] = {}
        self._start_wall_s: float | None = None
        self._next_markers_s = 0.0
        self._lock = threading.Lock()

    # -- life ----------------------------------------------------------------------------------
    def __enter__(self) -> RunNode:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def open(self) -> None:
        """Set the environment, start the node, declare every topic and service, spin its executor."""
        ros2_environment(self.config)
        self._context = rclpy.Context()
        rclpy.init(context=self._context)
        node = self._node = rclpy.create_node(self.node_name, namespace=self.namespace, context=self._context)

        pub = self._pub
        if self.sim_time:
            pub["poses"] = node.create_publisher(PoseArray, "poses", STATE_QOS)
        for uav_id in range(self.n_uavs):
            pub[f"pose{uav_id}"] = node.create_publisher(PoseStamped, f"uav_{uav_id}/pose", STATE_QOS)
            pub[f"target{uav_id}"] = node.create_publisher(PoseStamped, f"uav_{uav_id}/target", LATCHED_QOS)
            if not self.sim_time:
                pub[f"fix{uav_id}"] = node.create_publisher(NavSatFix, f"uav_{uav_id}/fix", STATE_QOS)
        pub["plan"] = node.create_publisher(PoseArray, "plan", RELIABLE_QOS)
        pub["plan/info"] = node.create_publisher(DiagnosticArray, "plan/info", RELIABLE_QOS)
        pub["qos"] = node.create_publisher(DiagnosticArray, "qos", RELIABLE_QOS)
        pub["radio"] = node.create_publisher(DiagnosticArray, "radio", MARKER_QOS)
        pub["markers"] = node.create_publisher(MarkerArray, "markers", MARKER_QOS)
        pub["crowd"] = node.create_publisher(PointCloud2, "crowd", MARKER_QOS)
        pub["scene"] = node.create_publisher(MarkerArray, "scene", LATCHED_QOS)
        if self.sim_time:
            pub["clock"] = node.create_publisher(Clock, "/clock", CLOCK_QOS)
        if self.steering is not None:
            pub["status"] = node.create_publisher(DiagnosticArray, "operator/status", RELIABLE_QOS)
            for uav_id in range(self.n_uavs):
                node.create_subscription(PoseStamped, f"uav_{uav_id}/operator_target",
                                         functools.partial(self._on_target, uav_id), RELIABLE_QOS)
                node.create_service(Trigger, f"uav_{uav_id}/release",
                                    functools.partial(self._on_release, uav_id))
        self._executor = SingleThreadedExecutor(context=self._context)
        self._executor.add_node(node)
        self._thread = threading.Thread(target=self._spin, name="ros2-executor", daemon=True)
        self._thread.start()
        logger.info("ROS 2 node %s/%s up (ROS_DOMAIN_ID %s, discovery range %s)", self.namespace,
                    self.node_name, os.environ.get("ROS_DOMAIN_ID", "0"),
                    os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "SUBNET"))

    def _spin(self) -> None:
        try:
            self._executor.spin()
        except Exception as exc:  # the context shut down under it: the node is closing
            logger.debug("ROS 2 executor stopped: %s", exc)

    def close(self) -> None:
        """Stop the executor, destroy the node and shut its context down (idempotent)."""
        if self._node is None:
            return
        self._executor.shutdown(timeout_sec=2.0)
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        self._node.destroy_node()
        rclpy.shutdown(context=self._context)
        self._node = None

    def wait_for_subscriber(self, timeout_s: float) -> bool:
        """Wait until the poses have a subscriber and every subscriber the graph knows is matched.

        The poses: ``poses`` (``simulate``) or every UAV's ``pose``.

        The second half means a node that subscribes to the poses and the plan gets the first plan too.
        True when so within ``timeout_s``.
        """
        deadline_s = time.monotonic() + timeout_s
        while not self._subscribers_matched():
            if time.monotonic() >= deadline_s:
                return False
            time.sleep(0.01)
        return True

    def _subscribers_matched(self) -> bool:
        def subscribed(publisher: Any) -> bool:
            return bool(publisher.get_subscription_count() > 0
                        and self._node.count_subscribers(publisher.topic_name) > 0)

        if not (("poses" in self._pub and subscribed(self._pub["poses"]))
                or all(subscribed(self._pub[f"pose{i}"]) for i in range(self.n_uavs))):
            return False
        return all(p.get_subscription_count() >= self._node.count_subscribers(p.topic_name)
                   for p in self._pub.values())

    # -- what a run publishes ------------------------------------------------------------------
    def _stamp(self, time_s: float | None, stamp_s: float) -> Any:
        """Run time ``time_s`` under simulated time, else the payload's UNIX time ``stamp_s``."""
        return msg.stamp(time_s if self.sim_time and time_s is not None else stamp_s)

    def static_scene(self, obstacles_m: np.ndarray, time_s: float = 0.0) -> None:
        """The area and the obstacles, latched on ``scene`` for every subscriber, also late ones."""
        scene = msg.static_scene(self._stamp(time_s, time.time()), self.width_m, self.height_m, obstacles_m)
        self._pub["scene"].publish(scene)

    def plan(self, time_s: float | None, plan: Plan) -> None:
        """A plan on ``plan`` and ``plan/info`` (``time_s``: its run time, used under simulated time)."""
        at = self._stamp(time_s, plan.stamp_s)
        self._pub["plan"].publish(msg.plan_poses(at, plan))
        self._pub["plan/info"].publish(msg.plan_info(at, plan))

    def state(self, state: UavState, time_s: float | None = None, *, pose_if_subscribed: bool = False
              ) -> None:
        """One UAV's state: its pose, its fix (a vehicle's) and its target when it changed.

        ``pose_if_subscribed``: the pose only while its topic has a subscriber (``simulate``, whose
        ``poses`` carries every UAV's).
        """
        if not 0 <= state.uav_id < self.n_uavs or state.position_enu_m is None:
            return
        at = self._stamp(time_s, state.stamp_s)
        if not pose_if_subscribed or self._subscribed(f"pose{state.uav_id}"):
            self._pub[f"pose{state.uav_id}"].publish(msg.pose_stamped(at, state.position_enu_m))
        fix = state.position_wgs84
        if fix is not None and f"fix{state.uav_id}" in self._pub:
            fix_message = msg.nav_sat_fix(at, state.uav_id, fix.lat_deg, fix.lon_deg, fix.alt_m)
            self._pub[f"fix{state.uav_id}"].publish(fix_message)
        target = state.target_enu_m
        if target is not None:
            with self._lock:
                changed = self._targets.get(state.uav_id) != target
                self._targets[state.uav_id] = target
            if changed:
                self._pub[f"target{state.uav_id}"].publish(msg.pose_stamped(at, target))

    def qos(self, time_s: float | None, qos: Qos) -> None:
        """The QoS figures on ``qos``."""
        self._pub["qos"].publish(msg.qos_status(self._stamp(time_s, qos.stamp_s), qos, self.association))

    def step(self, time_s: float, states: Sequence[UavState], qos: Qos, pedestrians_m: np.ndarray,
             covered: np.ndarray, *, with_states: bool = True, association: np.ndarray | None = None,
             throughput_mbps: np.ndarray | None = None) -> None:
        """One published step: ``/clock``, the states (``with_states``), the QoS, markers and crowd when due.

        The states go out as one ``poses`` message (``simulate``), each UAV's ``pose`` while subscribed.
        ``association`` (each user's UAV, -1 for none) and ``throughput_mbps`` (each user's) go out summed
        per UAV on ``radio``. These streams are volatile: each goes out only while it has a subscriber
        (nobody else would get it); a UAV's target, latched for late subscribers, goes out when it changes.

        ``simulate`` keeps the ``[ros2] speed`` pace here (simulated seconds per wall-clock second).
        """
        self._keep_pace(time_s)
        at = self._stamp(time_s, qos.stamp_s)
        if self._subscribed("clock"):
            self._pub["clock"].publish(Clock(clock=at))
        if with_states:
            if self._subscribed("poses"):
                self._pub["poses"].publish(msg.swarm_poses(at, [s.position_enu_m for s in states]))
            for state in states:
                self.state(state, time_s, pose_if_subscribed="poses" in self._pub)
        if self._subscribed("qos"):
            self.qos(time_s, qos)
        radio = self._pub["radio"]
        if association is not None and throughput_mbps is not None and self._subscribed("radio"):
            uav_of = np.asarray(association)
            served = uav_of >= 0
            users = np.bincount(uav_of[served], minlength=self.n_uavs)[:self.n_uavs]
            mbps = np.bincount(uav_of[served], np.asarray(throughput_mbps)[served],
                               minlength=self.n_uavs)[:self.n_uavs]
            radio.publish(msg.radio_per_uav(at, users.tolist(), mbps.tolist()))
        markers, crowd = self._pub["markers"], self._pub["crowd"]
        if (self._subscribed("markers") or self._subscribed("crowd")) and self._markers_due():
            drawn = [s for s in states if s.position_enu_m is not None]
            uavs = {s.uav_id: s.position_enu_m for s in drawn if s.position_enu_m is not None}
            service = uav_service(drawn, pedestrians_m, covered, association)  # 802.11: channels, users
            markers.publish(msg.swarm_markers(at, uavs, self.coverage_radius_m, self.min_separation_m,
                                              service))
            crowd.publish(msg.crowd_cloud(at, pedestrians_m, covered))

    def _subscribed(self, topic: str) -> bool:
        """Whether ``topic`` is one of the node's and has a subscriber now."""
        publisher = self._pub.get(topic)
        return publisher is not None and publisher.get_subscription_count() > 0

    def _markers_due(self) -> bool:
        """Whether this step's markers go out (at most ``markers_max_rate_hz`` per wall-clock second)."""
        rate_hz = self.config.markers_max_rate_hz
        if not rate_hz:
            return True
        now_s = time.monotonic()
        if now_s < self._next_markers_s:
            return False
        self._next_markers_s = now_s + 1.0 / rate_hz
        return True

    def _keep_pace(self, time_s: float) -> None:
        if not (self.sim_time and self.config.speed):
            return
        if self._start_wall_s is None:
            self._start_wall_s = time.monotonic() - time_s / self.config.speed
        time.sleep(max(0.0, self._start_wall_s + time_s / self.config.speed - time.monotonic()))

    # -- the operator --------------------------------------------------------------------------
    def _on_target(self, uav_id: int, message: PoseStamped) -> None:
        p = message.pose.position
        target = (float(p.x), float(p.y), float(p.z))
        reason = self.steering.offer(uav_id, message.header.frame_id, *target)  # type: ignore[union-attr]
        if reason is None:
            logger.info("UAV %d: operator target (%.1f, %.1f) accepted", uav_id, target[0], target[1])
        else:
            logger.warning("UAV %d: operator target refused: %s", uav_id, reason)
        self._status(uav_id, reason is None, "accepted" if reason is None else reason, target)

    def _on_release(self, uav_id: int, request: Any, response: Any) -> Any:
        held = self.steering.release(uav_id)  # type: ignore[union-attr]
        response.success = held
        response.message = "back to the planner" if held else "no operator target was held"
        if held:
            logger.info("UAV %d: released to the planner", uav_id)
            self._status(uav_id, True, "released", None)
        return response

    def _status(self, uav_id: int, accepted: bool, message: str, target: tuple[float, float, float] | None
                ) -> None:
        status = msg.operator_status(msg.stamp(time.time()), uav_id, accepted, message, target)
        self._pub["status"].publish(status)
