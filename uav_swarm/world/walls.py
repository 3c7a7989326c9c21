"""Hard, repulsive walls for a crowd: obstacle segments plus the area bounds, vectorised over pedestrians.

:class:`Walls` answers the three questions the crowd asks of its walls every step:

- :meth:`Walls.repulsion`: distances to every wall and the summed exponential wall repulsion;
- :meth:`Walls.steer_around`: where to head when a wall hides the goal (a pedestrian near such a wall
  aims just past the wall end with the shorter detour from which the goal is visible, like a bug
  algorithm; pure social force would jam a crowd against a wall standing across its way);
- :meth:`Walls.resolve`: correct moves so that no pedestrian crosses a wall (the move loses its normal
  component and slides along the wall; a move that still collides after a few corrections is cancelled).
"""

from __future__ import annotations

import numpy as np

from uav_swarm.world.geometry import segments_cross
from uav_swarm.world.scenario import Scenario

__all__ = ["SKIN_M", "Walls"]

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
        self._obstacles = scenario.obstacles
        self._is_obstacle = np.arange(len(self.segments)) < self.n_obstacles
        self._a = self.segments[:, :2].copy()
        self._w = self.segments[:, 2:] - self._a
        self._length = np.hypot(self._w[:, 0], self._w[:, 1])
        self._unit = self._w / np.maximum(self._length, _EPS)[:, None]
        inv_len2 = 1.0 / np.maximum(self._length**2, _EPS)
        # (W, 1) columns broadcast over (W, N) buffers: large temporaries cost more in page faults
        # than in arithmetic, so the distance computation works in place.
        self._columns = tuple(
            c[:, None] for c in (self._a[:, 0], self._a[:, 1], self._w[:, 0], self._w[:, 1])
        )
        self._inv_len2 = inv_len2[:, None]
        self._buffers = np.empty((4, len(self.segments), n_pedestrians))
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

    def repulsion(
        self, p: np.ndarray, strength_m_s2: float, range_m: float, radius_m: float, cutoff_m: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Distances to the walls and the wall repulsion ``A exp((r - d) / B)`` summed over near walls.

        Args:
            p: ``(N, 2)`` positions.
            strength_m_s2: ``A``.
            range_m: ``B``.
            radius_m: Pedestrian body radius ``r``.
            cutoff_m: Walls farther than this are ignored.

        Returns:
            ``(W, N)`` squared distances (a buffer overwritten by the next call), ``(N, 2)`` accelerations,
            and the flat indices ``wall * N + pedestrian`` of the pairs closer than ``cutoff_m``.
        """
        n = len(p)
        rx, ry, t, tmp = self._buffers
        ax, ay, wx, wy = self._columns
        np.subtract(p[:, 0], ax, out=rx)
        np.subtract(p[:, 1], ay, out=ry)
        np.multiply(rx, wx, out=t)
        t += np.multiply(ry, wy, out=tmp)
        t *= self._inv_len2
        np.clip(t, 0.0, 1.0, out=t)
        rx -= np.multiply(t, wx, out=tmp)  # rx, ry: from the closest wall point to the pedestrian
        ry -= np.multiply(t, wy, out=tmp)
        dist2 = np.multiply(rx, rx, out=t)
        dist2 += np.multiply(ry, ry, out=tmp)
        near = np.flatnonzero(dist2 < cutoff_m**2)
        force = np.zeros((n, 2))
        if len(near):
            ped = near % n
            dist = np.maximum(np.sqrt(dist2.ravel()[near]), _EPS)
            scale = strength_m_s2 * np.exp((radius_m - dist) / range_m) / dist
            force[:, 0] = np.bincount(ped, scale * rx.ravel()[near], n)
            force[:, 1] = np.bincount(ped, scale * ry.ravel()[near], n)
        return dist2, force, near

    def steer_around(
        self,
        p: np.ndarray,
        target: np.ndarray,
        goal_m: np.ndarray,
        direction: np.ndarray,
        dist2: np.ndarray,
        near: np.ndarray,
    ) -> None:
        """Turn ``direction`` (in place) towards the end of the nearest obstacle hiding the goal.

        Of the two ends the pedestrian takes the cheaper ``|p - aim| + |aim - goal|``, where ``aim`` lies
        ``_END_OFFSET_M`` past the end, plus a huge penalty when an obstacle hides the goal from ``aim``:
        so at a corner of a closed shape it picks the end it can leave by.

        Args:
            p: ``(N, 2)`` positions.
            target: ``(N,)`` index of each pedestrian's goal in ``scenario.waypoints``.
            goal_m: ``(N, 2)`` goal positions.
            direction: ``(N, 2)`` unit desired directions; rows of pedestrians without a goal are zero
                and stay so.
            dist2: Squared distances from :meth:`repulsion`.
            near: Near pairs from :meth:`repulsion`.
        """
        slot, ped = np.divmod(near, len(p))
        wall = self._wall_of(slot, ped)
        keep = self._is_obstacle[wall] & (direction[ped] != 0).any(axis=1)  # area bounds hide nothing
        wall, ped, near = wall[keep], ped[keep], near[keep]
        a, unit = self._a[wall], self._unit[wall]
        to_p, to_goal = p[ped] - a, goal_m[ped] - a
        side_p = unit[:, 0] * to_p[:, 1] - unit[:, 1] * to_p[:, 0]
        side_goal = unit[:, 0] * to_goal[:, 1] - unit[:, 1] * to_goal[:, 0]
        opposite = side_p * side_goal < 0  # the straight way crosses the wall's line ...
        t = side_p / np.where(opposite, side_p - side_goal, 1.0)
        along_x = (to_p[:, 0] + t * (to_goal[:, 0] - to_p[:, 0])) * unit[:, 0]
        along = along_x + (to_p[:, 1] + t * (to_goal[:, 1] - to_p[:, 1])) * unit[:, 1]
        blocked = opposite & (along >= 0.0) & (along <= self._length[wall])  # ... within the wall
        if not blocked.any():
            return
        wall, ped = wall[blocked], ped[blocked]
        order = np.lexsort((dist2.ravel()[near[blocked]], ped))
        first = order[np.unique(ped[order], return_index=True)[1]]  # the nearest blocking wall
        wall, ped = wall[first], ped[first]
        aims = self._aims[wall]  # (K, 2 ends, 2)
        cost = np.linalg.norm(aims - p[ped][:, None, :], axis=2) + self._onward_cost_of(wall, target[ped])
        heading = aims[np.arange(len(ped)), np.argmin(cost, axis=1)] - p[ped]
        direction[ped] = heading / np.maximum(np.linalg.norm(heading, axis=1), _EPS)[:, None]

    def resolve(self, p: np.ndarray, move: np.ndarray, dist2: np.ndarray, step_m: np.ndarray) -> np.ndarray:
        """Correct ``move`` in place so that no move crosses a wall; return the indices of changed moves.

        A move violates a wall when it approaches the wall's line and ends beyond it or within
        ``SKIN_M`` of it, at a point within the wall's extent (grown by ``SKIN_M``). The earliest such
        contact of each pedestrian is resolved by removing the normal part of the move (the pedestrian
        slides along the wall, stopping ``2 * SKIN_M`` from its line); after ``_MAX_SLIDES`` rounds the
        moves still violating a wall are cancelled. Positions never closer than ``SKIN_M``-ish to a wall
        therefore never cross one.

        Args:
            p: ``(N, 2)`` positions before the move.
            move: ``(N, 2)`` displacements, corrected in place.
            dist2: Squared distances from :meth:`repulsion` at ``p``.
            step_m: ``(N,)`` upper bounds of ``|move|`` (walls farther away are not tested).
        """
        reach = step_m + 2 * SKIN_M
        slot, ped = np.divmod(np.flatnonzero(dist2 < reach * reach), len(p))
        wall = self._wall_of(slot, ped)
        changed: list[np.ndarray] = []
        for attempt in range(_MAX_SLIDES + 1):
            if not len(ped):
                break
            unit = self._unit[wall]
            rel = p[ped] - self._a[wall]
            m = move[ped]
            s0 = unit[:, 0] * rel[:, 1] - unit[:, 1] * rel[:, 0]  # signed distance to the wall's line
            side = np.where(s0 >= 0, 1.0, -1.0)
            normal = side[:, None] * np.stack([-unit[:, 1], unit[:, 0]], axis=1)  # towards the pedestrian
            s0 = side * s0
            m_normal = m[:, 0] * normal[:, 0] + m[:, 1] * normal[:, 1]
            t_line = np.clip(s0 / np.maximum(-m_normal, _EPS), 0.0, 1.0)  # when the move meets the line
            contact = rel + t_line[:, None] * m
            along = contact[:, 0] * unit[:, 0] + contact[:, 1] * unit[:, 1]
            within = (along >= -SKIN_M) & (along <= self._length[wall] + SKIN_M)
            hit = (m_normal < -_EPS) & (s0 + m_normal < SKIN_M) & within
            if not hit.any():
                break
            hit_ped = ped[hit]
            if attempt == _MAX_SLIDES:
                move[hit_ped] = 0.0
                changed.append(hit_ped)
                break
            order = np.lexsort((t_line[hit], hit_ped))  # first contact of each pedestrian
            k = np.flatnonzero(hit)[order[np.unique(hit_ped[order], return_index=True)[1]]]
            new_normal = np.maximum(m_normal[k], np.minimum(0.0, 2 * SKIN_M - s0[k]))
            move[ped[k]] = m[k] + (new_normal - m_normal[k])[:, None] * normal[k]
            changed.append(ped[k])
            keep = np.isin(ped, ped[k])
            ped, wall = ped[keep], wall[keep]
        return np.unique(np.concatenate(changed)) if changed else np.zeros(0, dtype=np.int64)

    def _wall_of(self, slot: np.ndarray, ped: np.ndarray) -> np.ndarray:
        """Index into the per-wall arrays of the wall in distance row ``slot`` for pedestrian ``ped``."""
        return slot

    def _onward_cost_of(self, wall: np.ndarray, target: np.ndarray) -> np.ndarray:
        """``(K, 2)`` cost of going on from both aims of ``wall`` to waypoint ``target``."""
        return self._onward_cost[wall, :, target]
