"""The walls of B crowd copies for their stacked pedestrians: :class:`BatchedWalls` (for :mod:`crowd_batch`).

Each copy's area is cut into square cells that list the walls within reach of them
(:func:`walls_near_cells`); a pedestrian's wall distances are then taken only to the walls of its own
cell (:class:`~uav_swarm.world.walls.Cells`), so :class:`~uav_swarm.world.crowd_batch.BatchedCrowd` pays
per pedestrian for the few walls near it, not for every wall of every copy.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from uav_swarm.world.geometry import point_segment_distances
from uav_swarm.world.walls import Cells, Contacts, Walls

__all__ = ["BatchedWalls", "walls_near_cells"]

_FAR_M = 1e7  # padding walls sit here: never within any cutoff or step of a pedestrian


class BatchedWalls(Walls):
    """The walls of B copies for their stacked pedestrians (see the module docstring).

    Wall ``s`` of copy ``c`` has the index ``c * S + s`` in the per-wall arrays (``S`` the most walls of
    a copy; the slots a copy does not fill are padding, far away and listed by no cell). Each copy's area
    is cut into square cells; a cell lists, in ascending order, the walls within reach of it
    (``near_cells``), so each pedestrian meets its near walls in the order of its copy's :class:`Walls`
    (and the sums of forces are the same).

    Args:
        walls: Each copy's walls.
        copy_index: ``(N,)`` copy of each stacked pedestrian.
        waypoint_offsets: ``(B,)`` index of each copy's first waypoint in the global waypoint array.
        near_cells: Per copy, the ``(K_c, G)`` lists of walls near each cell (:func:`walls_near_cells`;
            cells row-major, ``G = grid[0] * grid[1]``).
        grid: ``(columns, rows)`` of the cells.
        cell_m: Side of a cell (m).

    Attributes:
        segments: ``(B * S, 4)`` segments, padded per copy.
        n_obstacles: ``(B,)`` obstacle count of each copy.
    """

    n_obstacles: np.ndarray

    def __init__(self, walls: Sequence[Walls], copy_index: np.ndarray, waypoint_offsets: np.ndarray,
                 near_cells: Sequence[np.ndarray], grid: tuple[int, int], cell_m: float) -> None:
        n_copies, slots = len(walls), max(len(w.segments) for w in walls)
        n_goals = max(1, max(w._onward_cost.shape[2] for w in walls))
        segments = np.full((n_copies, slots, 4), _FAR_M)
        unit = np.zeros((n_copies, slots, 2))
        length = np.zeros((n_copies, slots))
        inv_len2 = np.zeros((n_copies, slots))
        is_obstacle = np.zeros((n_copies, slots), dtype=bool)
        aims = np.zeros((n_copies, slots, 2, 2))
        onward = np.zeros((n_copies, slots, 2, n_goals))
        for c, w in enumerate(walls):
            n_walls, n_obstacles = len(w.segments), w.n_obstacles
            segments[c, :n_walls] = w.segments
            unit[c, :n_walls] = w._unit
            length[c, :n_walls] = w._length
            inv_len2[c, :n_walls] = w._inv_len2
            is_obstacle[c, :n_obstacles] = True
            aims[c, :n_obstacles] = w._aims
            onward[c, :n_obstacles, :, : w._onward_cost.shape[2]] = w._onward_cost
        self.segments = segments.reshape(-1, 4)
        self.segments.flags.writeable = False
        self.n_obstacles = np.array([w.n_obstacles for w in walls])
        self._a = self.segments[:, :2].copy()
        self._unit = unit.reshape(-1, 2)
        self._length = length.ravel()
        self._inv_len2 = inv_len2.ravel()
        self._is_obstacle = is_obstacle.ravel()
        self._aims = aims.reshape(-1, 2, 2)
        self._onward_cost = onward.reshape(-1, 2, n_goals)
        self._goal_offset = np.repeat(np.asarray(waypoint_offsets, dtype=np.int64), slots)
        w_xy = (self.segments[:, 2:] - self._a).T
        self._per_wall = (self._a[:, 0].copy(), self._a[:, 1].copy(), w_xy[0].copy(), w_xy[1].copy(),
                          self._inv_len2)
        # (K, B * G) global ids of the walls near each cell, ascending, padded with -1.
        k = max(len(near) for near in near_cells)
        lists = np.full((k, n_copies, grid[0] * grid[1]), -1, dtype=np.int64)
        for c, near in enumerate(near_cells):
            lists[:len(near), c] = np.where(near >= 0, near + c * slots, -1)
        self._cells = Cells(lists.reshape(k, -1), copy_index.astype(np.int64) * (grid[0] * grid[1]), grid,
                            1.0 / cell_m)
        self._contacts = Contacts(len(copy_index), k)


def walls_near_cells(
    segments: np.ndarray, grid: tuple[int, int], cell_m: float, reach_m: float
) -> np.ndarray:
    """``(K, G)`` ascending indices of the segments that may pass within ``reach_m`` of each cell, -1 padded.

    A superset: the segments within ``reach_m`` plus half the cell's diagonal of the cell's centre.

    Args:
        segments: ``(W, 4)`` wall segments.
        grid: ``(columns, rows)`` of cells, row-major; cell ``(i, j)`` is ``[i, i + 1] x [j, j + 1]`` times
            ``cell_m``.
        cell_m: Side of a cell (m).
        reach_m: Distance (m).
    """
    columns, rows = grid
    x, y = np.meshgrid((np.arange(columns) + 0.5) * cell_m, (np.arange(rows) + 0.5) * cell_m)
    centres = np.stack([x.ravel(), y.ravel()], axis=1)
    near = point_segment_distances(centres, segments) <= reach_m + cell_m / math.sqrt(2.0)  # (G, W)
    rank = np.cumsum(near, axis=1) - 1  # place of each near segment in its cell's list
    lists = np.full((max(1, int(rank[:, -1].max()) + 1 if len(segments) else 1), len(centres)), -1)
    cell, segment = np.nonzero(near)
    lists[rank[cell, segment], cell] = segment
    return lists
