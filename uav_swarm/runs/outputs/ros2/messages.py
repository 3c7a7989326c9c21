"""A run's payloads as standard ROS 2 messages (REP 103 units, ENU ``map`` frame of REP 105).

Poses and targets are ``geometry_msgs`` in frame ``map``: East-North-Up metres around the run's home;
a vehicle's fix is a ``sensor_msgs/NavSatFix`` in its own frame ``uav_<id>/base_link``. The plan is a
``geometry_msgs/PoseArray`` (one pose per planned UAV, in the order of the UAV ids that
``plan/info`` lists). The QoS and the plan's figures are ``diagnostic_msgs/DiagnosticArray``
key-value pairs; the scene and the swarm are ``visualization_msgs/MarkerArray`` for RViz and
Foxglove, the crowd a ``sensor_msgs/PointCloud2`` (built from one numpy buffer: hundreds of people cost
no more than a few markers). No ``/tf``: the ``tf2_msgs`` messages have no wheel; every pose names its frame.

Examples:
    >>> pose = pose_stamped(stamp(12.25), (1.0, 2.0, 10.0))
    >>> pose.header.frame_id, pose.header.stamp.sec, pose.header.stamp.nanosec, pose.pose.position.z
    ('map', 12, 250000000, 10.0)
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, Pose, PoseArray, PoseStamped, Quaternion, Vector3
from sensor_msgs.msg import NavSatFix, NavSatStatus, PointCloud2, PointField
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray

from bridge.telemetry.schema import Plan, Qos
from uav_swarm.runs.outputs.radio_report import Service, service_label, service_rgb

__all__ = ["MAP_FRAME", "stamp", "pose_stamped", "nav_sat_fix", "swarm_poses", "plan_poses", "plan_info",
           "qos_status", "radio_per_uav", "operator_status", "static_scene", "swarm_markers", "crowd_cloud",
           "uav_frame"]

MAP_FRAME = "map"
"""The run's fixed frame: East-North-Up metres from the home (REP 103 / 105)."""

