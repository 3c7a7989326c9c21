"""Compiled social-force crowd in the spirit of libpedsim (Pedsim): pedestrians walk their group's route.

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

The step is a few numba loops over the pedestrians of every world (goals, walls, pair forces, cohesion,
then the Euler step with the walls' corrections and the route bookkeeping), into buffers kept between
steps; :class:`~uav_swarm.world.crowd_batch.BatchedCrowd` runs the same loops over B stacked worlds.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import sys

import numba
import numpy as np

from typed_config import Config, ConfigError, param
from uav_swarm.world.geometry import point_segment_distances
from uav_swarm.world.pair_forces import PAIRS_AT_ONCE, pair_forces_into
from uav_swarm.world.scenario import Scenario, ScenarioError
from uav_swarm.world.walls import SKIN_M, Walls, resolve_move

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
    """The crowd of a :class:`Scenario`, stepped with a compiled social-force model.

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
        self._wall_reach_m = _wall_reach_m(self.max_speeds_m_s, self.dt_s)
        self._velocities = np.zeros((n, 2))
        self._velocities.flags.writeable = False
        self._world_starts = np.array([0, n], dtype=np.int64)  # one world (B worlds in BatchedCrowd)
        self._sweep_order = np.arange(n, dtype=np.int64)  # the pair sweep's order, kept between steps
        self._scratch = _Scratch(self._route_length[self.group_ids])
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
        cfg, s, walls = self.config, self._scratch, self._walls
        p = self._positions
        _goals(p, self.group_ids, self._route_start, self._route_position, self._route_flat,
               self._waypoints_m, self._has_route, s.target, s.goal_m, s.direction)
        wall_force = walls.repulsion(p, cfg.obstacle_repulsion_m_s2, cfg.obstacle_repulsion_range_m,
                                     cfg.pedestrian_radius_m, cfg.neighbour_cutoff_m, self._wall_reach_m)
        walls.steer_around(p, s.target, s.goal_m, s.direction)
        pair_forces_into(p, s.direction, self._world_starts, self._sweep_order, cfg.neighbour_cutoff_m,
                         cfg.ped_repulsion_m_s2, cfg.ped_repulsion_range_m, cfg.pedestrian_radius_m,
                         cfg.ped_anisotropy, s.pair_force, s.rows, s.sorted_m, s.pairs)
        if cfg.group_cohesion_m_s2 == 0:
            s.cohesion[:] = 0.0
        else:
            _cohesion(p, self.group_ids, self._group_sizes, self._group_radius_m, cfg.group_cohesion_m_s2,
                      s.cohesion)
        positions, velocities = s.unused(self._positions, self._velocities)
        start, contact_wall, dist2, wall_a, wall_unit, wall_length = walls.resolve_arguments()
        _advance(p, self._velocities, s.direction, self.desired_speeds_m_s, self.max_speeds_m_s, s.pair_force,
                 wall_force, s.cohesion, cfg.relaxation_time_s, self.dt_s, s.goal_m, s.target,
                 self._waypoint_radius_m, self._has_route, s.route_length, self._route_position,
                 self.waypoints_reached, start, contact_wall, dist2, wall_a, wall_unit, wall_length,
                 positions, velocities)
        positions.flags.writeable = False
        velocities.flags.writeable = False
        self._positions, self._velocities = positions, velocities


