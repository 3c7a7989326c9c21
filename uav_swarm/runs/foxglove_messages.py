"""Foxglove's published message types as JSON: the schemas a recording declares, and builders.

Foxglove (and Lichtblick) recognise a JSON channel by its schema name (``foxglove.SceneUpdate``,
``foxglove.PointCloud``, ``foxglove.FrameTransforms``, ``foxglove.PosesInFrame``,
``foxglove.LocationFix``) and draw it in the 3D, Map and Plot panels without setup. The schemas
below are JSON Schema (draft 2020-12) descriptions of those types with Foxglove's field names and
enum values; times are ``{"sec", "nsec"}`` objects, ``bytes`` fields base64 text. Only what a run
needs is built here: each builder returns the message as a plain dict.

Positions are East-North-Up metres in the frame :data:`MAP_FRAME` (origin: the run's home, the
area's South-West corner); a UAV ``i`` has its own frame ``uav_<i>``.

Examples:
    >>> stamp(1.25)
    {'sec': 1, 'nsec': 250000000}
    >>> SCHEMAS["foxglove.PosesInFrame"]["properties"]["poses"]["type"]
    'array'
"""

from __future__ import annotations

import base64
from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = [
    "MAP_FRAME",
    "SCHEMAS",
    "LINE_LIST",
    "LINE_LOOP",
    "FLOAT32",
    "stamp",
    "pose",
    "color",
    "scene_entity",
    "point_cloud",
    "frame_transforms",
    "poses_in_frame",
    "location_fix",
    "uav_frame",
]

MAP_FRAME = "map"
"""The run's local East-North-Up frame."""

LINE_LOOP, LINE_LIST = 1, 2  # foxglove.LineType
FLOAT32 = 7  # foxglove.NumericType
_COVARIANCE_UNKNOWN = 0  # foxglove.LocationFix.PositionCovarianceType

_NUMBER: dict[str, Any] = {"type": "number"}
_INTEGER: dict[str, Any] = {"type": "integer"}
_STRING: dict[str, Any] = {"type": "string"}
_BOOLEAN: dict[str, Any] = {"type": "boolean"}


def _object(title: str, description: str, **properties: dict[str, Any]) -> dict[str, Any]:
    return {"title": title, "description": description, "type": "object", "properties": properties}


def _array(items: dict[str, Any]) -> dict[str, Any]:
    return {"type": "array", "items": items}


_TIME = _object("time", "Timestamp: seconds and nanoseconds",
                sec={"type": "integer", "minimum": 0},
                nsec={"type": "integer", "minimum": 0, "maximum": 999_999_999})
_DURATION = _object("duration", "Duration: seconds and nanoseconds", sec=_INTEGER,
                    nsec={"type": "integer", "minimum": 0, "maximum": 999_999_999})
_VECTOR3 = _object("foxglove.Vector3", "A vector in 3D space", x=_NUMBER, y=_NUMBER, z=_NUMBER)
_QUATERNION = _object("foxglove.Quaternion", "A rotation as a unit quaternion",
                      x=_NUMBER, y=_NUMBER, z=_NUMBER, w=_NUMBER)
_POSE = _object("foxglove.Pose", "A position and orientation", position=_VECTOR3, orientation=_QUATERNION)
_COLOR = _object("foxglove.Color", "A colour, RGBA in [0, 1]", r=_NUMBER, g=_NUMBER, b=_NUMBER, a=_NUMBER)
_KEY_VALUE = _object("foxglove.KeyValuePair", "A key with its value", key=_STRING, value=_STRING)
_SPHERE = _object("foxglove.SpherePrimitive", "A sphere or ellipsoid", pose=_POSE, size=_VECTOR3,
                  color=_COLOR)
_CUBE = _object("foxglove.CubePrimitive", "A box", pose=_POSE, size=_VECTOR3, color=_COLOR)
_CYLINDER = _object("foxglove.CylinderPrimitive", "A cylinder, cone or truncated cone", pose=_POSE,
                    size=_VECTOR3, bottom_scale=_NUMBER, top_scale=_NUMBER, color=_COLOR)
_LINE = _object("foxglove.LinePrimitive", "Line segments through points", type=_INTEGER, pose=_POSE,
                thickness=_NUMBER, scale_invariant=_BOOLEAN, points=_array(_VECTOR3), color=_COLOR,
                colors=_array(_COLOR), indices=_array(_INTEGER))
_TEXT = _object("foxglove.TextPrimitive", "A text label", pose=_POSE, billboard=_BOOLEAN,
                font_size=_NUMBER, scale_invariant=_BOOLEAN, color=_COLOR, text=_STRING)
_ENTITY = _object(
    "foxglove.SceneEntity", "A visual element of a 3D scene, its primitives in one frame",
    timestamp=_TIME, frame_id=_STRING, id=_STRING, lifetime=_DURATION, frame_locked=_BOOLEAN,
    metadata=_array(_KEY_VALUE), arrows=_array({"type": "object"}), cubes=_array(_CUBE),
    spheres=_array(_SPHERE), cylinders=_array(_CYLINDER), lines=_array(_LINE),
    triangles=_array({"type": "object"}), texts=_array(_TEXT), models=_array({"type": "object"}))
_DELETION = _object("foxglove.SceneEntityDeletion", "Removes entities", timestamp=_TIME, type=_INTEGER,
                    id=_STRING)
_FIELD = _object("foxglove.PackedElementField", "A field of a packed point", name=_STRING, offset=_INTEGER,
                 type=_INTEGER)