Vec3 = tuple[float, float, float]
_FLAT_M = 0.05  # thickness of the discs drawn on the ground and at the UAVs' altitude
_UAV = ColorRGBA(r=0.1, g=0.4, b=0.9, a=1.0)
_COVERAGE = ColorRGBA(r=0.1, g=0.7, b=0.3, a=0.2)
_SEPARATION = ColorRGBA(r=0.9, g=0.5, b=0.1, a=0.35)
_CROWD_FIELDS = [PointField(name=name, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                 for i, name in enumerate(("x", "y", "z", "served"))]
_OUTLINE = ColorRGBA(r=0.2, g=0.2, b=0.2, a=1.0)
_OBSTACLE = ColorRGBA(r=0.8, g=0.1, b=0.1, a=1.0)
_LABEL_M, _LABEL_ABOVE_M = 2.0, 4.0  # the height of a UAV's text and how far above the UAV it stands


def uav_frame(uav_id: int) -> str:
    """The body frame of UAV ``uav_id`` (REP 105 ``base_link`` under a per-UAV prefix)."""
    return f"uav_{uav_id}/base_link"


def stamp(time_s: float) -> Time:
    """``builtin_interfaces/Time`` of ``time_s`` seconds (run time or UNIX time)."""
    ns = round(time_s * 1e9)
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def _header(at: Time, frame_id: str = MAP_FRAME) -> Header:
    return Header(stamp=at, frame_id=frame_id)


def _pose(position_m: Sequence[float]) -> Pose:
    return Pose(position=Point(x=float(position_m[0]), y=float(position_m[1]), z=float(position_m[2])),
                orientation=Quaternion(w=1.0))


def pose_stamped(at: Time, position_m: Vec3) -> PoseStamped:
    """A position in ``map`` (no attitude: the identity orientation)."""
    return PoseStamped(header=_header(at), pose=_pose(position_m))


def nav_sat_fix(at: Time, uav_id: int, lat_deg: float, lon_deg: float, alt_m: float) -> NavSatFix:
    """A vehicle's WGS84 fix (altitude above the ellipsoid as the vehicle reports it; covariance unknown)."""
    return NavSatFix(header=_header(at, uav_frame(uav_id)),
                     status=NavSatStatus(status=NavSatStatus.STATUS_FIX, service=NavSatStatus.SERVICE_GPS),
                     latitude=float(lat_deg), longitude=float(lon_deg), altitude=float(alt_m),
                     position_covariance_type=NavSatFix.COVARIANCE_TYPE_UNKNOWN)


def swarm_poses(at: Time, positions_m: Sequence[Vec3 | None]) -> PoseArray:
    """The swarm in one message: pose ``i`` at ``positions_m[i]`` (UAV ``i``; a missing one at NaN).

    Examples:
        >>> poses = swarm_poses(stamp(0.5), [(1.0, 2.0, 10.0), (3.0, 4.0, 12.0)])
        >>> [(p.position.x, p.position.z) for p in poses.poses], poses.header.frame_id
        ([(1.0, 10.0), (3.0, 12.0)], 'map')
    """
    nan = (float("nan"),) * 3
    return PoseArray(header=_header(at), poses=[_pose(nan if p is None else p) for p in positions_m])


def plan_poses(at: Time, plan: Plan) -> PoseArray:
    """The plan's targets, one pose per UAV in the order of ``plan.targets``."""
    return PoseArray(header=_header(at), poses=[_pose(t.target_enu_m) for t in plan.targets])


def _status(name: str, level: bytes, message: str, values: dict[str, object]) -> DiagnosticStatus:
    return DiagnosticStatus(level=level, name=name, message=message, hardware_id="uav_swarm",
                            values=[KeyValue(key=k, value=str(v)) for k, v in values.items()])


def plan_info(at: Time, plan: Plan) -> DiagnosticArray:
    """The plan's figures: ``seq``, ``planner``, ``latency_ms``, ``uav_ids`` (comma-separated, pose order)."""
    values = {"seq": plan.seq, "planner": plan.planner, "latency_ms": repr(plan.latency_ms),
              "uav_ids": ",".join(str(t.uav_id) for t in plan.targets)}
    status = _status("plan", DiagnosticStatus.OK, plan.planner, values)
    return DiagnosticArray(header=_header(at), status=[status])


def qos_status(at: Time, qos: Qos, association: str) -> DiagnosticArray:
    """The QoS: ``seq``, ``qos_s1``, ``qos_s2``, ``mean_throughput_mbps``, ``n_users``, ``association``.

    Floats are written with ``repr``: they read back to the very value the run computed.
    """
    values = {"seq": qos.seq, "qos_s1": repr(qos.qos_s1), "qos_s2": repr(qos.qos_s2),
              "mean_throughput_mbps": repr(qos.mean_throughput_mbps), "n_users": qos.n_users,
              "association": association}
    status = _status("qos", DiagnosticStatus.OK, association, values)
    return DiagnosticArray(header=_header(at), status=[status])


def radio_per_uav(at: Time, users: Sequence[int], throughput_mbps: Sequence[float]) -> DiagnosticArray:
    """The radio as each UAV serves it: one status ``uav_<id>/radio`` per UAV, nothing per user.

    Values: ``users`` (stations associated with the UAV) and ``throughput_mbps`` (their total).

    Examples:
        >>> radio = radio_per_uav(stamp(0.1), [3, 0], [60.0, 0.0])
        >>> [(s.name, [(v.key, v.value) for v in s.values]) for s in radio.status]
        [('uav_0/radio', [('users', '3'), ('throughput_mbps', '60.0')]), ('uav_1/radio', [('users', '0'), \
('throughput_mbps', '0.0')])]
    """
    statuses = [_status(f"uav_{uav_id}/radio", DiagnosticStatus.OK, "",
                        {"users": int(n), "throughput_mbps": repr(float(mbps))})
                for uav_id, (n, mbps) in enumerate(zip(users, throughput_mbps, strict=True))]
    return DiagnosticArray(header=_header(at), status=statuses)


def operator_status(at: Time, uav_id: int, accepted: bool, message: str, target_m: Vec3 | None
                    ) -> DiagnosticArray:
    """An operator target's outcome: OK (accepted or released) or ERROR (refused: ``message`` says why)."""
    values: dict[str, object] = {"uav_id": uav_id, "accepted": str(accepted).lower()}
    if target_m is not None:
        values |= {"x_m": repr(target_m[0]), "y_m": repr(target_m[1]), "z_m": repr(target_m[2])}
    level = DiagnosticStatus.OK if accepted else DiagnosticStatus.ERROR
    status = _status(f"uav_{uav_id}/operator_target", level, message, values)
    return DiagnosticArray(header=_header(at), status=[status])


def _marker(at: Time, ns: str, marker_id: int, kind: int, color: ColorRGBA, scale: Vec3,
            position_m: Vec3 = (0.0, 0.0, 0.0)) -> Marker:
    return Marker(header=_header(at), ns=ns, id=marker_id, type=kind, action=Marker.ADD,
                  pose=_pose(position_m), scale=Vector3(x=scale[0], y=scale[1], z=scale[2]), color=color)


def static_scene(at: Time, width_m: float, height_m: float, obstacles_m: np.ndarray) -> MarkerArray:
    """The area's outline (``area``) and the obstacle segments (``obstacles``), on the ground."""
    outline = _marker(at, "area", 0, Marker.LINE_STRIP, _OUTLINE, (0.3, 0.0, 0.0))
    outline.points = [Point(x=x, y=y, z=0.0) for x, y in
                      ((0.0, 0.0), (width_m, 0.0), (width_m, height_m), (0.0, height_m), (0.0, 0.0))]
    markers = [outline]
    segments = np.asarray(obstacles_m, np.float64).reshape(-1, 4)
    if len(segments):
        walls = _marker(at, "obstacles", 0, Marker.LINE_LIST, _OBSTACLE, (0.5, 0.0, 0.0))
        walls.points = [Point(x=float(x), y=float(y), z=0.0) for x1, y1, x2, y2 in segments
                        for x, y in ((x1, y1), (x2, y2))]
        markers.append(walls)
    return MarkerArray(markers=markers)


def crowd_cloud(at: Time, pedestrians_m: np.ndarray, covered: np.ndarray) -> PointCloud2:
    """The crowd on the ground: float fields ``x``, ``y``, ``z``, ``served`` (1 for a user a UAV serves)."""
    positions = np.asarray(pedestrians_m, np.float32).reshape(-1, 2)
    points = np.zeros((len(positions), 4), np.float32)
    points[:, :2] = positions
    points[:, 3] = np.asarray(covered, bool)
    return PointCloud2(header=_header(at), height=1, width=len(points), fields=_CROWD_FIELDS,
                       is_bigendian=False, point_step=16, row_step=16 * len(points), data=points.tobytes(),
                       is_dense=True)


def _service_colour(uav_id: int, alpha: float = 1.0) -> ColorRGBA:
    r, g, b = service_rgb(uav_id)
    return ColorRGBA(r=r, g=g, b=b, a=alpha)


def swarm_markers(at: Time, uavs_m: dict[int, Vec3], coverage_radius_m: float, min_separation_m: float,
                  service: Sequence[Service] | None = None) -> MarkerArray:
    """The swarm now: a ``DELETEALL``, then each UAV, its coverage and its separation circle.

    Namespaces: ``uavs`` (a sphere per UAV, id = UAV id), ``coverage`` (the disc a UAV serves, on the
    ground), ``separation`` (a disc of radius ``min_separation_m / 2`` at the UAV: two discs overlap when
    the pair is too close).

    With ``service`` (the 802.11 radio, :func:`~uav_swarm.runs.outputs.radio_report.uav_service`) there is no
    coverage disc: each UAV takes its colour (``SERVICE_COLOURS``), a text above it names it and its channel
    (``channels``: ``UAV 3, ch 40, 52 users``) and a line of its colour joins it to every user it serves
    (``service``), as in a recording.
    """
    markers = [Marker(header=_header(at), action=Marker.DELETEALL)]
    diameter_m, separation_m = 2.0 * coverage_radius_m, max(min_separation_m, 1e-3)
    served = {uav_id: (channel, users) for uav_id, channel, users in service or ()}
    for uav_id, (x, y, z) in sorted(uavs_m.items()):
        colour = _UAV if service is None else _service_colour(uav_id)
        markers += [_marker(at, "uavs", uav_id, Marker.SPHERE, colour, (1.0, 1.0, 1.0), (x, y, z)),
                    _marker(at, "separation", uav_id, Marker.CYLINDER, _SEPARATION,
                            (separation_m, separation_m, _FLAT_M), (x, y, z))]
        if service is None:
            markers.append(_marker(at, "coverage", uav_id, Marker.CYLINDER, _COVERAGE,
                                   (diameter_m, diameter_m, _FLAT_M), (x, y, 0.0)))
            continue
        channel, users = served.get(uav_id, (None, None))
        label = _marker(at, "channels", uav_id, Marker.TEXT_VIEW_FACING, colour, (0.0, 0.0, _LABEL_M),
                        (x, y, z + _LABEL_ABOVE_M))
        label.text = service_label(uav_id, channel, users)
        markers.append(label)
        if users is not None and len(users):
            lines = _marker(at, "service", uav_id, Marker.LINE_LIST, _service_colour(uav_id, 0.5),
                            (0.15, 0.0, 0.0))
            lines.points = [Point(x=float(px), y=float(py), z=float(pz)) for ux, uy in users
                            for px, py, pz in ((x, y, z), (ux, uy, 0.0))]
            markers.append(lines)
    return MarkerArray(markers=markers)