class _Scratch:
    """Per-pedestrian buffers of a step, reused from step to step, and each pedestrian's route length.

    The positions and velocities of a step are new arrays for whoever keeps them; :meth:`unused` hands out
    those of two steps before when nothing refers to them any more (a large crowd then costs no fresh
    memory, page faults included, at every step).
    """

    def __init__(self, route_length: np.ndarray) -> None:
        n = len(route_length)
        self.route_length = route_length
        self.target = np.empty(n, dtype=np.int64)
        self.goal_m, self.direction, self.pair_force, self.cohesion = np.empty((4, n, 2))
        self.rows = np.empty((2, n), dtype=np.int64)
        self.sorted_m = np.empty((2, n))
        self.pairs = np.empty((2, PAIRS_AT_ONCE), dtype=np.int64)
        self._retired: list[np.ndarray] = []  # the positions and velocities replaced at the last step

    def unused(self, positions: np.ndarray, velocities: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Two ``(N, 2)`` arrays for the next positions and velocities.

        ``positions`` and ``velocities``, the current ones, are retired: offered again at the next call if
        nothing refers to them then.
        """
        fresh = []
        for array in self._retired:
            # referred to only by the list, the loop and getrefcount's argument (a view holds its base): reuse
            if sys.getrefcount(array) == 3 and array.base is None:
                array.flags.writeable = True
                fresh.append(array)
            else:
                fresh.append(np.empty_like(positions))
        while len(fresh) < 2:
            fresh.append(np.empty_like(positions))
        self._retired = [positions, velocities]
        return fresh[0], fresh[1]


def _wall_reach_m(max_speeds_m_s: np.ndarray, dt_s: float) -> np.ndarray:
    """``(N,)`` the farthest a wall can be and still stop a pedestrian's move (``resolve_move``)."""
    return max_speeds_m_s * dt_s + 2 * SKIN_M


@numba.njit(cache=True, nogil=True)
def _cohesion(p: np.ndarray, group_ids: np.ndarray, group_sizes: np.ndarray, group_radius_m: np.ndarray,
              strength_m_s2: float, pull: np.ndarray) -> None:
    """``pull`` ``(N, 2)``: ``strength * clip(d - R_g, 0, 1)`` towards each group's centroid (compiled).

    The centroid sums run over the pedestrians in index order, as ``numpy.bincount`` adds them.
    """
    n, n_groups = p.shape[0], group_sizes.shape[0]
    sum_x, sum_y = np.zeros(n_groups), np.zeros(n_groups)
    for k in range(n):
        sum_x[group_ids[k]] += p[k, 0]
        sum_y[group_ids[k]] += p[k, 1]
    centre_x, centre_y = sum_x / group_sizes, sum_y / group_sizes
    for k in range(n):
        g = group_ids[k]
        to_x, to_y = centre_x[g] - p[k, 0], centre_y[g] - p[k, 1]
        dist = math.sqrt(to_x * to_x + to_y * to_y)
        scale = strength_m_s2 * min(max(dist - group_radius_m[g], 0.0), 1.0) / max(dist, _EPS)
        pull[k, 0], pull[k, 1] = to_x * scale, to_y * scale


@numba.njit(cache=True, nogil=True)
def _goals(p: np.ndarray, group_ids: np.ndarray, route_start: np.ndarray, route_position: np.ndarray,
           route_flat: np.ndarray, waypoints_m: np.ndarray, has_route: np.ndarray, target: np.ndarray,
           goal_m: np.ndarray, direction: np.ndarray) -> None:
    """Each pedestrian's waypoint, its position and the unit direction to it; compiled.

    Written into the buffers ``target`` ``(N,)``, ``goal_m`` and ``direction`` ``(N, 2)`` (zero direction
    without a route).
    """
    for k in range(p.shape[0]):
        t = route_flat[route_start[group_ids[k]] + route_position[k]]
        target[k] = t
        goal_m[k, 0], goal_m[k, 1] = waypoints_m[t, 0], waypoints_m[t, 1]
        to_x, to_y = goal_m[k, 0] - p[k, 0], goal_m[k, 1] - p[k, 1]
        scale = (1.0 if has_route[k] else 0.0) / max(math.sqrt(to_x * to_x + to_y * to_y), _EPS)
        direction[k, 0], direction[k, 1] = to_x * scale, to_y * scale


@numba.njit(cache=True, nogil=True)
def _advance(p: np.ndarray, v: np.ndarray, direction: np.ndarray, desired_m_s: np.ndarray,
             max_m_s: np.ndarray, pair: np.ndarray, wall: np.ndarray, cohesion: np.ndarray,
             relaxation_s: float, dt_s: float, goal_m: np.ndarray, target: np.ndarray,
             waypoint_radius_m: np.ndarray, has_route: np.ndarray, route_length: np.ndarray,
             route_position: np.ndarray, waypoints_reached: np.ndarray, start: np.ndarray,
             contact_wall: np.ndarray, dist2: np.ndarray, wall_a: np.ndarray, wall_unit: np.ndarray,
             wall_length: np.ndarray, positions: np.ndarray, v_new: np.ndarray) -> None:
    """One explicit Euler step under the summed forces, speeds capped, moves kept off the walls; compiled.

    Writes the new positions and velocities into ``positions`` and ``v_new``; a pedestrian that reaches
    its waypoint's circle moves on along its route (``route_position``, ``waypoints_reached`` updated).
    """
    for k in range(v.shape[0]):
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
        step_m = min(speed, max_m_s[k]) * dt_s  # bounds the move
        m_x, m_y = v_x * dt_s, v_y * dt_s
        if start[k] < start[k + 1]:  # walls within reach
            m_x, m_y, changed = resolve_move(k, p, m_x, m_y, step_m, start, contact_wall, dist2, wall_a,
                                             wall_unit, wall_length)
            if changed:
                v_x, v_y = m_x / dt_s, m_y / dt_s
        v_new[k, 0], v_new[k, 1] = v_x, v_y
        x, y = p[k, 0] + m_x, p[k, 1] + m_y
        positions[k, 0], positions[k, 1] = x, y
        to_x, to_y = goal_m[k, 0] - x, goal_m[k, 1] - y
        radius = waypoint_radius_m[target[k]]
        if has_route[k] and to_x * to_x + to_y * to_y <= radius * radius:
            route_position[k] = (route_position[k] + 1) % route_length[k]
            waypoints_reached[k] += 1
