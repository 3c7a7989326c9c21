"""Vectorised social-force crowd in the spirit of libpedsim (Pedsim): pedestrians walk their group's route.

Each step (explicit Euler, ``dt_s``) sums, per pedestrian ``i`` (accelerations in m/s²):

- desired force ``(v0_i e_i - v_i) / relaxation_time_s`` towards the current waypoint of the
  group's route (``e_i`` unit direction; zero desired velocity for a group without a route); a
  pedestrian near an obstacle that hides the waypoint heads for the end of that obstacle instead
  (:meth:`uav_swarm.world.walls.Walls.steer_around`), so crowds flow around walls rather than jam;
- pedestrian repulsion (Helbing) ``A exp((2 r - d_ij) / B) n_ij`` weighted by the anisotropy
  ``lambda + (1 - lambda) (1 + cos phi_ij) / 2`` (people react more to whom they face), only for pairs
  closer than ``neighbour_cutoff_m`` (compiled: :func:`uav_swarm.world.pair_forces.pair_forces`);
- wall repulsion ``A_w exp((r - d_iw) / B_w)`` away from the closest point of every obstacle segment and
  of the four area bounds within the cutoff;
- group cohesion towards the group's centroid, ``group_cohesion_m_s2 * clip(d - R_g, 0, 1)`` with
  ``R_g = group_spacing_m * sqrt(size)``, so that a group keeps together.

Velocities are capped per pedestrian at ``min(max_speed_factor * v0_i, max_speed_m_s)``. Walls are
hard: a move that would cross an obstacle segment or an area bound (or end within 1 cm of it)
loses its normal component (the pedestrian slides along the wall); a move that still collides after a
few corrections is cancelled. A pedestrian switches to the next waypoint of its route once inside the
current waypoint's circle; routes loop. Dynamics are deterministic: the generator is used only at
construction (spawn positions, desired speeds).
"""

from __future__ import annotations

import dataclasses
import logging
import math

import numba
import numpy as np

from typed_config import Config, ConfigError, param
from uav_swarm.world.geometry import point_segment_distances
from uav_swarm.world.pair_forces import pair_forces
from uav_swarm.world.scenario import Scenario, ScenarioError
from uav_swarm.world.walls import SKIN_M, Walls

__all__ = ["CrowdConfig", "CrowdSim"]

logger = logging.getLogger(__name__)

_SPAWN_ROUNDS = 200
_EPS = 1e-12


@dataclasses.dataclass(frozen=True)
class CrowdConfig(Config):
    """Parameters of the social-force crowd (:class:`CrowdSim`)."""

    dt_s: float = param(0.1, gt=0.0, le=1.0, doc="simulated seconds per step")
    relaxation_time_s: float = param(0.5, gt=0.0, le=10.0, doc="time to reach the desired velocity (s)")
    desired_speed_mean_m_s: float = param(1.34, gt=0.0, le=3.0, doc="mean desired walking speed (m/s)")
    desired_speed_std_m_s: float = param(0.26, ge=0.0, le=1.0, doc="std of desired speeds (m/s)")
    desired_speed_group_correlation: float = param(
        0.8, ge=0.0, le=1.0, doc="share of the desired-speed variance common to a group (0: independent)"
    )
    desired_speed_min_m_s: float = param(
        0.5, gt=0.0, le=3.0, doc="desired speeds are clipped to >= this (m/s)"
    )
    desired_speed_max_m_s: float = param(
        2.0, gt=0.0, le=3.0, doc="desired speeds are clipped to <= this (m/s)"
    )
    max_speed_factor: float = param(1.3, ge=1.0, le=3.0, doc="speed cap as a multiple of the desired speed")
    max_speed_m_s: float = param(2.5, gt=0.0, le=10.0, doc="hard speed cap for everyone (m/s)")
    pedestrian_radius_m: float = param(0.25, gt=0.0, le=1.0, doc="body radius (m)")
    ped_repulsion_m_s2: float = param(2.1, ge=0.0, le=100.0, doc="pedestrian repulsion strength A (m/s^2)")
    ped_repulsion_range_m: float = param(0.3, gt=0.0, le=5.0, doc="pedestrian repulsion range B (m)")
    ped_anisotropy: float = param(0.5, ge=0.0, le=1.0, doc="weight lambda of people behind (1: isotropic)")
    obstacle_repulsion_m_s2: float = param(10.0, ge=0.0, le=1000.0, doc="wall repulsion strength (m/s^2)")
    obstacle_repulsion_range_m: float = param(0.2, gt=0.0, le=5.0, doc="wall repulsion range (m)")
    neighbour_cutoff_m: float = param(
        1.5, gt=0.0, le=20.0, doc="pedestrians and walls farther are ignored (m)"
    )
    group_cohesion_m_s2: float = param(1.0, ge=0.0, le=100.0, doc="largest pull towards the group centroid")
    group_spacing_m: float = param(0.7, gt=0.0, le=10.0, doc="group radius R_g = spacing * sqrt(size) (m)")
    spawn_clearance_m: float = param(0.5, ge=0.0, le=10.0, doc="spawn points keep this from walls (m)")

    def check(self) -> None:
        """Check that the desired speed range is consistent and the integration stable."""
        low, mean, high = self.desired_speed_min_m_s, self.desired_speed_mean_m_s, self.desired_speed_max_m_s
        if not low <= mean <= high:
            raise ConfigError(
                f"CrowdConfig needs desired_speed_min_m_s <= desired_speed_mean_m_s <= "
                f"desired_speed_max_m_s, got {low} <= {mean} <= {high}"
            )
        if high > self.max_speed_m_s:
            raise ConfigError(
                f"CrowdConfig.desired_speed_max_m_s = {high} must be <= max_speed_m_s = {self.max_speed_m_s}"
            )
        if self.dt_s > self.relaxation_time_s:
            raise ConfigError(
                f"CrowdConfig.dt_s = {self.dt_s} must be <= relaxation_time_s = "
                f"{self.relaxation_time_s} (explicit integration)"
            )