_TRANSFORM = _object("foxglove.FrameTransform", "A transform from a parent frame to a child frame",
                     timestamp=_TIME, parent_frame_id=_STRING, child_frame_id=_STRING,
                     translation=_VECTOR3, rotation=_QUATERNION)

SCHEMAS: dict[str, dict[str, Any]] = {
    "foxglove.SceneUpdate": _object("foxglove.SceneUpdate", "Entities added to or removed from a 3D scene",
                                    deletions=_array(_DELETION), entities=_array(_ENTITY)),
    "foxglove.PointCloud": _object(
        "foxglove.PointCloud", "Points packed in bytes, each with the same fields", timestamp=_TIME,
        frame_id=_STRING, pose=_POSE, point_stride={"type": "integer", "minimum": 0},
        fields=_array(_FIELD), data={"type": "string", "contentEncoding": "base64"}),
    "foxglove.FrameTransforms": _object("foxglove.FrameTransforms", "Transforms between frames",
                                        transforms=_array(_TRANSFORM)),
    "foxglove.PosesInFrame": _object("foxglove.PosesInFrame", "Poses in one frame", timestamp=_TIME,
                                     frame_id=_STRING, poses=_array(_POSE)),
    "foxglove.LocationFix": _object(
        "foxglove.LocationFix", "A WGS84 position", timestamp=_TIME, frame_id=_STRING, latitude=_NUMBER,
        longitude=_NUMBER, altitude=_NUMBER,
        position_covariance={"type": "array", "items": _NUMBER, "minItems": 9, "maxItems": 9},
        position_covariance_type=_INTEGER),
}
"""JSON Schema of each Foxglove message type a recording uses, by its Foxglove name."""

for _name, _schema in SCHEMAS.items():
    _schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"


def stamp(time_s: float) -> dict[str, int]:
    """A Foxglove time (``sec``, ``nsec``) from seconds (non-negative)."""
    ns = round(time_s * 1e9)
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def _vector(x: float, y: float, z: float) -> dict[str, float]:
    return {"x": float(x), "y": float(y), "z": float(z)}


def pose(x_m: float, y_m: float, z_m: float) -> dict[str, Any]:
    """A pose at a position, not rotated."""
    return {"position": _vector(x_m, y_m, z_m), "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}


def color(r: float, g: float, b: float, a: float = 1.0) -> dict[str, float]:
    """A colour, each channel in [0, 1]."""
    return {"r": r, "g": g, "b": b, "a": a}


def uav_frame(uav_id: int) -> str:
    """The frame of UAV ``uav_id``."""
    return f"uav_{uav_id}"


def scene_entity(entity_id: str, time_s: float, **primitives: list[dict[str, Any]]) -> dict[str, Any]:
    """A :data:`MAP_FRAME` entity kept until replaced (lifetime 0); primitives by kind (``spheres=``...)."""
    entity: dict[str, Any] = {
        "timestamp": stamp(time_s), "frame_id": MAP_FRAME, "id": entity_id, "lifetime": {"sec": 0, "nsec": 0},
        "frame_locked": False, "metadata": []}
    for kind in ("arrows", "cubes", "spheres", "cylinders", "lines", "triangles", "texts", "models"):
        entity[kind] = primitives.pop(kind, [])
    if primitives:
        raise ValueError(f"unknown primitive kinds {sorted(primitives)}")
    return entity


def point_cloud(time_s: float, points_m: np.ndarray, values: dict[str, np.ndarray]) -> dict[str, Any]:
    """A :data:`MAP_FRAME` cloud of ``(N, 3)`` points with float32 fields (``values``: ``(N,)`` by name)."""
    columns = [np.asarray(points_m, np.float32).reshape(-1, 3)]
    columns += [np.asarray(v, np.float32).reshape(-1, 1) for v in values.values()]
    packed = np.ascontiguousarray(np.hstack(columns), dtype="<f4")
    names = ["x", "y", "z", *values]
    return {"timestamp": stamp(time_s), "frame_id": MAP_FRAME, "pose": pose(0.0, 0.0, 0.0),
            "point_stride": 4 * len(names),
            "fields": [{"name": name, "offset": 4 * i, "type": FLOAT32} for i, name in enumerate(names)],
            "data": base64.b64encode(packed.tobytes()).decode("ascii")}


def frame_transforms(time_s: float, positions_m: dict[int, Sequence[float]]) -> dict[str, Any]:
    """One transform :data:`MAP_FRAME` -> ``uav_<id>`` per UAV (its position, no rotation)."""
    transforms = []
    for uav_id, (x, y, z) in positions_m.items():
        placed = pose(x, y, z)
        transforms.append({"timestamp": stamp(time_s), "parent_frame_id": MAP_FRAME,
                           "child_frame_id": uav_frame(uav_id), "translation": placed["position"],
                           "rotation": placed["orientation"]})
    return {"transforms": transforms}


def poses_in_frame(time_s: float, positions_m: Sequence[Sequence[float]]) -> dict[str, Any]:
    """Poses at the given ``(x, y, z)`` positions in :data:`MAP_FRAME`."""
    return {"timestamp": stamp(time_s), "frame_id": MAP_FRAME, "poses": [pose(*p) for p in positions_m]}


def location_fix(time_s: float, uav_id: int, lat_deg: float, lon_deg: float, alt_m: float) -> dict[str, Any]:
    """A WGS84 fix of UAV ``uav_id`` (covariance unknown)."""
    return {"timestamp": stamp(time_s), "frame_id": uav_frame(uav_id), "latitude": float(lat_deg),
            "longitude": float(lon_deg), "altitude": float(alt_m), "position_covariance": [0.0] * 9,
            "position_covariance_type": _COVARIANCE_UNKNOWN}
