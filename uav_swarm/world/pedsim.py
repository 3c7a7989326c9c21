"""Import of Pedsim (libpedsim / pedsim_ros) XML scenes into a :class:`~uav_swarm.world.scenario.Scenario`.

Supported elements, children of the ``<scenario>`` root:

- ``<obstacle x1 y1 x2 y2>``: a wall segment.
- ``<waypoint id x y r>``: a circular waypoint named by ``id``.
- ``<agent x y n dx dy type>`` with ``<addwaypoint id>`` children: a group of ``n`` pedestrians spawned
  uniformly in ``[x - dx/2, x + dx/2] x [y - dy/2, y + dy/2]`` walking the listed waypoints in order,
  looping (as Pedsim does). Types 0 (adult), 1 (child) and 3 (elder) are pedestrians; an agent without
  ``<addwaypoint>`` stands still (libpedsim lets it idle too); agents with ``n = 0`` are dropped.

Frame: Pedsim coordinates may be negative and need not start at 0. The scene is shifted so that the
bounding box of every obstacle end, waypoint circle and spawn rectangle, grown by ``margin_m``, becomes
our area ``[0, width_m] x [0, height_m]``; ``Scenario.origin_m`` holds the shift
(``x_pedsim = x_m + origin_m[0]``, ``y_pedsim = y_m + origin_m[1]``).

Not simulated, skipped with a single :class:`PedsimImportWarning` naming them: waiting queues
(``<queue>``, ``<waitingqueue>``, ``<addqueue>``), ``<attraction>``, robots (agent ``type="2"``),
any other element, and ``<addwaypoint>`` references to undefined waypoints (Pedsim files often keep
such references to waypoints that were commented out).
"""

from __future__ import annotations

import collections
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from uav_swarm.world.scenario import AgentGroup, Scenario, ScenarioError, Waypoint

__all__ = ["PedsimImportWarning", "load_pedsim_xml"]

_ROBOT_TYPE = 2


class PedsimImportWarning(UserWarning):
    """Some elements of a Pedsim scene are not simulated and were skipped."""


def _number(element: ET.Element, key: str, where: str, path: Path) -> float:
    raw = element.get(key)
    if raw is None:
        raise ScenarioError(f"{path}: {where} <{element.tag}> lacks the attribute {key!r}")
    try:
        value = float(raw)
    except ValueError:
        raise ScenarioError(f"{path}: {where} <{element.tag}> {key}={raw!r} is not a number") from None
    if not np.isfinite(value):
        raise ScenarioError(f"{path}: {where} <{element.tag}> {key}={raw!r} is not finite")
    return value


def _integer(element: ET.Element, key: str, where: str, path: Path, default: int | None = None) -> int:
    if element.get(key) is None and default is not None:
        return default
    value = _number(element, key, where, path)
    if value != int(value) or value < 0:
        raise ScenarioError(
            f"{path}: {where} <{element.tag}> {key}={element.get(key)!r} must be an integer >= 0"
        )
    return int(value)


def _parse(
    root: ET.Element, path: Path, skipped: collections.Counter
) -> tuple[list[list[float]], list[tuple[str, float, float, float]], list[tuple]]:
    """Read obstacles, waypoints and (not yet resolved) agents in Pedsim coordinates."""
    obstacles: list[list[float]] = []
    waypoints: list[tuple[str, float, float, float]] = []
    agents: list[tuple] = []
    counts: collections.Counter = collections.Counter()
    for element in root:
        counts[element.tag] += 1
        where = f"{element.tag} #{counts[element.tag]}"
        if element.tag == "obstacle":
            obstacles.append([_number(element, k, where, path) for k in ("x1", "y1", "x2", "y2")])
        elif element.tag == "waypoint":
            name = element.get("id")
            if not name:
                raise ScenarioError(f"{path}: {where} <waypoint> lacks the attribute 'id'")
            radius = _number(element, "r", where, path)
            if radius <= 0:
                raise ScenarioError(f"{path}: {where} <waypoint id={name!r}> r={radius} must be > 0")
            waypoints.append(
                (name, _number(element, "x", where, path), _number(element, "y", where, path), radius)
            )
        elif element.tag == "agent":
            agent_type = _integer(element, "type", where, path, default=0)
            if agent_type == _ROBOT_TYPE:
                skipped["robot <agent type=2>"] += 1
                continue
            x, y, dx, dy = (_number(element, k, where, path) for k in ("x", "y", "dx", "dy"))
            n = _integer(element, "n", where, path)
            route = []
            for child in element:
                if child.tag == "addwaypoint" and child.get("id"):
                    route.append(child.get("id"))
                else:
                    skipped[f"<{child.tag}>"] += 1
            if n > 0:
                agents.append((x, y, abs(dx), abs(dy), n, route))
        else:
            skipped[f"<{element.tag}>"] += 1
    return obstacles, waypoints, agents