class CrowdSim:
    """The crowd of a :class:`Scenario`, stepped with a vectorised social-force model.

    Args:
        scenario: Obstacles, waypoints and groups; pedestrians spawn uniformly in their group's
            rectangle, at least ``config.spawn_clearance_m`` from every wall.
        config: The crowd parameters.
        rng: Draws the spawn positions and desired speeds (the dynamics are deterministic).

    Raises:
        ScenarioError: A group's spawn rectangle has no point far enough from the walls.

    Attributes:
        scenario: The scenario.
        config: The crowd parameters.
        dt_s: Simulated seconds per step (``config.dt_s``).
        time_s: Simulated time since construction (s).
        group_ids: ``(N,)`` int group index of each pedestrian (pedestrians are ordered by group).
        desired_speeds_m_s: ``(N,)`` desired walking speeds.
        max_speeds_m_s: ``(N,)`` speed caps; ``|velocity|`` never exceeds them.
        waypoints_reached: ``(N,)`` int number of waypoints each pedestrian has reached.

    Examples:
        >>> from uav_swarm.world.scenario import random_scenario
        >>> rng = np.random.default_rng(0)
        >>> sim = CrowdSim(random_scenario(rng), CrowdConfig(), rng)
        >>> sim.step(10)
        >>> sim.positions_m.shape == (sim.scenario.n_pedestrians, 2)
        True
    """

    def __init__(self, scenario: Scenario, config: CrowdConfig, rng: np.random.Generator) -> None:
        self.scenario = scenario
        self.config = config
        self.dt_s = config.dt_s
        self.time_s: float | np.ndarray = 0.0  # (B,) in BatchedCrowd
        sizes = np.array([g.size for g in scenario.groups], dtype=np.int64)
        n = int(sizes.sum())
        self.group_ids = np.repeat(np.arange(len(sizes)), sizes)
        self.group_ids.flags.writeable = False
        self._group_sizes = sizes.astype(np.float64)
        self._group_radius_m = config.group_spacing_m * np.sqrt(self._group_sizes)
        names = {w.name: k for k, w in enumerate(scenario.waypoints)}
        # a trailing dummy waypoint keeps the indexing valid for groups without a route
        self._waypoints_m = np.array([[w.x_m, w.y_m] for w in scenario.waypoints] + [[0.0, 0.0]])
        self._waypoint_radius_m = np.array([w.radius_m for w in scenario.waypoints] + [1.0])
        routes = [[names[name] for name in g.route] for g in scenario.groups]
        self._route_length = np.array([len(r) for r in routes], dtype=np.int64)
        self._route_start = np.concatenate([[0], np.cumsum(self._route_length)[:-1]]).astype(np.int64)
        self._route_flat = np.array(
            [k for r in routes for k in r] + [len(scenario.waypoints)], dtype=np.int64
        )
        self._has_route = self._route_length[self.group_ids] > 0
        self._route_position = np.zeros(n, dtype=np.int64)
        self.waypoints_reached = np.zeros(n, dtype=np.int64)
        self._walls = Walls(scenario, n)
        self._positions = self._spawn(rng)
        rho = config.desired_speed_group_correlation
        shared = rng.standard_normal(len(sizes))[self.group_ids]
        own = rng.standard_normal(n)
        speeds = config.desired_speed_mean_m_s + config.desired_speed_std_m_s * (
            np.sqrt(rho) * shared + np.sqrt(1.0 - rho) * own
        )
        self.desired_speeds_m_s = np.clip(speeds, config.desired_speed_min_m_s, config.desired_speed_max_m_s)
        self.max_speeds_m_s = np.minimum(
            config.max_speed_factor * self.desired_speeds_m_s, config.max_speed_m_s
        )
        for array in (self.desired_speeds_m_s, self.max_speeds_m_s):
            array.flags.writeable = False
        self._velocities = np.zeros((n, 2))
        self._velocities.flags.writeable = False
        self._world_starts = np.array([0, n], dtype=np.int64)  # one world (B worlds in BatchedCrowd)
        self._sweep_order = np.arange(n, dtype=np.int64)  # the pair sweep's order, kept between steps
        logger.debug(
            "crowd of %d pedestrians in %d groups, %d obstacles", n, len(sizes), self._walls.n_obstacles
        )

    @property
    def positions_m(self) -> np.ndarray:
        """``(N, 2)`` float64 positions, read-only; a new array each step, so a kept one stays valid."""
        return self._positions

    @property
    def velocities_m_s(self) -> np.ndarray:
        """``(N, 2)`` float64 velocities (read-only, replaced at every step)."""
        return self._velocities

    @property
    def n_pedestrians(self) -> int:
        """Number of pedestrians."""
        return len(self._positions)

    @property
    def current_waypoints(self) -> np.ndarray:
        """``(N,)`` index into ``scenario.waypoints`` of each pedestrian's target (-1: no route)."""
        target = self._route_flat[self._route_start[self.group_ids] + self._route_position]
        return np.where(self._has_route, target, -1)

    def _spawn(self, rng: np.random.Generator) -> np.ndarray:
        """Uniform positions in each group's spawn rectangle, at least ``spawn_clearance_m`` from walls."""
        clearance = self.config.spawn_clearance_m
        w, h = self.scenario.width_m, self.scenario.height_m
        blocks = []
        for index, group in enumerate(self.scenario.groups):
            x0, y0, x1, y1 = group.spawn_rectangle_m
            low = np.clip([x0, y0], [SKIN_M, SKIN_M], [w - SKIN_M, h - SKIN_M])
            high = np.clip([x1, y1], low, [w - SKIN_M, h - SKIN_M])
            accepted = np.zeros((0, 2))
            for _ in range(_SPAWN_ROUNDS):
                candidates = rng.uniform(low, high, size=(max(2 * group.size, 16), 2))
                free = point_segment_distances(candidates, self._walls.segments).min(axis=1) >= max(
                    clearance, 2 * SKIN_M
                )
                accepted = np.vstack([accepted, candidates[free]])
                if len(accepted) >= group.size:
                    break
            else:
                raise ScenarioError(
                    f"groups[{index}]: no free spawn space in [{x0}, {x1}] x [{y0}, {y1}] at least "
                    f"spawn_clearance_m = {clearance} m from every wall"
                )
            blocks.append(accepted[: group.size])
        positions = np.vstack(blocks) if blocks else np.zeros((0, 2))
        positions.flags.writeable = False
        return positions

    def step(self, n_steps: int = 1) -> None:
        """Advance the crowd by ``n_steps`` steps of ``dt_s`` seconds.

        Args:
            n_steps: Number of steps (>= 0).

        Raises:
            ValueError: ``n_steps`` is not a non-negative integer.
        """
        if isinstance(n_steps, bool) or not isinstance(n_steps, (int, np.integer)) or n_steps < 0:
            raise ValueError(f"n_steps = {n_steps!r} must be an integer >= 0")
        for _ in range(int(n_steps)):
            if len(self._positions):
                self._step_once()
            self.time_s += self.dt_s

    def _step_once(self) -> None:
        cfg = self.config
        p, v = self._positions, self._velocities
        target = self._route_flat[self._route_start[self.group_ids] + self._route_position]
        goal_m = self._waypoints_m[target]
        direction = _directions(p, goal_m, self._has_route)
        wall_distance2, wall_force, near = self._walls.repulsion(
            p,
            cfg.obstacle_repulsion_m_s2,
            cfg.obstacle_repulsion_range_m,
            cfg.pedestrian_radius_m,
            cfg.neighbour_cutoff_m,
        )
        self._walls.steer_around(p, target, goal_m, direction, wall_distance2, near)
        pair_force = pair_forces(p, direction, self._world_starts, self._sweep_order, cfg.neighbour_cutoff_m,
                                 cfg.ped_repulsion_m_s2, cfg.ped_repulsion_range_m, cfg.pedestrian_radius_m,
                                 cfg.ped_anisotropy)
        v_new, move, step_m = _integrate(
            v, direction, self.desired_speeds_m_s, self.max_speeds_m_s, pair_force, wall_force,
            self._cohesion_forces(p), cfg.relaxation_time_s, self.dt_s,
        )
        changed = self._walls.resolve(p, move, wall_distance2, step_m)
        if len(changed):
            v_new[changed] = move[changed] / self.dt_s

        positions = p + move
        to_goal = goal_m - positions
        radius = self._waypoint_radius_m[target]
        reached = self._has_route & (to_goal[:, 0] ** 2 + to_goal[:, 1] ** 2 <= radius * radius)
        if reached.any():
            lengths = self._route_length[self.group_ids[reached]]
            self._route_position[reached] = (self._route_position[reached] + 1) % lengths
            self.waypoints_reached[reached] += 1
        positions.flags.writeable = False
        v_new.flags.writeable = False
        self._positions, self._velocities = positions, v_new

    def _cohesion_forces(self, p: np.ndarray) -> np.ndarray:
        """Pull towards the group centroid for pedestrians farther than the group radius, ``(N, 2)``."""
        strength_m_s2 = self.config.group_cohesion_m_s2
        if strength_m_s2 == 0:
            return np.zeros_like(p)
        return _cohesion(p, self.group_ids, self._group_sizes, self._group_radius_m, strength_m_s2)


