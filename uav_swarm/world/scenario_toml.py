"""Scenarios from our TOML format: :func:`load_scenario`.

TOML format (``configs/scenarios/*.toml``)::

    width_m = 200.0                 # area size (required)
    height_m = 120.0
    obstacles = [                   # optional: segments [x1, y1, x2, y2] in metres
        [40.0, 30.0, 40.0, 90.0],
    ]

    [[waypoints]]                   # one table per waypoint: a circle reached when inside it
    name = "west"
    x_m = 20.0
    y_m = 60.0
    radius_m = 5.0

    [[groups]]                      # one table per group
    x_m = 20.0                      # spawn rectangle centre
    y_m = 20.0
    dx_m = 10.0                     # spawn rectangle full extent (0 spawns everyone on one point)
    dy_m = 10.0
    size = 40                       # number of pedestrians (>= 1)
    route = ["west", "east"]        # waypoint names walked in order, looping (may be empty)

Unknown keys, missing keys, values out of range, unknown waypoint names in a route and spawn
rectangles or waypoints outside the area raise :class:`ScenarioError` (a
:class:`typed_config.ConfigError`) naming the file and the field.
"""

from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from typed_config import Config, ConfigError, unknown_keys_text
from uav_swarm.world.scenario import AgentGroup, Scenario, ScenarioError, Waypoint

__all__ = ["load_scenario"]


def _tables(cls: type[Config], data: dict[str, Any], key: str, path: Path) -> tuple[Any, ...]:
    """Parse the array of tables ``data[key]`` into ``cls`` objects, naming ``key[i].field`` on errors."""
    items = data.get(key, [])
    if not isinstance(items, list) or not all(isinstance(item, dict) for item in items):
        raise ScenarioError(f"{path}: {key} must be an array of tables ([[{key}]])")
    required = [f.name for f in dataclasses.fields(cls)]  # type: ignore[arg-type]
    parsed = []
    for i, item in enumerate(items):
        missing = [name for name in required if name not in item]
        unknown = sorted(set(item) - set(required))
        if unknown:
            raise ScenarioError(f"{path}: {unknown_keys_text(f'{key}[{i}]', unknown, required)}")
        if missing:
            raise ScenarioError(f"{path}: {key}[{i}]: missing key(s) {missing}; the keys are {required}")
        try:
            parsed.append(cls.from_dict(item, where=f"{key}[{i}]"))
        except ConfigError as exc:
            raise ScenarioError(f"{path}: {exc}") from None
    return tuple(parsed)


def load_scenario(path: str | Path) -> Scenario:
    """Load a scenario from our TOML format (described in this module's docstring).

    Args:
        path: The TOML file.

    Returns:
        The validated :class:`Scenario`.

    Raises:
        ScenarioError: The file is missing, malformed or inconsistent; the message names the field.
    """
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ScenarioError(f"scenario file not found: {path}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{path}: invalid TOML: {exc}") from None
    allowed = {"width_m", "height_m", "obstacles", "waypoints", "groups"}
    unknown = sorted(set(data) - allowed)
    if unknown:
        raise ScenarioError(f"{path}: {unknown_keys_text('', unknown, sorted(allowed))}")
    missing = sorted({"width_m", "height_m"} - set(data))
    if missing:
        raise ScenarioError(f"{path}: missing key(s) {missing}")
    waypoints = _tables(Waypoint, data, "waypoints", path)
    groups = _tables(AgentGroup, data, "groups", path)
    for name in ("width_m", "height_m"):
        if isinstance(data[name], bool) or not isinstance(data[name], (int, float)):
            raise ScenarioError(f"{path}: {name} = {data[name]!r} must be a number")
    obstacles = data.get("obstacles", [])
    shape_ok = isinstance(obstacles, list) and all(
        isinstance(row, list)
        and len(row) == 4
        and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in row)
        for row in obstacles
    )
    if not shape_ok:
        raise ScenarioError(f"{path}: obstacles must be a list of [x1, y1, x2, y2] lists of numbers")
    try:
        return Scenario(
            float(data["width_m"]),
            float(data["height_m"]),
            np.array(obstacles, dtype=np.float64),
            waypoints,
            groups,
        )
    except ScenarioError as exc:
        raise ScenarioError(f"{path}: {exc}") from None
