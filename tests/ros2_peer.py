"""A ROS 2 peer of a run, in its own process: it subscribes to every topic of the run and may steer it.

Run as ``python tests/ros2_peer.py SPEC.json OUT.json``. The spec names the namespace, the UAVs and,
optionally, operator targets to send (each after the previous one's status came back) and UAVs to
release. The peer uses the project's ROS 2 environment (loopback discovery, its own ROS_DOMAIN_ID from
the caller). It ends when the run's pose publishers are gone after it has heard them (the run ended),
or after ``timeout_s``, and writes what it received to OUT.json.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

from uav_swarm.runs.outputs.ros2.config import Ros2Config, ros2_environment

ros2_environment(Ros2Config())

import rclpy  # noqa: E402  (after the environment)
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import PoseArray, PoseStamped  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import NavSatFix, PointCloud2  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402
from visualization_msgs.msg import MarkerArray  # noqa: E402

BEST_EFFORT = QoSProfile(depth=1000, reliability=ReliabilityPolicy.BEST_EFFORT)
RELIABLE = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)


def _ns(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def _values(array: DiagnosticArray) -> list[dict]:
    return [{"name": s.name, "level": int.from_bytes(s.level, "little"), "message": s.message,
             "values": {kv.key: kv.value for kv in s.values}, "stamp_ns": _ns(array.header.stamp),
             "frame_id": array.header.frame_id} for s in array.status]


def _markers(array: MarkerArray) -> list[dict]:
    return [{"ns": m.ns, "id": m.id, "type": m.type, "action": m.action, "frame_id": m.header.frame_id,
             "stamp_ns": _ns(m.header.stamp), "scale": [m.scale.x, m.scale.y, m.scale.z],
             "color": [m.color.r, m.color.g, m.color.b, m.color.a],
             "orientation": [m.pose.orientation.x, m.pose.orientation.y, m.pose.orientation.z,
                             m.pose.orientation.w],
             "position": [m.pose.position.x, m.pose.position.y, m.pose.position.z],
             "points": [[p.x, p.y, p.z] for p in m.points], "n_colors": len(m.colors)} for m in array.markers]


def _cloud(cloud: PointCloud2) -> dict:
    points = np.frombuffer(bytes(cloud.data), np.float32).reshape(-1, 4)
    return {"stamp_ns": _ns(cloud.header.stamp), "frame_id": cloud.header.frame_id, "width": cloud.width,
            "fields": [(f.name, f.offset, f.datatype) for f in cloud.fields], "point_step": cloud.point_step,
            "n_bytes": len(cloud.data), "served": points[:, 3].tolist(),
            "z": sorted(set(points[:, 2].tolist()))}


def main() -> int:
    spec = json.loads(Path(sys.argv[1]).read_text())
    out = Path(sys.argv[2])
    ns, n_uavs = spec["namespace"], spec["n_uavs"]
    got: dict = {"poses": {str(i): [] for i in range(n_uavs)}, "targets": {str(i): [] for i in range(n_uavs)},
                 "plans": [], "plan_info": [], "qos": [], "markers": [], "scene": [], "late_scene": [],
                 "statuses": [], "clock": [], "releases": [], "crowd": [], "swarm": [], "radio": [],
           "fixes": {str(i): [] for i in range(n_uavs)}}
    rclpy.init()
    node = rclpy.create_node("uav_swarm_test_peer")
    def pose(key: str, i: int):
        return lambda m: got[key][str(i)].append([_ns(m.header.stamp), m.header.frame_id, m.pose.position.x,
                                                  m.pose.position.y, m.pose.position.z])

    for i in range(n_uavs):
        node.create_subscription(PoseStamped, f"{ns}/uav_{i}/pose", pose("poses", i), BEST_EFFORT)
        node.create_subscription(PoseStamped, f"{ns}/uav_{i}/target", pose("targets", i), LATCHED)
        node.create_subscription(NavSatFix, f"{ns}/uav_{i}/fix", lambda m, i=i: got["fixes"][str(i)].append(
            [_ns(m.header.stamp), m.header.frame_id, m.latitude, m.longitude, m.altitude]), BEST_EFFORT)
    node.create_subscription(PoseArray, f"{ns}/plan", lambda m: got["plans"].append(
        [_ns(m.header.stamp), m.header.frame_id,
         [[p.position.x, p.position.y, p.position.z] for p in m.poses]]), RELIABLE)
    node.create_subscription(DiagnosticArray, f"{ns}/plan/info",
                             lambda m: got["plan_info"].extend(_values(m)), RELIABLE)
    node.create_subscription(DiagnosticArray, f"{ns}/qos", lambda m: got["qos"].extend(_values(m)), RELIABLE)
    node.create_subscription(PoseArray, f"{ns}/poses", lambda m: got["swarm"].append(
        [_ns(m.header.stamp), m.header.frame_id,
         [[p.position.x, p.position.y, p.position.z] for p in m.poses]]), BEST_EFFORT)
    node.create_subscription(DiagnosticArray, f"{ns}/radio", lambda m: got["radio"].append(_values(m)),
                             RELIABLE)
    node.create_subscription(DiagnosticArray, f"{ns}/operator/status",
                             lambda m: got["statuses"].extend(_values(m)), RELIABLE)
    node.create_subscription(MarkerArray, f"{ns}/markers", lambda m: got["markers"].append(_markers(m)),
                             RELIABLE)
    node.create_subscription(MarkerArray, f"{ns}/scene", lambda m: got["scene"].append(_markers(m)), LATCHED)
    node.create_subscription(PointCloud2, f"{ns}/crowd", lambda m: got["crowd"].append(_cloud(m)), RELIABLE)
    node.create_subscription(Clock, "/clock", lambda m: got["clock"].append(_ns(m.clock)), BEST_EFFORT)
    steer = [node.create_publisher(PoseStamped, f"{ns}/uav_{i}/operator_target", RELIABLE)
             for i in range(n_uavs)]
    release = [node.create_client(Trigger, f"{ns}/uav_{i}/release") for i in range(n_uavs)]
    pose_pubs = f"{ns}/uav_0/pose"
    late = None
    heard = False
    actions = list(spec.get("actions", []))
    deadline = time.monotonic() + spec.get("timeout_s", 120.0)
    Path(str(out) + ".ready").write_text("ready")
    while time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.02)
        count = node.count_publishers(pose_pubs)
        heard = heard or any(got["poses"].values())
        if heard and count == 0:
            break
        if late is None and len(got["poses"]["0"]) >= spec.get("late_after_poses", 10):
            late = node.create_subscription(MarkerArray, f"{ns}/scene",
                                             lambda m: got["late_scene"].append(_markers(m)), LATCHED)
        if heard and actions:
            _act(node, actions, steer, release, got)
    end = time.monotonic() + 1.0  # what is still in flight
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.02)
    node.destroy_node()
    rclpy.shutdown()
    out.write_text(json.dumps(got))
    return 0


def _act(node, actions: list, steer: list, release: list, got: dict) -> None:
    """Do the next action once the run can take it: a target once matched, then wait for its status."""
    action = actions[0]
    uav = action["uav"]
    if action["kind"] == "target":
        if "sent_at" not in action:
            if steer[uav].get_subscription_count() == 0:
                return
            message = PoseStamped()
            message.header.frame_id = action.get("frame_id", "map")
            message.pose.position.x, message.pose.position.y, message.pose.position.z = action["xyz"]
            message.pose.orientation.w = 1.0
            action["sent_at"] = len(got["statuses"])
            steer[uav].publish(message)
            return
        if any(s["name"] == f"uav_{uav}/operator_target" for s in got["statuses"][action["sent_at"]:]):
            actions.pop(0)
    elif action["kind"] == "release":
        if "future" not in action:
            if not release[uav].service_is_ready():
                return
            action["future"] = release[uav].call_async(Trigger.Request())
            return
        if action["future"].done():
            result = action["future"].result()
            got["releases"].append({"uav": uav, "success": result.success, "message": result.message})
            actions.pop(0)


if __name__ == "__main__":
    sys.exit(main())
