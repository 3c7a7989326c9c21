"""A run's scene as Foxglove's own message types (``foxglove.messages`` of the ``foxglove-sdk``).

Foxglove draws these in its 3D, Map and Plot panels without setup: ``SceneUpdate`` (the area, the
obstacles, the UAVs, their coverage discs, their targets, their separation circles and conflicts; under
the 802.11 radio, which has no coverage disc, each UAV in a colour of its own with its channel written
above it and a line to each user it serves), ``PointCloud`` (the crowd, with a ``covered`` field and,
under 802.11, the ``uav`` that serves each user), ``FrameTransforms``, ``LocationFix`` and
``PosesInFrame``. Each builder takes numbers and returns one SDK message; the recorder
(:mod:`uav_swarm.runs.outputs.recording`) logs them.

Positions are East-North-Up metres in the frame :data:`MAP_FRAME` (origin: the run's home, the
area's South-West corner); a UAV ``i`` has its own frame ``uav_<i>``. Times are run seconds.

Examples:
    >>> t = stamp(1.25)
    >>> (t.sec, t.nsec)
    (1, 250000000)
    >>> cloud = crowd_cloud(0.5, np.array([[1.0, 2.0], [3.0, 4.0]]), np.array([True, False]))
    >>> len(cloud.encode()) > 2 * 16
    True
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from foxglove.messages import (
    Color,
    CubePrimitive,
    CylinderPrimitive,
    Duration,
    FrameTransform,
    FrameTransforms,
    LinePrimitive,
    LinePrimitiveLineType,
    LocationFix,
    LocationFixPositionCovarianceType,
    PackedElementField,
    PackedElementFieldNumericType,
    Point3,
    PointCloud,
    Pose,
    PosesInFrame,
    Quaternion,
    SceneEntity,
    SceneUpdate,
    SpherePrimitive,
    TextPrimitive,
    Timestamp,
    Vector3,
)

from uav_swarm.runs.outputs.radio_report import Service, service_label, service_rgb

__all__ = ["MAP_FRAME", "uav_frame", "stamp", "pose", "static_scene", "swarm_scene", "crowd_cloud",
           "frame_transforms", "poses_in_frame", "location_fix"]

MAP_FRAME = "map"
"""The run's local East-North-Up frame."""

Vec3 = tuple[float, float, float]

_UAV, _TARGET = Color(r=0.10, g=0.35, b=0.85, a=1.0), Color(r=0.90, g=0.45, b=0.05, a=1.0)
_DISC = Color(r=0.10, g=0.35, b=0.85, a=0.15)
_SEPARATED, _HELD = Color(r=0.15, g=0.65, b=0.25, a=0.35), Color(r=0.95, g=0.70, b=0.05, a=0.5)
_CONFLICT, _CONFLICT_LINE = Color(r=0.90, g=0.10, b=0.10, a=0.6), Color(r=0.90, g=0.10, b=0.10, a=1.0)
_WALL, _OUTLINE = Color(r=0.25, g=0.25, b=0.25, a=1.0), Color(r=0.55, g=0.55, b=0.55, a=1.0)
_UAV_SIZE_M, _TARGET_SIZE_M, _DISC_HEIGHT_M = 3.0, 2.0, 0.1
_COVERED_FIELDS = ("x", "y", "z", "covered")
_SERVED_FIELDS = ("x", "y", "z", "covered", "uav")
_LABEL_ABOVE_M, _LABEL_SIZE_PX = 4.0, 14.0
_UNROTATED = Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)
_FOREVER = Duration(0, 0)  # an entity's lifetime: kept until replaced
_UAV_BOX = Vector3(x=_UAV_SIZE_M, y=_UAV_SIZE_M, z=_UAV_SIZE_M)
_TARGET_BOX = Vector3(x=_TARGET_SIZE_M, y=_TARGET_SIZE_M, z=_TARGET_SIZE_M)


def uav_frame(uav_id: int) -> str:
    """The frame of UAV ``uav_id``."""
    return f"uav_{uav_id}"


