"""Hard, repulsive walls for a crowd: obstacle segments plus the area bounds, compiled per pedestrian.

:class:`Walls` answers the three questions the crowd asks of its walls every step:

- :meth:`Walls.repulsion`: the summed exponential wall repulsion of the walls near each pedestrian (and
  the contacts, the walls within reach, that the two others use);
- :meth:`Walls.steer_around`: where to head when a wall hides the goal (a pedestrian near such a wall
  aims just past the wall end with the shorter detour from which the goal is visible, like a bug
  algorithm; pure social force would jam a crowd against a wall standing across its way);
- :func:`resolve_move`: correct a move so that the pedestrian crosses no wall (the move loses its normal
  component and slides along the wall; a move that still collides after a few corrections is cancelled),
  compiled per pedestrian so that the crowd's own compiled loop calls it.

A pedestrian's candidate walls are those its cell lists (:class:`Walls` has one cell listing every wall;
:class:`~uav_swarm.world.walls_batch.BatchedWalls` cuts each copy's area into cells listing the walls
within reach); the per-pedestrian work is compiled (numba), one loop over the pedestrians of every world
(the exponentials of the repulsion are numpy's, taken between two compiled loops). A pedestrian meets its
candidate walls in ascending order, so its forces sum alike whatever the cells.

Examples:
    >>> from uav_swarm.world.scenario import AgentGroup, Scenario, Waypoint
    >>> scenario = Scenario(10.0, 10.0, np.array([[5.0, 0.0, 5.0, 8.0]]), (Waypoint("g", 9.0, 5.0, 1.0),),
    ...                     (AgentGroup(1.5, 5.0, 1.0, 2.0, 1, ("g",)),))
    >>> walls = Walls(scenario, 1)
    >>> p, reach = np.array([[4.0, 5.0]]), np.array([1.52])
    >>> force = walls.repulsion(p, 10.0, 0.2, 0.25, 1.5, reach)
    >>> bool(force[0, 0] < 0.0), walls.n_obstacles
    (True, 1)
    >>> direction = np.array([[1.0, 0.0]])
    >>> walls.steer_around(p, np.array([0]), np.array([[9.0, 5.0]]), direction)
    >>> bool(direction[0, 1] > 0.9)  # around the wall's upper end
    True
    >>> m_x, m_y, changed = resolve_move(0, p, 1.5, 0.0, 1.5, *walls.resolve_arguments())
    >>> changed, bool(4.0 + m_x < 5.0)  # stopped before the wall at x = 5
    (True, True)
"""

from __future__ import annotations

import math

import numba
import numpy as np

from uav_swarm.world.geometry import segments_cross
from uav_swarm.world.scenario import Scenario

__all__ = ["SKIN_M", "Cells", "Contacts", "Walls", "resolve_move"]

SKIN_M = 0.01  # moves stop this close to a wall's line, never on or beyond it
_MAX_SLIDES = 3  # wall corrections of one move per step before it is cancelled
_END_OFFSET_M = 1.0  # pedestrians going around a wall aim this far past its end
_HIDDEN_GOAL_PENALTY_M = 1e6  # detour cost added when the goal is hidden from a wall end
_EPS = 1e-12


