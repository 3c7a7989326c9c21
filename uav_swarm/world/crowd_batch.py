"""Many independent crowds stepped together: :class:`BatchedCrowd`, B copies of :class:`CrowdSim` in one.

The B copies form one disjoint world that :class:`CrowdSim`'s own step code advances, so a copy moves
bit for bit as the same crowd stepped alone (same equations, same operations in the same order):

- pedestrians of all copies are stacked, copy by copy, in one ``(N, 2)`` array (``copy_index``,
  ``offsets``); group, waypoint and route indices are made global by offsets;
- every copy's walls (obstacles, the four area bounds, then padding) get global indices; each copy's
  area is cut into square cells that list the walls within reach, and a pedestrian meets only the walls
  of its cell (:class:`~uav_swarm.world.walls_batch.BatchedWalls`): the cost is linear in B and does not
  grow with the number of walls far away;
- the pair forces come from the compiled kernel :func:`~uav_swarm.world.pair_forces.pair_forces` that
  :class:`CrowdSim` calls for one world, here over the B copies (``offsets``): it never pairs two copies,
  and sums each pedestrian's pair forces in an order fixed by its own copy.

Examples:
    >>> from uav_swarm.world.crowd import CrowdConfig
    >>> from uav_swarm.world.scenario import ScenarioConfig, random_scenario
    >>> small = ScenarioConfig(n_groups_min=1, n_groups_max=1, group_size_min=5, group_size_max=5)
    >>> rngs = [np.random.default_rng(seed) for seed in (0, 1)]
    >>> crowd = BatchedCrowd([CrowdSim(random_scenario(r, small), CrowdConfig(), r) for r in rngs])
    >>> crowd.step(3)
    >>> crowd.offsets.tolist(), crowd.positions_of(1).shape
    ([0, 5, 10], (5, 2))
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from uav_swarm.world.crowd import CrowdSim, _Scratch, _wall_reach_m
from uav_swarm.world.scenario import Scenario
from uav_swarm.world.walls import SKIN_M
from uav_swarm.world.walls_batch import BatchedWalls, walls_near_cells

__all__ = ["BatchedCrowd"]

_CELL_MARGIN_M = 0.5  # cells list the walls this much beyond the farthest a wall can matter
_CELL_M = 4.0  # side of the cells that list nearby walls ...
_MAX_CELLS_PER_SIDE = 256  # ... unless the area is larger than this many cells


class BatchedCrowd(CrowdSim):
    """B independent crowds (one config) stepped together; each copy moves as its :class:`CrowdSim` would.

    Build it from crowds just made by :class:`CrowdSim`'s constructor (so spawn positions and desired
    speeds are drawn as for a crowd alone); it takes over their current state. The arrays inherited from
    :class:`CrowdSim` (``positions_m``, ``velocities_m_s``, ``group_ids`` ...) hold all copies stacked.

    Args:
        sims: One crowd per copy, all with the same :class:`CrowdConfig`.

    Raises:
        ValueError: No crowd, or crowds with different configs.

    Attributes:
        scenarios: Each copy's scenario.
        time_s: ``(B,)`` simulated time of each copy since its crowd was built (s).
        copy_index: ``(N,)`` copy of each pedestrian.
        offsets: ``(B + 1,)`` copy ``c``'s pedestrians are ``offsets[c]:offsets[c + 1]``.
    """

    time_s: np.ndarray

    def __init__(self, sims: Sequence[CrowdSim]) -> None:
        if not len(sims):
            raise ValueError("BatchedCrowd needs at least one crowd")
        if any(sim.config != sims[0].config for sim in sims):
            raise ValueError("every crowd of a BatchedCrowd must have the same CrowdConfig")
        self.config = sims[0].config
        self.dt_s = self.config.dt_s
        self._near_cache: dict[int, tuple[tuple[int, int], np.ndarray]] = {}
        self._build(list(sims), [_state_of(sim) for sim in sims])

    @property
    def n_copies(self) -> int:
        """Number of copies B."""
        return len(self.scenarios)

    @property
    def current_waypoints(self) -> np.ndarray:
        """``(N,)`` index into its copy's waypoints of each pedestrian's target (-1: no route)."""
        target = self._route_flat[self._route_start[self.group_ids] + self._route_position]
        local = target - self._waypoint_offsets[self.copy_index]
        return np.where(self._has_route, local, -1)

    def positions_of(self, copy: int) -> np.ndarray:
        """``(N_c, 2)`` positions of copy ``copy`` (a read-only view)."""
        return self._positions[self.offsets[copy]:self.offsets[copy + 1]]

    def counts(self) -> np.ndarray:
        """``(B,)`` number of pedestrians of each copy."""
        return np.diff(self.offsets)

    def step(self, n_steps: int = 1, active: np.ndarray | None = None) -> None:
        """Advance the copies in ``active`` (all by default) by ``n_steps`` steps; the others stay put.

        Args:
            n_steps: Number of steps (>= 0).
            active: ``(B,)`` bool, the copies to advance.

        Raises:
            ValueError: ``n_steps`` is not a non-negative integer, or ``active`` not ``(B,)`` bool.
        """
        if active is None:
            super().step(n_steps)
            return
        active = np.asarray(active)
        if active.shape != (self.n_copies,) or active.dtype != bool:
            raise ValueError(f"active must be a ({self.n_copies},) bool array, got {active!r}")
        if active.all() or not active.any():
            super().step(n_steps if active.any() else 0)
            return
        frozen = ~active[self.copy_index]
        saved = [array[frozen] for array in (self._positions, self._velocities, self._route_position,
                                              self.waypoints_reached)]
        time_s = self.time_s.copy()
        super().step(n_steps)
        positions, velocities = self._positions.copy(), self._velocities.copy()
        for array, old in zip((positions, velocities, self._route_position, self.waypoints_reached), saved,
                              strict=True):
            array[frozen] = old
        for array in (positions, velocities):
            array.flags.writeable = False
        self._positions, self._velocities = positions, velocities
        self.time_s[~active] = time_s[~active]

    def replace(self, copies: Sequence[int] | np.ndarray, sims: Sequence[CrowdSim]) -> None:
        """Replace copies by new crowds (same config); the other copies keep their current state.

        Args:
            copies: Indices of the copies to replace (distinct).
            sims: One new crowd per index, as :class:`BatchedCrowd` takes them.

        Raises:
            ValueError: Lengths differ, an index is out of range or repeated, or a config differs.
        """
        copies = [int(c) for c in copies]
        if len(copies) != len(sims) or len(set(copies)) != len(copies):
            raise ValueError(f"replace needs distinct copies and a crowd each, got {copies} and {len(sims)}")
        if any(not 0 <= c < self.n_copies for c in copies):
            raise ValueError(f"copies {copies} out of range for {self.n_copies} copies")
        if any(sim.config != self.config for sim in sims):
            raise ValueError("a replacing crowd has another CrowdConfig than the batch")
        new = dict(zip(copies, sims, strict=True))
        parts = list(self._parts)
        states = [self._copy_state(c) for c in range(self.n_copies)]
        for c, sim in new.items():
            parts[c], states[c] = sim, _state_of(sim)
        self._build(parts, states)

    def _copy_state(self, c: int) -> tuple[np.ndarray, ...]:
        """Copy ``c``'s positions, velocities, route positions, waypoints reached and time."""
        s = slice(self.offsets[c], self.offsets[c + 1])
        return (self._positions[s], self._velocities[s], self._route_position[s],
                self.waypoints_reached[s], self.time_s[c])

    def _build(self, parts: list[CrowdSim], states: list[tuple[np.ndarray, ...]]) -> None:
        """Stack the static data of ``parts`` and the dynamic ``states`` into the global arrays."""
        self._parts = parts
        self.scenarios: tuple[Scenario, ...] = tuple(sim.scenario for sim in parts)
        counts = np.array([sim.n_pedestrians for sim in parts], dtype=np.int64)
        self.offsets = np.concatenate([[0], np.cumsum(counts)])
        self.copy_index = np.repeat(np.arange(len(parts)), counts)
        n_groups = np.array([len(sim._group_sizes) for sim in parts])
        n_goals = np.array([len(sim._waypoints_m) - 1 for sim in parts])  # without the dummy waypoint
        n_legs = np.array([len(sim._route_flat) - 1 for sim in parts])
        group_offsets, self._waypoint_offsets, leg_offsets = (
            np.concatenate([[0], np.cumsum(k)[:-1]]) for k in (n_groups, n_goals, n_legs))
        dummy = int(n_goals.sum())  # one trailing dummy waypoint for all copies (see CrowdSim)
        self.group_ids = np.concatenate([sim.group_ids + group_offsets[c] for c, sim in enumerate(parts)])
        self.group_ids.flags.writeable = False
        self._group_sizes = np.concatenate([sim._group_sizes for sim in parts])
        self._group_radius_m = np.concatenate([sim._group_radius_m for sim in parts])
        self._waypoints_m = np.vstack([sim._waypoints_m[:-1] for sim in parts] + [np.zeros((1, 2))])
        self._waypoint_radius_m = np.concatenate([sim._waypoint_radius_m[:-1] for sim in parts] + [[1.0]])
        self._route_length = np.concatenate([sim._route_length for sim in parts])
        self._route_start = np.concatenate([sim._route_start + leg_offsets[c] for c, sim in enumerate(parts)])
        self._route_flat = np.concatenate(
            [sim._route_flat[:-1] + self._waypoint_offsets[c] for c, sim in enumerate(parts)] + [[dummy]]
        ).astype(np.int64)
        self._has_route = np.concatenate([sim._has_route for sim in parts])
        self.desired_speeds_m_s = np.concatenate([sim.desired_speeds_m_s for sim in parts])
        self.max_speeds_m_s = np.concatenate([sim.max_speeds_m_s for sim in parts])
        for array in (self.desired_speeds_m_s, self.max_speeds_m_s):
            array.flags.writeable = False
        self._wall_reach_m = _wall_reach_m(self.max_speeds_m_s, self.dt_s)
        positions, velocities, route_position, reached, time_s = zip(*states, strict=True)
        self._positions = np.concatenate(positions).reshape(-1, 2)
        self._velocities = np.concatenate(velocities).reshape(-1, 2)
        for array in (self._positions, self._velocities):
            array.flags.writeable = False
        self._route_position = np.concatenate(route_position).astype(np.int64)
        self.waypoints_reached = np.concatenate(reached).astype(np.int64)
        self.time_s = np.array(time_s, dtype=np.float64)
        self._walls = self._batched_walls(parts)
        self._world_starts = self.offsets
        self._sweep_order = np.arange(self.offsets[-1], dtype=np.int64)
        self._scratch = _Scratch(self._route_length[self.group_ids])

    def _batched_walls(self, parts: list[CrowdSim]) -> BatchedWalls:
        """The walls of ``parts``, with the cell lists of the crowds seen before taken from the cache."""
        cfg = self.config
        reach = max(cfg.neighbour_cutoff_m, cfg.max_speed_m_s * cfg.dt_s + 2 * SKIN_M) + _CELL_MARGIN_M
        width, height = (max(getattr(s, name) for s in self.scenarios) for name in ("width_m", "height_m"))
        cell_m = max(_CELL_M, max(width, height) / _MAX_CELLS_PER_SIDE)
        grid = (math.ceil(width / cell_m), math.ceil(height / cell_m))
        near, cache = [], {}
        for sim in parts:
            known = self._near_cache.get(id(sim))
            if known is None or known[0] != grid:
                known = (grid, walls_near_cells(sim._walls.segments, grid, cell_m, reach))
            cache[id(sim)] = known
            near.append(known[1])
        self._near_cache = cache
        walls = [sim._walls for sim in parts]
        return BatchedWalls(walls, self.copy_index, self._waypoint_offsets, near, grid, cell_m)


def _state_of(sim: CrowdSim) -> tuple[Any, ...]:
    """A crowd's positions, velocities, route positions, waypoints reached and time."""
    return sim._positions, sim._velocities, sim._route_position, sim.waypoints_reached, sim.time_s