def stamp(time_s: float) -> Timestamp:
    """A Foxglove time from run seconds (non-negative)."""
    ns = round(time_s * 1e9)
    return Timestamp(ns // 1_000_000_000, ns % 1_000_000_000)


def pose(x_m: float, y_m: float, z_m: float) -> Pose:
    """A pose at a position, not rotated."""
    return Pose(position=Vector3(x=float(x_m), y=float(y_m), z=float(z_m)), orientation=_UNROTATED)


def _point(x_m: float, y_m: float, z_m: float) -> Point3:
    return Point3(x=float(x_m), y=float(y_m), z=float(z_m))


def _entity(entity_id: str, t: Timestamp, **primitives: list) -> SceneEntity:
    """A :data:`MAP_FRAME` entity kept until replaced (lifetime 0)."""
    return SceneEntity(timestamp=t, frame_id=MAP_FRAME, id=entity_id, lifetime=_FOREVER, frame_locked=False,
                       **primitives)


def static_scene(width_m: float, height_m: float, obstacles_m: np.ndarray,
                 time_s: float = 0.0) -> SceneUpdate:
    """The area's outline (entity ``area``) and the obstacle segments ``(M, 4)`` (entity ``obstacles``)."""
    w, h = float(width_m), float(height_m)
    corners = ((0.0, 0.0), (w, 0.0), (w, h), (0.0, h))
    outline = LinePrimitive(type=LinePrimitiveLineType.LineLoop, pose=pose(0.0, 0.0, 0.0), thickness=0.5,
                            color=_OUTLINE, points=[_point(x, y, 0.0) for x, y in corners])
    segments = np.asarray(obstacles_m, np.float64).reshape(-1, 4)
    walls = LinePrimitive(type=LinePrimitiveLineType.LineList, pose=pose(0.0, 0.0, 0.0), thickness=1.0,
                          color=_WALL, points=[_point(x, y, 0.0) for x1, y1, x2, y2 in segments
                                               for x, y in ((x1, y1), (x2, y2))])
    t = stamp(time_s)
    return SceneUpdate(entities=[_entity("area", t, lines=[outline]),
                                 _entity("obstacles", t, lines=[walls] if len(segments) else [])])


def swarm_scene(time_s: float, placed: Sequence[tuple[Vec3, Vec3 | None]], coverage_radius_m: float,
                min_separation_m: float = 0.0, held: Sequence[bool] = (),
                service: Sequence[Service] | None = None) -> SceneUpdate:
    """The UAVs (``uavs``), their coverage discs (``coverage``) and targets (``targets``, a leg to each).

    With a minimum separation also each UAV's separation circle (``separation``: a flat disc of radius
    ``min_separation_m / 2`` at its altitude, so two circles overlap exactly when the pair is closer than
    the minimum; red for a UAV in such a pair, amber for one the guard holds, green otherwise) and a red
    line between the UAVs of every such pair (``conflicts``; 3-D distances).

    With ``service`` (the 802.11 radio) there is no coverage disc: each UAV takes its colour
    (:data:`~uav_swarm.runs.outputs.radio_report.SERVICE_COLOURS`), a label above it names it and its channel
    (``channels``: ``UAV 3, ch 40, 52 users``) and a line of its colour joins it to every user it serves
    (``service``).

    Args:
        time_s: Run time.
        placed: Position and target (or None) of each UAV with a position fix.
        coverage_radius_m: Radius of a disc on the ground (the paper's radio).
        min_separation_m: The minimum distance between two UAVs (0: no circles).
        held: Whether the separation guard holds each UAV of ``placed`` (empty: none known).
        service: For each UAV of ``placed``, its id, channel and the ``(M, 2)`` users it serves (None: not
            known, no lines).
    """
    colours = [_UAV] * len(placed) if service is None else [_service_colour(uav) for uav, _, _ in service]
    uavs = [SpherePrimitive(pose=pose(*position), size=_UAV_BOX, color=colour)
            for (position, _), colour in zip(placed, colours, strict=True)]
    disc = Vector3(x=2.0 * coverage_radius_m, y=2.0 * coverage_radius_m, z=_DISC_HEIGHT_M)
    discs = [] if service is not None else [
        CylinderPrimitive(pose=pose(x, y, _DISC_HEIGHT_M / 2), size=disc, bottom_scale=1.0, top_scale=1.0,
                          color=_DISC) for (x, y, _), _ in placed]
    aimed = [(position, target) for position, target in placed if target is not None]
    targets = [CubePrimitive(pose=pose(*target), size=_TARGET_BOX, color=_TARGET) for _, target in aimed]
    legs = LinePrimitive(type=LinePrimitiveLineType.LineList, pose=pose(0.0, 0.0, 0.0), thickness=0.3,
                         color=_TARGET, points=[_point(*p) for pair in aimed for p in pair])
    t = stamp(time_s)
    entities = [_entity("uavs", t, spheres=uavs), _entity("coverage", t, cylinders=discs),
                _entity("targets", t, cubes=targets, lines=[legs] if aimed else [])]
    if service is not None:
        entities += _service(t, [position for position, _ in placed], service)
    if min_separation_m > 0:
        entities += _separation(t, [position for position, _ in placed], min_separation_m, held)
    return SceneUpdate(entities=entities)


def _service_colour(uav_id: int, alpha: float = 1.0) -> Color:
    """UAV ``uav_id``'s colour in the pictures of an 802.11 run."""
    r, g, b = service_rgb(uav_id)
    return Color(r=r, g=g, b=b, a=alpha)


def _service(t: Timestamp, positions: Sequence[Vec3], service: Sequence[Service]) -> list[SceneEntity]:
    """Each UAV's label (entity ``channels``) and its lines to the users it serves (entity ``service``)."""
    labels, lines = [], []
    for (x, y, z), (uav_id, channel, users_m) in zip(positions, service, strict=True):
        colour = _service_colour(uav_id)
        users = np.zeros((0, 2)) if users_m is None else np.asarray(users_m, np.float64).reshape(-1, 2)
        labels.append(TextPrimitive(pose=pose(x, y, z + _LABEL_ABOVE_M), billboard=True,
                                    font_size=_LABEL_SIZE_PX, scale_invariant=True, color=colour,
                                    text=service_label(uav_id, channel, users_m)))
        if len(users):
            ends = [_point(x, y, z) if i % 2 == 0 else _point(users[i // 2, 0], users[i // 2, 1], 0.0)
                    for i in range(2 * len(users))]
            lines.append(LinePrimitive(type=LinePrimitiveLineType.LineList, pose=pose(0.0, 0.0, 0.0),
                                       thickness=0.15, color=_service_colour(uav_id, 0.5),
                                       points=ends))
    return [_entity("channels", t, texts=labels), _entity("service", t, lines=lines)]


def _separation(t: Timestamp, positions: Sequence[Vec3], min_separation_m: float, held: Sequence[bool]
                ) -> list[SceneEntity]:
    """The separation circles (entity ``separation``) and the conflict lines (entity ``conflicts``)."""
    p = np.asarray(positions, np.float64).reshape(-1, 3)
    d = np.linalg.norm(p[:, None] - p[None], axis=-1) + np.diag(np.full(len(p), np.inf))
    pairs = np.argwhere(np.triu(d < min_separation_m, 1))
    conflicted = np.zeros(len(p), dtype=bool)
    conflicted[pairs.ravel()] = True
    size = Vector3(x=float(min_separation_m), y=float(min_separation_m), z=_DISC_HEIGHT_M)
    circles = [CylinderPrimitive(pose=pose(*position), size=size, bottom_scale=1.0, top_scale=1.0,
                                 color=_CONFLICT if conflicted[i] else _HELD if i < len(held) and held[i]
                                 else _SEPARATED)
               for i, position in enumerate(positions)]
    ends = [_point(*positions[k]) for pair in pairs for k in pair]
    lines = LinePrimitive(type=LinePrimitiveLineType.LineList, pose=pose(0.0, 0.0, 0.0), thickness=0.6,
                          color=_CONFLICT_LINE, points=ends)
    return [_entity("separation", t, cylinders=circles),
            _entity("conflicts", t, lines=[lines] if ends else [])]


def crowd_cloud(time_s: float, users_m: np.ndarray, covered: np.ndarray,
                association: np.ndarray | None = None) -> PointCloud:
    """The crowd ``(N, 2)`` on the ground as float32 ``x, y, z, covered`` (1 for a user a UAV serves).

    With ``association`` (``(N,)`` each user's UAV, -1 for none; the 802.11 radio) also ``uav``, the UAV
    that serves the user (-1: none), by which Foxglove's point cloud can be coloured.
    """
    users = np.asarray(users_m, np.float64).reshape(-1, 2)
    names = _COVERED_FIELDS if association is None else _SERVED_FIELDS
    packed = np.zeros((len(users), len(names)), "<f4")
    packed[:, :2] = users
    packed[:, 3] = np.asarray(covered, bool)
    if association is not None:
        packed[:, 4] = np.where(np.asarray(covered, bool), np.asarray(association), -1)
    fields = [PackedElementField(name=name, offset=4 * i, type=PackedElementFieldNumericType.Float32)
              for i, name in enumerate(names)]
    return PointCloud(timestamp=stamp(time_s), frame_id=MAP_FRAME, pose=pose(0.0, 0.0, 0.0),
                      point_stride=packed.itemsize * packed.shape[1], fields=fields, data=packed.tobytes())


def frame_transforms(time_s: float, positions_m: dict[int, Vec3]) -> FrameTransforms:
    """One transform :data:`MAP_FRAME` -> ``uav_<id>`` per UAV (its position, no rotation)."""
    t = stamp(time_s)
    return FrameTransforms(transforms=[
        FrameTransform(timestamp=t, parent_frame_id=MAP_FRAME, child_frame_id=uav_frame(uav_id),
                       translation=Vector3(x=float(x), y=float(y), z=float(z)), rotation=_UNROTATED)
        for uav_id, (x, y, z) in positions_m.items()])


def poses_in_frame(time_s: float, positions_m: Sequence[Vec3]) -> PosesInFrame:
    """Poses at the given ``(x, y, z)`` positions in :data:`MAP_FRAME`."""
    return PosesInFrame(timestamp=stamp(time_s), frame_id=MAP_FRAME, poses=[pose(*p) for p in positions_m])


def location_fix(time_s: float, uav_id: int, lat_deg: float, lon_deg: float, alt_m: float) -> LocationFix:
    """A WGS84 fix of UAV ``uav_id`` (covariance unknown)."""
    return LocationFix(timestamp=stamp(time_s), frame_id=uav_frame(uav_id), latitude=float(lat_deg),
                       longitude=float(lon_deg), altitude=float(alt_m), position_covariance=[0.0] * 9,
                       position_covariance_type=LocationFixPositionCovarianceType.Unknown)