class Walls:
    """The obstacle segments of a scenario followed by its four area bounds, for ``n`` pedestrians.

    Attributes:
        segments: ``(W, 4)`` wall segments; the last four are the area bounds.
        n_obstacles: Number of obstacle segments (the walls before the bounds).
    """

    def __init__(self, scenario: Scenario, n_pedestrians: int) -> None:
        w, h = scenario.width_m, scenario.height_m
        bounds = np.array([[0.0, 0.0, w, 0.0], [w, 0.0, w, h], [w, h, 0.0, h], [0.0, h, 0.0, 0.0]])
        self.segments = np.vstack([scenario.obstacles, bounds])
        self.segments.flags.writeable = False
        self.n_obstacles: int | np.ndarray = len(scenario.obstacles)  # (B,) in BatchedWalls
        self._is_obstacle = np.arange(len(self.segments)) < self.n_obstacles
        self._a = self.segments[:, :2].copy()
        self._w = self.segments[:, 2:] - self._a
        self._length = np.hypot(self._w[:, 0], self._w[:, 1])
        self._unit = self._w / np.maximum(self._length, _EPS)[:, None]
        self._inv_len2 = 1.0 / np.maximum(self._length**2, _EPS)
        self._per_wall = tuple(np.ascontiguousarray(c) for c in (self._a[:, 0], self._a[:, 1], self._w[:, 0],
                                                                  self._w[:, 1], self._inv_len2))
        self._goal_offset = np.zeros(len(self.segments), dtype=np.int64)  # waypoint index of a wall's world
        # one cell listing every wall
        self._cells = Cells(np.arange(len(self.segments), dtype=np.int64)[:, None],
                            np.zeros(n_pedestrians, dtype=np.int64), (1, 1), 0.0)
        self._contacts = Contacts(n_pedestrians, len(self.segments))
        # Aim points just past both ends of every obstacle, (M, 2, 2), and the cost of going on from
        # each to each waypoint, (M, 2, n_waypoints) (see steer_around): computed once.
        obstacles = self.segments[: self.n_obstacles]
        past = _END_OFFSET_M * self._unit[: self.n_obstacles]
        self._aims = np.stack([obstacles[:, :2] - past, obstacles[:, 2:] + past], axis=1)
        goals = np.array([[wp.x_m, wp.y_m] for wp in scenario.waypoints]).reshape(-1, 2)
        aims = self._aims.reshape(-1, 2)
        legs = np.concatenate(
            [np.repeat(aims, len(goals), axis=0), np.tile(goals, (len(aims), 1))], axis=1
        )  # (2M * n_waypoints, 4): aim -> goal
        hidden = (
            segments_cross(legs[:, None, :], obstacles[None, :, :]).any(axis=1) if len(legs) else legs[:, 0]
        )
        length = np.hypot(legs[:, 2] - legs[:, 0], legs[:, 3] - legs[:, 1])
        self._onward_cost = (length + _HIDDEN_GOAL_PENALTY_M * hidden).reshape(
            self.n_obstacles, 2, len(goals)
        )


    def repulsion(self, p: np.ndarray, strength_m_s2: float, range_m: float, radius_m: float, cutoff_m: float,
                  reach_m: np.ndarray) -> np.ndarray:
        """The wall repulsion ``A exp((r - d) / B)`` summed over the walls closer than ``cutoff_m``.

        Records each pedestrian's contacts, the walls closer than ``cutoff_m`` or ``reach_m``, for
        :meth:`steer_around` and :func:`resolve_move` at the same positions.

        Args:
            p: ``(N, 2)`` positions.
            strength_m_s2: ``A``.
            range_m: ``B``.
            radius_m: Pedestrian body radius ``r``.
            cutoff_m: Walls farther than this are ignored.
            reach_m: ``(N,)`` the farthest a wall can be to stop a pedestrian's move (:func:`resolve_move`).

        Returns:
            ``(N, 2)`` accelerations (a buffer overwritten by the next call).
        """
        c, cells = self._contacts, self._cells
        a_x, a_y, w_x, w_y, inv_len2 = self._per_wall
        count = _find_contacts(p, cells.walls, cells.base, cells.grid[0], cells.grid[1], cells.scale, a_x,
                               a_y, w_x, w_y, inv_len2, cutoff_m**2, reach_m * reach_m, c.start, c.wall, c.rx,
                               c.ry, c.dist2, c.dist, radius_m, range_m, c.arg)
        np.exp(c.arg[:count], out=c.exp[:count])
        self._cutoff2 = cutoff_m**2
        _wall_forces(c.start, c.dist2, c.dist, c.rx, c.ry, c.exp, self._cutoff2, strength_m_s2, c.force)
        return c.force

    def steer_around(self, p: np.ndarray, target: np.ndarray, goal_m: np.ndarray,
                     direction: np.ndarray) -> None:
        """Turn ``direction`` (in place) towards the end of the nearest obstacle hiding the goal.

        Of the two ends the pedestrian takes the cheaper ``|p - aim| + |aim - goal|``, where ``aim`` lies
        ``_END_OFFSET_M`` past the end, plus a huge penalty when an obstacle hides the goal from ``aim``:
        so at a corner of a closed shape it picks the end it can leave by. The obstacles are those closer
        than the cutoff of the last :meth:`repulsion` (at the same positions).

        Args:
            p: ``(N, 2)`` positions.
            target: ``(N,)`` index of each pedestrian's goal in ``scenario.waypoints``.
            goal_m: ``(N, 2)`` goal positions.
            direction: ``(N, 2)`` unit desired directions; rows of pedestrians without a goal are zero
                and stay so.
        """
        c = self._contacts
        _steer(p, target, goal_m, direction, c.start, c.wall, c.dist2, self._cutoff2, self._is_obstacle,
               self._a, self._unit, self._length, self._aims, self._onward_cost, self._goal_offset)

    def resolve_arguments(self) -> tuple[np.ndarray, ...]:
        """The last :meth:`repulsion`'s contacts and the walls' geometry.

        The tail of :func:`resolve_move`'s arguments: ``(start, wall, dist2, a, unit, length)``.
        """
        c = self._contacts
        return c.start, c.wall, c.dist2, self._a, self._unit, self._length