@numba.njit(cache=True, nogil=True)
def _cohesion(p: np.ndarray, group_ids: np.ndarray, group_sizes: np.ndarray, group_radius_m: np.ndarray,
              strength_m_s2: float) -> np.ndarray:
    """``(N, 2)`` pull ``strength * clip(d - R_g, 0, 1)`` towards each group's centroid (compiled).

    The centroid sums run over the pedestrians in index order, as ``numpy.bincount`` adds them.
    """
    n, n_groups = p.shape[0], group_sizes.shape[0]
    sum_x, sum_y = np.zeros(n_groups), np.zeros(n_groups)
    for k in range(n):
        sum_x[group_ids[k]] += p[k, 0]
        sum_y[group_ids[k]] += p[k, 1]
    centre_x, centre_y = sum_x / group_sizes, sum_y / group_sizes
    pull = np.empty((n, 2))
    for k in range(n):
        g = group_ids[k]
        to_x, to_y = centre_x[g] - p[k, 0], centre_y[g] - p[k, 1]
        dist = math.sqrt(to_x * to_x + to_y * to_y)
        scale = strength_m_s2 * min(max(dist - group_radius_m[g], 0.0), 1.0) / max(dist, _EPS)
        pull[k, 0], pull[k, 1] = to_x * scale, to_y * scale
    return pull