def load_pedsim_xml(path: str | Path, *, margin_m: float = 5.0) -> Scenario:
    """Import a Pedsim XML scene (see this module's docstring for what is kept and the frame).

    Args:
        path: The ``.xml`` scene file.
        margin_m: Free space added around the bounding box of the scene (m).

    Returns:
        The scene as a :class:`Scenario`, with ``origin_m`` the Pedsim coordinates of our origin.

    Raises:
        ScenarioError: The file is missing, not well-formed XML, not a ``<scenario>``, has a missing or
            non-numeric attribute, repeats a waypoint id, or holds nothing to place.

    Warns:
        PedsimImportWarning: Once, naming every skipped (unsupported) element kind with its count.
    """
    path = Path(path)
    if not (np.isfinite(margin_m) and margin_m >= 0):
        raise ValueError(f"margin_m = {margin_m!r} is out of range: allowed 0 <= margin_m < inf")
    try:
        root = ET.parse(path).getroot()
    except FileNotFoundError:
        raise ScenarioError(f"Pedsim scene not found: {path}") from None
    except ET.ParseError as exc:
        raise ScenarioError(f"{path}: malformed Pedsim XML: {exc}") from None
    if root.tag != "scenario":
        raise ScenarioError(f"{path}: the root element is <{root.tag}>, expected <scenario>")
    skipped: collections.Counter = collections.Counter()
    obstacles, waypoints, agents = _parse(root, path, skipped)
    names = [w[0] for w in waypoints]
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise ScenarioError(f"{path}: waypoint id(s) defined more than once: {repeated}")
    known = set(names)
    for *_, route in agents:
        for name in route:
            if name not in known:
                skipped[f"<addwaypoint id={name!r}> (undefined waypoint)"] += 1
    boxes = [[min(o[0], o[2]), min(o[1], o[3]), max(o[0], o[2]), max(o[1], o[3])] for o in obstacles]
    boxes += [[x - r, y - r, x + r, y + r] for _, x, y, r in waypoints]
    boxes += [[x - dx / 2, y - dy / 2, x + dx / 2, y + dy / 2] for x, y, dx, dy, *_ in agents]
    if not boxes:
        raise ScenarioError(f"{path}: the scene has no obstacles, waypoints or pedestrians")
    extent = np.array(boxes)
    x0, y0 = extent[:, 0].min() - margin_m, extent[:, 1].min() - margin_m
    width = max(extent[:, 2].max() + margin_m - x0, 1.0)
    height = max(extent[:, 3].max() + margin_m - y0, 1.0)
    if skipped:
        listing = ", ".join(f"{count} x {kind}" for kind, count in sorted(skipped.items()))
        warnings.warn(PedsimImportWarning(f"{path.name}: not simulated, skipped: {listing}"), stacklevel=2)
    return Scenario(
        width_m=float(width),
        height_m=float(height),
        obstacles=np.array(obstacles, dtype=np.float64).reshape(-1, 4) - [x0, y0, x0, y0],
        waypoints=tuple(Waypoint(name, x - x0, y - y0, r) for name, x, y, r in waypoints),
        groups=tuple(
            AgentGroup(x - x0, y - y0, dx, dy, n, tuple(w for w in route if w in known))
            for x, y, dx, dy, n, route in agents
        ),
        origin_m=(float(x0), float(y0)),
    )