class Cells:
    """Square cells that list the walls near them, for the pedestrians of one or more worlds.

    Args:
        walls: ``(K, C)`` int64, the walls of each cell in ascending order, padded at the end with -1.
        base: ``(N,)`` int64, each pedestrian's world's first cell.
        grid: ``(columns, rows)`` of each world's cells (row-major).
        scale: Cells per metre (a position ``(x, y)`` is in cell ``(x scale, y scale)``, clipped to the grid).
    """

    def __init__(self, walls: np.ndarray, base: np.ndarray, grid: tuple[int, int], scale: float) -> None:
        self.walls, self.base, self.grid, self.scale = walls, base, grid, scale


class Contacts:
    """The walls within reach of each pedestrian (``start[k]:start[k + 1]``), buffers reused every step."""

    def __init__(self, n_pedestrians: int, most_per_pedestrian: int) -> None:
        size = n_pedestrians * most_per_pedestrian
        self.start = np.zeros(n_pedestrians + 1, dtype=np.int64)
        self.wall = np.empty(size, dtype=np.int64)
        self.rx, self.ry, self.dist2, self.dist, self.arg, self.exp = np.empty((6, size))
        self.force = np.empty((n_pedestrians, 2))


@numba.njit(cache=True, nogil=True)
def _find_contacts(p: np.ndarray, cell_walls: np.ndarray, cell_base: np.ndarray, columns: int, rows: int,
                   scale: float, a_x: np.ndarray, a_y: np.ndarray, w_x: np.ndarray, w_y: np.ndarray,
                   inv_len2: np.ndarray, cutoff2: float, reach2: np.ndarray, start: np.ndarray,
                   wall: np.ndarray, rx_out: np.ndarray, ry_out: np.ndarray, dist2_out: np.ndarray,
                   dist_out: np.ndarray, radius_m: float, range_m: float, arg: np.ndarray) -> int:
    """Record each pedestrian's walls closer than the cutoff or its reach; return their number.

    Per contact: the wall, the vector from its closest point to the pedestrian, the squared distance,
    the distance (at least ``_EPS``) and the exponent ``(r - d) / B`` of its repulsion.
    """
    count = 0
    for k in range(p.shape[0]):
        start[k] = count
        column = min(int(p[k, 0] * scale), columns - 1)  # positions are inside the area (>= 0)
        row = min(int(p[k, 1] * scale), rows - 1)
        cell = cell_base[k] + row * columns + column
        for slot in range(cell_walls.shape[0]):
            s = cell_walls[slot, cell]
            if s < 0:
                break
            rx, ry = p[k, 0] - a_x[s], p[k, 1] - a_y[s]
            t = rx * w_x[s] + ry * w_y[s]
            t *= inv_len2[s]
            t = min(max(t, 0.0), 1.0)
            rx -= t * w_x[s]  # from the closest wall point to the pedestrian
            ry -= t * w_y[s]
            dist2 = rx * rx + ry * ry
            if dist2 < cutoff2 or dist2 < reach2[k]:
                dist = max(math.sqrt(dist2), _EPS)
                wall[count], rx_out[count], ry_out[count], dist2_out[count] = s, rx, ry, dist2
                dist_out[count], arg[count] = dist, (radius_m - dist) / range_m
                count += 1
    start[p.shape[0]] = count
    return count


@numba.njit(cache=True, nogil=True)
def _wall_forces(start: np.ndarray, dist2: np.ndarray, dist: np.ndarray, rx: np.ndarray, ry: np.ndarray,
                 exp: np.ndarray, cutoff2: float, strength_m_s2: float, force: np.ndarray) -> None:
    """``force`` ``(N, 2)``: the repulsion summed over each pedestrian's contacts closer than the cutoff."""
    for k in range(force.shape[0]):
        force[k, 0], force[k, 1] = 0.0, 0.0
        for j in range(start[k], start[k + 1]):
            if dist2[j] < cutoff2:
                scale = strength_m_s2 * exp[j] / dist[j]
                force[k, 0] += scale * rx[j]
                force[k, 1] += scale * ry[j]


