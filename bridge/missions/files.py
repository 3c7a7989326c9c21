"""Mission files: QGroundControl ``.plan`` (JSON) and ``QGC WPL 110`` (``.waypoints``).

Both are written atomically (:mod:`typed_config.files`: a temporary file in the same folder, then
``os.replace``) and read back to the same items: coordinates as degrees that
round to the same degE7 integers, parameters and altitudes as the shortest
decimal of the same float32 (``NaN`` is ``null`` in JSON, ``nan`` in WPL).

* ``.plan``: the items are QGC ``SimpleItem`` s; ``plannedHomePosition`` is the
  mission's home and ``firmwareType`` its autopilot. As in QGC, ArduPilot's home
  placeholder is not listed: it is rebuilt from the planned home on load.
* ``.waypoints``: one tab-separated row per item, seq 0 first (ArduPilot's home
  row when there is one), readable by ``pymavlink.mavwp.MAVWPLoader``. The
  format has no home or autopilot: the reader supplies them.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from pymavlink.dialects.v20 import common as mavlink

from bridge.autopilots import conventions_for
from bridge.geo import Home
from bridge.missions.items import DEG_E7, Mission, MissionItem, home_placeholder, mark_current
from typed_config.files import write_text_atomic

__all__ = [
    "save_plan",
    "load_plan",
    "save_wpl",
    "load_wpl",
    "save_mission",
    "load_mission",
]

WPL_HEADER = "QGC WPL 110"
PLAN_SUFFIXES = (".plan",)
WPL_SUFFIXES = (".waypoints", ".txt")


def _json_number(value: float) -> float | None:
    return None if math.isnan(value) else value


def _from_json(value: float | int | None) -> float:
    return float("nan") if value is None else float(value)


def save_plan(path: str | Path, mission: Mission) -> None:
    """Write a mission as a QGroundControl ``.plan`` file (atomically).

    Args:
        path: Destination file.
        mission: The mission; an ArduPilot home placeholder is left out, as QGC does.
    """
    items = mission.items[1:] if mission.has_home_placeholder else mission.items
    plan_items = [
        {
            "type": "SimpleItem",
            "autoContinue": bool(item.autocontinue),
            "command": item.command,
            "doJumpId": index + 1,
            "frame": item.frame,
            "params": [_json_number(v) for v in (item.param1, item.param2, item.param3, item.param4)]
            + [item.x / DEG_E7, item.y / DEG_E7, _json_number(item.z)],
        }
        for index, item in enumerate(items)
    ]
    document = {
        "fileType": "Plan",
        "version": 1,
        "groundStation": "uav-swarm",
        "mission": {
            "version": 2,
            "firmwareType": mission.autopilot,
            "vehicleType": mavlink.MAV_TYPE_QUADROTOR,
            "cruiseSpeed": 15,
            "hoverSpeed": 5,
            "plannedHomePosition": [mission.home.lat_deg, mission.home.lon_deg, mission.home.alt_m],
            "items": plan_items,
        },
        "geoFence": {"circles": [], "polygons": [], "version": 2},
        "rallyPoints": {"points": [], "version": 2},
    }
    write_text_atomic(path, json.dumps(document, indent=4, allow_nan=False) + "\n")


def load_plan(path: str | Path) -> Mission:
    """Read a QGroundControl ``.plan`` file written by :func:`save_plan` (or QGC, simple items only).

    Raises:
        ValueError: Not a plan file, or it holds complex items (surveys, ...).
    """
    document = json.loads(Path(path).read_text(encoding="utf-8"))
    if document.get("fileType") != "Plan" or "mission" not in document:
        raise ValueError(f"{path}: not a QGroundControl plan file (fileType must be 'Plan')")
    section = document["mission"]
    lat_deg, lon_deg, alt_m = section["plannedHomePosition"]
    home = Home(lat_deg=lat_deg, lon_deg=lon_deg, alt_m=alt_m)
    autopilot = int(section.get("firmwareType", mavlink.MAV_AUTOPILOT_GENERIC))
    items = [home_placeholder(home)] if conventions_for(autopilot).home_item else []
    for index, entry in enumerate(section["items"]):
        if entry.get("type") != "SimpleItem":
            raise ValueError(
                f"{path}: mission item {index} is a {entry.get('type')!r}; only SimpleItem is read"
            )
        p = entry["params"]
        items.append(
            MissionItem(
                seq=len(items),
                frame=entry["frame"],
                command=entry["command"],
                autocontinue=int(entry.get("autoContinue", True)),
                param1=_from_json(p[0]),
                param2=_from_json(p[1]),
                param3=_from_json(p[2]),
                param4=_from_json(p[3]),
                x=round(_from_json(p[4]) * DEG_E7),
                y=round(_from_json(p[5]) * DEG_E7),
                z=_from_json(p[6]),
            )
        )
    return Mission(home=home, items=mark_current(items), autopilot=autopilot)


def save_wpl(path: str | Path, items: tuple[MissionItem, ...]) -> None:
    """Write mission items as a ``QGC WPL 110`` file (atomically), loadable by ``MAVWPLoader``."""
    rows = [WPL_HEADER]
    for item in items:
        values = [
            item.seq,
            item.current,
            item.frame,
            item.command,
            repr(item.param1),
            repr(item.param2),
            repr(item.param3),
            repr(item.param4),
            f"{item.x / DEG_E7:.7f}",
            f"{item.y / DEG_E7:.7f}",
            repr(item.z),
            item.autocontinue,
        ]
        rows.append("\t".join(str(v) for v in values))
    write_text_atomic(path, "\n".join(rows) + "\n")


def load_wpl(path: str | Path) -> tuple[MissionItem, ...]:
    """Read a ``QGC WPL 110`` file.

    Raises:
        ValueError: Wrong header, or a row without exactly 12 fields.
    """
    lines = Path(path).read_text(encoding="utf-8").splitlines()
    if not lines or lines[0].strip() != WPL_HEADER:
        raise ValueError(f"{path}: first line must be {WPL_HEADER!r}")
    items = []
    for number, line in enumerate(lines[1:], start=2):
        if not line.strip() or line.startswith("#"):
            continue
        f = line.split()
        if len(f) != 12:
            raise ValueError(f"{path}:{number}: a WPL row has 12 fields, found {len(f)}")
        items.append(
            MissionItem(
                seq=int(f[0]),
                current=int(f[1]),
                frame=int(f[2]),
                command=int(f[3]),
                param1=float(f[4]),
                param2=float(f[5]),
                param3=float(f[6]),
                param4=float(f[7]),
                x=round(float(f[8]) * DEG_E7),
                y=round(float(f[9]) * DEG_E7),
                z=float(f[10]),
                autocontinue=int(f[11]),
            )
        )
    return tuple(items)


def save_mission(path: str | Path, mission: Mission) -> None:
    """Write a mission as ``.plan`` or ``QGC WPL 110`` (``.waypoints``/``.txt``), chosen by suffix.

    Raises:
        ValueError: Unknown suffix.
    """
    suffix = Path(path).suffix.lower()
    if suffix in PLAN_SUFFIXES:
        save_plan(path, mission)
    elif suffix in WPL_SUFFIXES:
        save_wpl(path, mission.items)
    else:
        raise ValueError(f"{path}: unknown mission file suffix {suffix!r}; use .plan, .waypoints or .txt")


def load_mission(path: str | Path, home: Home, autopilot: int) -> Mission:
    """Read a ``.plan`` or WPL file; ``home`` and ``autopilot`` fill in what WPL lacks (ignored for .plan).

    Raises:
        ValueError: Unknown suffix or malformed file.
    """
    suffix = Path(path).suffix.lower()
    if suffix in PLAN_SUFFIXES:
        return load_plan(path)
    if suffix in WPL_SUFFIXES:
        return Mission(home=home, items=load_wpl(path), autopilot=autopilot)
    raise ValueError(f"{path}: unknown mission file suffix {suffix!r}; use .plan, .waypoints or .txt")