@numba.njit(cache=True, nogil=True)
def _directions(p: np.ndarray, goal_m: np.ndarray, has_route: np.ndarray) -> np.ndarray:
    """``(N, 2)`` unit directions to the goals (zero without a route), compiled."""
    direction = np.empty_like(p)
    for k in range(p.shape[0]):
        to_x, to_y = goal_m[k, 0] - p[k, 0], goal_m[k, 1] - p[k, 1]
        scale = (1.0 if has_route[k] else 0.0) / max(math.sqrt(to_x * to_x + to_y * to_y), _EPS)
        direction[k, 0], direction[k, 1] = to_x * scale, to_y * scale
    return direction


@numba.njit(cache=True, nogil=True)
def _integrate(v: np.ndarray, direction: np.ndarray, desired_m_s: np.ndarray, max_m_s: np.ndarray,
               pair: np.ndarray, wall: np.ndarray, cohesion: np.ndarray, relaxation_s: float, dt_s: float
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One explicit Euler step of the velocities under the summed forces, capped; compiled.

    Returns the new velocities, the moves ``v dt`` and the bound ``min(|v|, cap) dt`` of each move.
    """
    n = v.shape[0]
    v_new, move, step_m = np.empty((n, 2)), np.empty((n, 2)), np.empty(n)
    for k in range(n):
        force_x = (direction[k, 0] * desired_m_s[k] - v[k, 0]) / relaxation_s
        force_y = (direction[k, 1] * desired_m_s[k] - v[k, 1]) / relaxation_s
        force_x += pair[k, 0]
        force_y += pair[k, 1]
        force_x += wall[k, 0]
        force_y += wall[k, 1]
        force_x += cohesion[k, 0]
        force_y += cohesion[k, 1]
        v_x, v_y = v[k, 0] + force_x * dt_s, v[k, 1] + force_y * dt_s
        speed = math.sqrt(v_x * v_x + v_y * v_y)
        cap = min(1.0, max_m_s[k] / max(speed, _EPS))
        v_x *= cap
        v_y *= cap
        v_new[k, 0], v_new[k, 1] = v_x, v_y
        move[k, 0], move[k, 1] = v_x * dt_s, v_y * dt_s
        step_m[k] = min(speed, max_m_s[k]) * dt_s
    return v_new, move, step_m