@numba.njit(cache=True, nogil=True)
def _steer(p: np.ndarray, target: np.ndarray, goal_m: np.ndarray, direction: np.ndarray, start: np.ndarray,
           wall: np.ndarray, dist2: np.ndarray, cutoff2: float, is_obstacle: np.ndarray, a: np.ndarray,
           unit: np.ndarray, length: np.ndarray, aims: np.ndarray, onward_cost: np.ndarray,
           goal_offset: np.ndarray) -> None:
    """:meth:`Walls.steer_around`, compiled: each pedestrian's nearest blocking obstacle, its better end."""
    for k in range(p.shape[0]):
        if direction[k, 0] == 0.0 and direction[k, 1] == 0.0:
            continue  # no goal; and area bounds hide nothing
        best, best_dist2 = -1, math.inf
        for j in range(start[k], start[k + 1]):
            s = wall[j]
            if dist2[j] >= cutoff2 or not is_obstacle[s]:
                continue
            to_px, to_py = p[k, 0] - a[s, 0], p[k, 1] - a[s, 1]
            to_gx, to_gy = goal_m[k, 0] - a[s, 0], goal_m[k, 1] - a[s, 1]
            side_p = unit[s, 0] * to_py - unit[s, 1] * to_px
            side_goal = unit[s, 0] * to_gy - unit[s, 1] * to_gx
            opposite = side_p * side_goal < 0  # the straight way crosses the wall's line ...
            t = side_p / (side_p - side_goal if opposite else 1.0)
            along_x = (to_px + t * (to_gx - to_px)) * unit[s, 0]
            along = along_x + (to_py + t * (to_gy - to_py)) * unit[s, 1]
            if opposite and 0.0 <= along <= length[s] and dist2[j] < best_dist2:  # ... within the wall
                best, best_dist2 = s, dist2[j]
        if best < 0:
            continue
        local = target[k] - goal_offset[best]
        cost = np.empty(2)
        for end in range(2):
            dx, dy = aims[best, end, 0] - p[k, 0], aims[best, end, 1] - p[k, 1]
            cost[end] = math.sqrt(dx * dx + dy * dy) + onward_cost[best, end, local]
        end = 1 if cost[1] < cost[0] else 0
        hx, hy = aims[best, end, 0] - p[k, 0], aims[best, end, 1] - p[k, 1]
        norm = max(math.sqrt(hx * hx + hy * hy), _EPS)
        direction[k, 0], direction[k, 1] = hx / norm, hy / norm


@numba.njit(cache=True, nogil=True)
def resolve_move(k: int, p: np.ndarray, m_x: float, m_y: float, step_m: float, start: np.ndarray,
                 wall: np.ndarray, dist2: np.ndarray, a: np.ndarray, unit: np.ndarray,
                 length: np.ndarray) -> tuple[float, float, bool]:
    """Pedestrian ``k``'s move ``(m_x, m_y)`` from ``p[k]`` corrected to cross no wall; whether it changed.

    A move violates a wall when it approaches the wall's line and ends beyond it or within ``SKIN_M`` of
    it, at a point within the wall's extent (grown by ``SKIN_M``). The earliest such contact is resolved
    by removing the normal part of the move (the pedestrian slides along the wall, stopping ``2 * SKIN_M``
    from its line); after ``_MAX_SLIDES`` rounds a move still violating a wall is cancelled. Positions
    never closer than ``SKIN_M``-ish to a wall therefore never cross one. The walls tested are ``k``'s
    contacts closer than ``step_m + 2 * SKIN_M`` (``step_m`` bounds ``|move|``; the remaining arguments
    are :meth:`Walls.resolve_arguments`, of the repulsion at ``p``).
    """
    reach = step_m + 2 * SKIN_M
    reach2 = reach * reach
    changed = False
    for attempt in range(_MAX_SLIDES + 1):
        first, first_t = -1, math.inf
        for j in range(start[k], start[k + 1]):
            if not dist2[j] < reach2:
                continue
            s = wall[j]
            u_x, u_y = unit[s, 0], unit[s, 1]
            rel_x, rel_y = p[k, 0] - a[s, 0], p[k, 1] - a[s, 1]
            s0 = u_x * rel_y - u_y * rel_x  # signed distance to the wall's line
            side = 1.0 if s0 >= 0 else -1.0
            n_x, n_y = side * -u_y, side * u_x  # towards the pedestrian
            s0 = side * s0
            m_normal = m_x * n_x + m_y * n_y
            t_line = min(max(s0 / max(-m_normal, _EPS), 0.0), 1.0)  # when the move meets the line
            c_x, c_y = rel_x + t_line * m_x, rel_y + t_line * m_y
            along = c_x * u_x + c_y * u_y
            within = along >= -SKIN_M and along <= length[s] + SKIN_M
            if m_normal < -_EPS and s0 + m_normal < SKIN_M and within and t_line < first_t:
                first, first_t = j, t_line
        if first < 0:
            break
        changed = True
        if attempt == _MAX_SLIDES:
            return 0.0, 0.0, True
        s = wall[first]
        u_x, u_y = unit[s, 0], unit[s, 1]
        rel_x, rel_y = p[k, 0] - a[s, 0], p[k, 1] - a[s, 1]
        s0 = u_x * rel_y - u_y * rel_x
        side = 1.0 if s0 >= 0 else -1.0
        n_x, n_y = side * -u_y, side * u_x
        s0 = side * s0
        m_normal = m_x * n_x + m_y * n_y
        new_normal = max(m_normal, min(0.0, 2 * SKIN_M - s0))
        m_x, m_y = m_x + (new_normal - m_normal) * n_x, m_y + (new_normal - m_normal) * n_y
    return m_x, m_y, changed
