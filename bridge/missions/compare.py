"""Verification of a mission read back from a vehicle against the one sent.

By default it accepts what ArduPilot legitimately changes when it stores a mission (the seq-0
home, ``_INT`` frames read back without ``_INT``, positionless items in frame 0, NaN read back as
0, Copter's waypoint acceptance radius and yaw as 0, loiter param3 as 1, altitudes to 1 cm, float32
positions of items read back as MISSION_ITEM); ``strict`` compares exactly. See
:func:`compare_missions`.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence

import numpy as np
from pymavlink.dialects.v20 import common as mavlink

from bridge.errors import MissionMismatchError
from bridge.missions.items import DEG_E7, MissionItem

__all__ = ["compare_missions", "POSITIONAL_COMMANDS"]

POSITIONAL_COMMANDS = frozenset(
    getattr(mavlink, name)
    for name in (
        "MAV_CMD_NAV_WAYPOINT",
        "MAV_CMD_NAV_LOITER_UNLIM",
        "MAV_CMD_NAV_LOITER_TURNS",
        "MAV_CMD_NAV_LOITER_TIME",
        "MAV_CMD_NAV_LAND",
        "MAV_CMD_NAV_TAKEOFF",
        "MAV_CMD_NAV_CONTINUE_AND_CHANGE_ALT",
        "MAV_CMD_NAV_LOITER_TO_ALT",
        "MAV_CMD_NAV_SPLINE_WAYPOINT",
        "MAV_CMD_NAV_GUIDED_ENABLE",
        "MAV_CMD_DO_SET_HOME",
        "MAV_CMD_DO_LAND_START",
        "MAV_CMD_DO_GO_AROUND",
        "MAV_CMD_DO_SET_ROI",
        "MAV_CMD_NAV_VTOL_TAKEOFF",
        "MAV_CMD_NAV_VTOL_LAND",
        "MAV_CMD_NAV_PAYLOAD_PLACE",
    )
    if hasattr(mavlink, name)
)
"""Commands whose item carries a position (ArduPilot stores x, y, z only for these)."""

_NON_INT_FRAME = {
    mavlink.MAV_FRAME_GLOBAL_INT: mavlink.MAV_FRAME_GLOBAL,
    mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT: mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
    mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT: mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT,
}
_ALT_TOLERANCE_M = 0.01  # ArduPilot stores altitudes in centimetres



def _float32_tolerance_e7(value_e7: int) -> int:
    """degE7 error of a position sent as float32 degrees (MISSION_ITEM): half a float32 step, plus 1."""
    step_deg = float(np.spacing(np.float32(abs(value_e7) / DEG_E7)))
    return int(np.ceil(step_deg / 2 * DEG_E7)) + 1


def _same(a: float, b: float) -> bool:
    return a == b or (a != a and b != b)


def _differences(
    a: MissionItem, b: MissionItem, *, strict: bool, vehicle_home: bool, float_position: bool
) -> list[str]:
    """What differs between item ``a`` (sent) and ``b`` (read back) that matters; empty when none."""
    changes: list[str] = []

    def differ(name: str, sent: object, back: object) -> None:
        changes.append(f"{name} sent {sent}, read back {back}")

    exact: tuple[str, ...] = ("command", "mission_type", "autocontinue")
    if strict:
        exact += ("frame", "param1", "param2", "param3", "param4", "x", "y", "z")
    for name in exact:
        if not _same(getattr(a, name), getattr(b, name)):
            differ(name, getattr(a, name), getattr(b, name))
    if strict:
        return changes
    positional = a.command in POSITIONAL_COMMANDS and not vehicle_home
    frames = {a.frame, _NON_INT_FRAME.get(a.frame, a.frame)}
    if not positional:
        frames.add(mavlink.MAV_FRAME_GLOBAL)
    if b.frame not in frames:
        differ("frame", a.frame, b.frame)
    for index in range(1, 5):
        sent, back = getattr(a, f"param{index}"), getattr(b, f"param{index}")
        accepted = _same(sent, back) or (sent != sent and back == 0.0)  # NaN stored as 0
        if a.command == mavlink.MAV_CMD_NAV_WAYPOINT and index in (2, 4):
            accepted = accepted or back == 0.0  # Copter: acceptance radius and yaw not stored
        if a.command == mavlink.MAV_CMD_NAV_LOITER_TIME and index == 3:
            accepted = accepted or back == (-1.0 if sent < 0 else 1.0)  # only the direction is stored
        if vehicle_home:
            accepted = True
        if not accepted:
            differ(f"param{index}", sent, back)
    if positional:
        tolerance_e7 = _float32_tolerance_e7(a.x), _float32_tolerance_e7(a.y)
        for name, tol in zip(("x", "y"), tolerance_e7, strict=True):
            if abs(getattr(a, name) - getattr(b, name)) > (tol if float_position else 0):
                differ(name, getattr(a, name), getattr(b, name))
        if not abs(a.z - b.z) <= _ALT_TOLERANCE_M:
            differ("z", a.z, b.z)
    return changes


def compare_missions(
    system_id: int,
    sent: Sequence[MissionItem],
    received: Sequence[MissionItem],
    *,
    strict: bool = False,
    vehicle_home: bool = False,
    float_positions: Collection[int] = (),
) -> None:
    """Raise :class:`MissionMismatchError` unless ``received`` holds the mission ``sent``.

    ``current`` is never compared (vehicles report their own current item). Unless ``strict``
    (every other field exact), what ArduPilot legitimately changes when it stores a mission
    is accepted:

    * item 0 is the vehicle's real home (``vehicle_home``): any position, frame ``GLOBAL``;
    * ``_INT`` frames read back as their non-``_INT`` frame (6 -> 3, 5 -> 0, 11 -> 10);
    * items without a position (commands outside :data:`POSITIONAL_COMMANDS`) read back in
      frame 0 with any x, y, z;
    * NaN parameters read back as 0; ``NAV_WAYPOINT``'s acceptance radius (param2) and yaw
      (param4) read back as 0 (Copter); ``NAV_LOITER_TIME``'s param3 read back as 1 (or -1);
    * altitudes within 1 cm (stored in centimetres); positions exact in degE7, or within
      float32 rounding for the items in ``float_positions`` (read back as ``MISSION_ITEM``).

    Args:
        system_id: The vehicle (named in the error).
        sent: The items uploaded.
        received: The items read back.
        strict: Compare exactly.
        vehicle_home: Item 0 is the vehicle's home (ArduPilot).
        float_positions: Sequence numbers read back with float32 degrees.

    Raises:
        MissionMismatchError: Naming the first differing item and each difference.
    """
    if len(sent) != len(received):
        raise MissionMismatchError(system_id, None, f"{len(received)} items instead of {len(sent)}")
    for a, b in zip(sent, received, strict=True):
        changes = _differences(
            a,
            b,
            strict=strict,
            vehicle_home=vehicle_home and a.seq == 0,
            float_position=a.seq in float_positions,
        )
        if changes:
            known = a.command in mavlink.enums["MAV_CMD"]
            name = mavlink.enums["MAV_CMD"][a.command].name if known else f"command {a.command}"
            mode = "strict comparison" if strict else "ArduPilot's known changes accepted"
            raise MissionMismatchError(system_id, a.seq, f"{name}: {'; '.join(changes)} ({mode})")
