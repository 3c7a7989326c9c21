"""Crowd scenarios: obstacle segments, waypoints and pedestrian groups, and their random generation.

A :class:`Scenario` is the static part of a crowd world: the area ``[0, width_m] x [0, height_m]``
(metres, x = East, y = North, origin at the lower-left corner; its bounds are walls), obstacle line
segments, named circular waypoints and groups of pedestrians that spawn uniformly in a rectangle and
walk their route of waypoints in order, looping. A group with an empty route stands still.

Scenarios come from :func:`random_scenario` (random obstacles and waypoints, as the paper did with
Pedsim), from our TOML format (:func:`uav_swarm.world.scenario_toml.load_scenario`) or from a Pedsim
XML scene (:func:`uav_swarm.world.pedsim.load_pedsim_xml`). Invalid elements raise
:class:`ScenarioError` (a :class:`typed_config.ConfigError`) naming the field.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from typed_config import Config, ConfigError, param
from uav_swarm.world import geometry

__all__ = ["AgentGroup", "Scenario", "ScenarioConfig", "ScenarioError", "Waypoint", "random_scenario"]

_MAX_TRIES = 2000


class ScenarioError(ConfigError):
    """A scenario (file or object) is malformed or inconsistent."""


def _field(doc: str, **bounds: float) -> Any:
    """A required dataclass field with range metadata understood by :class:`typed_config.Config`."""
    return dataclasses.field(metadata={"doc": doc, **bounds})


@dataclasses.dataclass(frozen=True)
class Waypoint(Config):
    """A named circular waypoint: a pedestrian has reached it once inside the circle."""

    name: str = _field("unique name, referenced by group routes")
    x_m: float = _field("centre, East (m)")
    y_m: float = _field("centre, North (m)")
    radius_m: float = _field("radius (m)", gt=0.0)


@dataclasses.dataclass(frozen=True)
class AgentGroup(Config):
    """A group of pedestrians: spawn rectangle, size and looping route of waypoint names."""

    x_m: float = _field("spawn rectangle centre, East (m)")
    y_m: float = _field("spawn rectangle centre, North (m)")
    dx_m: float = _field("spawn rectangle full width (m): uniform in [x - dx/2, x + dx/2]", ge=0.0)
    dy_m: float = _field("spawn rectangle full height (m)", ge=0.0)
    size: int = _field("number of pedestrians", ge=1)
    route: tuple[str, ...] = _field("waypoint names walked in order, looping; empty: stand still")

    @property
    def spawn_rectangle_m(self) -> tuple[float, float, float, float]:
        """The spawn rectangle ``(x_min, y_min, x_max, y_max)``."""
        half_x, half_y = self.dx_m / 2, self.dy_m / 2
        return (self.x_m - half_x, self.y_m - half_y, self.x_m + half_x, self.y_m + half_y)


@dataclasses.dataclass(frozen=True)
class Scenario:
    """The static crowd world: area, obstacle segments, waypoints and groups.

    Attributes:
        width_m: Area width (East, m); the area is ``[0, width_m] x [0, height_m]`` and its bounds are walls.
        height_m: Area height (North, m).
        obstacles: ``(M, 4)`` float64 read-only segments ``x1, y1, x2, y2`` (``(0, 4)`` when none).
        waypoints: Waypoints with unique names.
        groups: Pedestrian groups; their routes name waypoints.
        origin_m: Where this frame's origin lies in the source frame (e.g. a Pedsim scene):
            ``x_source = x_m + origin_m[0]``, ``y_source = y_m + origin_m[1]``.
    """

    width_m: float
    height_m: float
    obstacles: np.ndarray
    waypoints: tuple[Waypoint, ...]
    groups: tuple[AgentGroup, ...]
    origin_m: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        for name in ("width_m", "height_m"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ScenarioError(f"Scenario.{name} = {value!r} is out of range: allowed 0 < {name} < inf")
        obstacles = np.array(self.obstacles, dtype=np.float64)
        if obstacles.size == 0:
            obstacles = np.zeros((0, 4))
        if obstacles.ndim != 2 or obstacles.shape[1] != 4:
            raise ScenarioError(f"Scenario.obstacles has shape {obstacles.shape}: expected (M, 4) segments")
        if not np.isfinite(obstacles).all():
            raise ScenarioError("Scenario.obstacles contains NaN or inf")
        obstacles.flags.writeable = False
        object.__setattr__(self, "obstacles", obstacles)
        object.__setattr__(self, "waypoints", tuple(self.waypoints))
        object.__setattr__(self, "groups", tuple(self.groups))
        object.__setattr__(self, "origin_m", (float(self.origin_m[0]), float(self.origin_m[1])))
        self._validate_references()

    def _validate_references(self) -> None:
        names = [w.name for w in self.waypoints]
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise ScenarioError(f"waypoint names must be unique; repeated: {duplicates}")
        tol = 1e-9
        for i, w in enumerate(self.waypoints):
            if not (-tol <= w.x_m <= self.width_m + tol and -tol <= w.y_m <= self.height_m + tol):
                raise ScenarioError(
                    f"waypoints[{i}] ({w.name!r}) at ({w.x_m}, {w.y_m}) lies outside the area "
                    f"[0, {self.width_m}] x [0, {self.height_m}]"
                )
        known = set(names)
        for i, g in enumerate(self.groups):
            unknown = [n for n in g.route if n not in known]
            if unknown:
                raise ScenarioError(f"groups[{i}].route names unknown waypoint(s) {unknown}; known: {names}")
            x0, y0, x1, y1 = g.spawn_rectangle_m
            if x0 < -tol or y0 < -tol or x1 > self.width_m + tol or y1 > self.height_m + tol:
                raise ScenarioError(
                    f"groups[{i}] spawn rectangle [{x0}, {x1}] x [{y0}, {y1}] is not inside the area "
                    f"[0, {self.width_m}] x [0, {self.height_m}]"
                )

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Scenario):
            return NotImplemented
        fields = ("width_m", "height_m", "waypoints", "groups", "origin_m")
        same = all(getattr(self, name) == getattr(other, name) for name in fields)
        return same and np.array_equal(self.obstacles, other.obstacles)

    __hash__ = None  # type: ignore[assignment]  # holds an array

    @property
    def n_pedestrians(self) -> int:
        """Total number of pedestrians over all groups."""
        return sum(g.size for g in self.groups)


@dataclasses.dataclass(frozen=True)
class ScenarioConfig(Config):
    """Settings of the random scenario generator (:func:`random_scenario`)."""

    width_m: float = param(200.0, gt=0.0, le=10_000.0, doc="area width, East (m)")
    height_m: float = param(200.0, gt=0.0, le=10_000.0, doc="area height, North (m)")
    n_obstacles: int = param(8, ge=0, le=500, doc="number of obstacle segments")
    obstacle_length_min_m: float = param(10.0, gt=0.0, doc="shortest obstacle segment (m)")
    obstacle_length_max_m: float = param(40.0, gt=0.0, doc="longest obstacle segment (m)")
    obstacle_gap_m: float = param(3.0, ge=0.0, doc="minimum distance between two obstacles (m): no corners")
    n_waypoints: int = param(6, ge=1, le=200, doc="number of waypoints")
    waypoint_radius_m: float = param(5.0, gt=0.0, doc="waypoint radius (m)")
    waypoint_separation_m: float = param(30.0, ge=0.0, doc="minimum distance between waypoint centres (m)")
    n_groups_min: int = param(6, ge=1, le=1000, doc="fewest groups")
    n_groups_max: int = param(10, ge=1, le=1000, doc="most groups")
    group_size_min: int = param(20, ge=1, doc="fewest pedestrians in a group")
    group_size_max: int = param(80, ge=1, doc="most pedestrians in a group")
    route_length_min: int = param(2, ge=1, doc="fewest waypoints on a route")
    route_length_max: int = param(4, ge=1, doc="most waypoints on a route (distinct waypoints)")
    spawn_extent_m: float = param(12.0, ge=0.0, doc="side of the square spawn area of each group (m)")
    margin_m: float = param(5.0, ge=0.0, doc="distance kept from the area bounds by everything placed (m)")
    clearance_m: float = param(
        2.0, ge=0.0, doc="distance kept between obstacles and waypoints/spawn areas (m)"
    )

    def check(self) -> None:
        """Check that every min <= max and that routes and obstacles fit."""
        pairs = (
            ("obstacle_length_min_m", "obstacle_length_max_m"),
            ("n_groups_min", "n_groups_max"),
            ("group_size_min", "group_size_max"),
            ("route_length_min", "route_length_max"),
        )
        for low, high in pairs:
            if getattr(self, low) > getattr(self, high):
                raise ConfigError(
                    f"ScenarioConfig.{low} = {getattr(self, low)} must be <= {high} = {getattr(self, high)}"
                )
        if self.route_length_max > self.n_waypoints:
            raise ConfigError(
                f"ScenarioConfig.route_length_max = {self.route_length_max} must be <= "
                f"n_waypoints = {self.n_waypoints} (routes visit distinct waypoints)"
            )
        inner = min(self.width_m, self.height_m) - 2 * self.margin_m
        for name in ("obstacle_length_max_m", "spawn_extent_m"):
            if getattr(self, name) >= inner:
                raise ConfigError(
                    f"ScenarioConfig.{name} = {getattr(self, name)} must be < the inner area side "
                    f"min(width_m, height_m) - 2 * margin_m = {inner}"
                )
        if 2 * (self.margin_m + self.waypoint_radius_m) >= min(self.width_m, self.height_m):
            raise ConfigError(
                f"ScenarioConfig.waypoint_radius_m = {self.waypoint_radius_m} does not fit "
                f"in the area with margin_m = {self.margin_m}"
            )


def _placement_error(what: str, config: ScenarioConfig) -> ScenarioError:
    return ScenarioError(
        f"random_scenario could not place {what} after {_MAX_TRIES} tries: the area "
        f"{config.width_m} x {config.height_m} m is too crowded for this ScenarioConfig"
    )


def _random_obstacles(rng: np.random.Generator, config: ScenarioConfig) -> np.ndarray:
    lo, hi_x, hi_y = config.margin_m, config.width_m - config.margin_m, config.height_m - config.margin_m
    segments = np.zeros((0, 4))
    tries = 0
    while len(segments) < config.n_obstacles:
        tries += 1
        if tries > _MAX_TRIES * max(1, config.n_obstacles):
            raise _placement_error(f"{config.n_obstacles} obstacles", config)
        length = rng.uniform(config.obstacle_length_min_m, config.obstacle_length_max_m)
        angle = rng.uniform(0.0, np.pi)
        centre = rng.uniform((lo, lo), (hi_x, hi_y))
        half = 0.5 * length * np.array([np.cos(angle), np.sin(angle)])
        candidate = np.concatenate([centre - half, centre + half])
        if candidate[[0, 2]].min() < lo or candidate[[0, 2]].max() > hi_x:
            continue
        if candidate[[1, 3]].min() < lo or candidate[[1, 3]].max() > hi_y:
            continue
        if (
            len(segments)
            and geometry.segment_segment_distances(candidate[None], segments).min() < config.obstacle_gap_m
        ):
            continue
        segments = np.vstack([segments, candidate])
    return segments


def _random_waypoints(
    rng: np.random.Generator, config: ScenarioConfig, obstacles: np.ndarray
) -> tuple[Waypoint, ...]:
    r = config.waypoint_radius_m
    lo = config.margin_m + r
    hi = (config.width_m - lo, config.height_m - lo)
    centres: list[np.ndarray] = []
    for _ in range(_MAX_TRIES * config.n_waypoints):
        if len(centres) == config.n_waypoints:
            break
        c = rng.uniform((lo, lo), hi)
        if (
            len(obstacles)
            and geometry.point_segment_distances(c[None], obstacles).min() < r + config.clearance_m
        ):
            continue
        if centres and np.hypot(*(np.array(centres) - c).T).min() < config.waypoint_separation_m:
            continue
        centres.append(c)
    if len(centres) < config.n_waypoints:
        raise _placement_error(f"{config.n_waypoints} waypoints", config)
    return tuple(Waypoint(f"wp{i}", float(c[0]), float(c[1]), r) for i, c in enumerate(centres))


def _random_groups(
    rng: np.random.Generator, config: ScenarioConfig, obstacles: np.ndarray, waypoints: tuple[Waypoint, ...]
) -> tuple[AgentGroup, ...]:
    n_groups = int(rng.integers(config.n_groups_min, config.n_groups_max + 1))
    half = config.spawn_extent_m / 2
    lo = config.margin_m + half
    hi = (config.width_m - lo, config.height_m - lo)
    groups = []
    for index in range(n_groups):
        for _ in range(_MAX_TRIES):
            c = rng.uniform((lo, lo), hi)
            rect = np.array([c[0] - half, c[1] - half, c[0] + half, c[1] + half])
            if (
                not len(obstacles)
                or geometry.rectangle_segment_distances(rect[None], obstacles).min() >= config.clearance_m
            ):
                break
        else:
            raise _placement_error(f"the spawn area of group {index}", config)
        size = int(rng.integers(config.group_size_min, config.group_size_max + 1))
        length = int(rng.integers(config.route_length_min, config.route_length_max + 1))
        route = tuple(waypoints[int(k)].name for k in rng.choice(len(waypoints), size=length, replace=False))
        groups.append(
            AgentGroup(float(c[0]), float(c[1]), config.spawn_extent_m, config.spawn_extent_m, size, route)
        )
    return tuple(groups)


def random_scenario(rng: np.random.Generator, config: ScenarioConfig | None = None) -> Scenario:
    """Draw a random scenario: obstacle segments, waypoints and groups with routes.

    Obstacles keep ``obstacle_gap_m`` between each other (no corners that trap pedestrians);
    waypoint circles and spawn rectangles keep ``clearance_m`` from every obstacle, so no spawn
    area straddles a segment; everything keeps ``margin_m`` from the area bounds.

    Args:
        rng: The random generator (same state, same scenario).
        config: Generator settings; defaults to ``ScenarioConfig()``.

    Returns:
        A valid :class:`Scenario`.

    Raises:
        ScenarioError: The requested elements do not fit in the area.

    Examples:
        >>> s = random_scenario(np.random.default_rng(0), ScenarioConfig(n_groups_min=2, n_groups_max=2))
        >>> len(s.groups), s.obstacles.shape
        (2, (8, 4))
    """
    config = config or ScenarioConfig()
    obstacles = _random_obstacles(rng, config)
    waypoints = _random_waypoints(rng, config, obstacles)
    groups = _random_groups(rng, config, obstacles, waypoints)
    return Scenario(config.width_m, config.height_m, obstacles, waypoints, groups)
