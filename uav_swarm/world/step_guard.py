"""The step guard: commands that keep every pair of UAVs at least the minimum separation apart (numpy).

The guard (:func:`guard_commands`) keeps every pair apart under the kinematics of
:func:`uav_swarm.world.uav.fly_step`. Its invariant: the *braking paths* of any two UAVs (the polyline a UAV
would fly if it braked at ``max_accel_m_s2`` from now on: a ray of its stopping distance, clamped to the
area) are at least the minimum apart. A UAV's command is accepted only if the path it implies (this step's
segment, then braking from the new state) keeps the minimum to every other UAV's path: the new path of a
UAV already decided this step, the current braking path of one not yet decided (which contains whatever
that UAV does next if it brakes). A refused UAV tries its command turned by 45 and 90 degrees either way
(it routes around), then brakes, whose path lies inside its current one. By induction no two UAVs
ever come closer than the minimum, whatever the commands, provided they start apart at rest.

Examples:
    >>> import numpy as np
    >>> from uav_swarm.world.separation import closest_distances_m
    >>> from uav_swarm.world.uav import UAVConfig, fly_step, waypoint_velocity
    >>> config, area = UAVConfig(min_separation_m=5.0), np.array([100.0, 100.0])
    >>> p, v = np.array([[20.0, 50.0], [80.0, 50.0]]), np.zeros((2, 2))
    >>> targets = p[::-1].copy()  # a head-on swap
    >>> closest = np.inf
    >>> for _ in range(400):
    ...     command, held = guard_commands(p, v, waypoint_velocity(p, targets, 0.1, config), 0.1, config,
    ...                                    upper_m=area)
    ...     p, v = fly_step(p, v, command, 0.1, config, area)
    ...     closest = min(closest, float(closest_distances_m(p)))
    >>> closest >= 5.0, bool(np.allclose(p, targets, atol=0.1))
    (True, True)
"""

from __future__ import annotations

import numpy as np

from uav_swarm.world.guard.kernels import decide_world
from uav_swarm.world.guard.reach import (
    braking_paths,
    path_distances_m,
    segment_distances_m,
    stopping_distance_m,
)
from uav_swarm.world.separation import pair_distances_m, required_distances_m
from uav_swarm.world.uav import UAVConfig, fly_step

__all__ = ["braking_paths", "guard_commands", "path_distances_m", "stopping_distance_m"]



def guard_commands(positions_m: np.ndarray, velocities_m_s: np.ndarray, command_m_s: np.ndarray, dt_s: float,
                   config: UAVConfig, altitudes_m: np.ndarray | None = None, *,
                   upper_m: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Commands that keep every pair of UAVs at least ``config.min_separation_m`` apart (module docstring).

    Args:
        positions_m: (..., K, 2) positions in metres.
        velocities_m_s: (..., K, 2) velocities in m/s.
        command_m_s: (..., K, 2) the velocity commands wanted (from the waypoint controller or a policy).
        dt_s: The step the commands will be flown for (s).
        config: Flight limits and the minimum separation (0: every command passes).
        altitudes_m: (K,) the UAVs' altitudes (layers), or None for one altitude.
        upper_m: (2,) the area's upper corner, as given to fly_step (None: no border).

    Returns:
        The safe commands (..., K, 2) and ``held`` (..., K) bool: True where a UAV did not get its command
        (it was turned around a neighbour or braked). UAV ``k`` has priority over UAV ``k + 1``.
    """
    p = np.asarray(positions_m, dtype=np.float64)
    v = np.asarray(velocities_m_s, dtype=np.float64)
    wanted = np.asarray(command_m_s, dtype=np.float64)
    k = p.shape[-2]
    held: np.ndarray = np.zeros(p.shape[:-1], dtype=bool)
    if k < 2 or config.min_separation_m <= 0:
        return wanted.copy(), held
    batch = p.shape[:-2]
    p, v, wanted = (a.reshape(-1, k, 2) for a in (p, v, wanted))
    held = held.reshape(-1, k)
    area = np.full(2, np.inf) if upper_m is None else np.asarray(upper_m, dtype=np.float64)
    pairs = required_distances_m(config.min_separation_m, altitudes_m, k)
    required = np.broadcast_to(pairs, (p.shape[0], k, k))
    p_next, v_next = fly_step(p, v, wanted, dt_s, config, area)
    current = _paths(p, p, v, dt_s, config, area)  # (B, K, 4, 2): braking from now
    proposed = _paths(p, p_next, v_next, dt_s, config, area)
    # Every path lies within its reach of the UAV's position: pairs whose discs keep the gap need no geometry.
    centre = pair_distances_m(p)
    accel = config.max_accel_m_s2
    reach_now = stopping_distance_m(np.linalg.norm(v, axis=-1), accel, dt_s)
    reach_next = (np.linalg.norm(p_next - p, axis=-1)
                  + stopping_distance_m(np.linalg.norm(v_next, axis=-1), accel, dt_s))
    # A pair already closer than the minimum (a start inside it) may only keep or widen its gap.
    threshold = required.copy()
    near = centre - reach_now[..., :, None] - reach_now[..., None, :] < required
    if near.any():
        b, i, j = np.nonzero(near)
        threshold[b, i, j] = np.minimum(required[b, i, j], _pair_gaps(current, current, b, i, j) - 1e-9)
    clear = np.ones_like(near)
    for others, reach in ((proposed, reach_next), (current, reach_now)):
        near = centre - reach_next[..., :, None] - reach[..., None, :] < threshold
        if near.any():
            b, i, j = np.nonzero(near)
            clear[b, i, j] &= _pair_gaps(proposed, others, b, i, j) >= threshold[b, i, j]
    tight = ~clear.all(axis=(-2, -1))
    safe = wanted.copy()
    if tight.any():
        safe[tight], held[tight] = _sequential(p[tight], v[tight], wanted[tight], current[tight],
                                               threshold[tight], dt_s, config, area)
    return safe.reshape(*batch, k, 2), held.reshape(*batch, k)


def _pair_gaps(paths_a: np.ndarray, paths_b: np.ndarray, world: np.ndarray, first: np.ndarray,
               second: np.ndarray) -> np.ndarray:
    """(M,) least distance between ``paths_a[world, first]`` and ``paths_b[world, second]`` (polylines)."""
    a, b = paths_a[world, first], paths_b[world, second]  # (M, P, 2)
    gaps = segment_distances_m(a[:, :-1, None], a[:, 1:, None], b[:, None, :-1], b[:, None, 1:])
    return gaps.min(axis=(-2, -1))


def _paths(p: np.ndarray, p_next: np.ndarray, v_next: np.ndarray, dt_s: float, config: UAVConfig,
           area: np.ndarray) -> np.ndarray:
    """(..., K, 4, 2): the segment from ``p`` to ``p_next``, then braking from ``(p_next, v_next)``."""
    return np.concatenate([p[..., None, :], braking_paths(p_next, v_next, dt_s, config, area)], axis=-2)


def _sequential(p: np.ndarray, v: np.ndarray, wanted: np.ndarray, current: np.ndarray, threshold: np.ndarray,
                dt_s: float, config: UAVConfig, area: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Decide UAV by UAV (priority = index) for the worlds where some command conflicts (compiled)."""
    safe, held = np.zeros_like(wanted), np.zeros(wanted.shape[:2], dtype=bool)
    for world in range(p.shape[0]):
        safe[world], held[world] = decide_world(p[world], v[world], wanted[world], current[world],
                                                threshold[world], dt_s, config.max_accel_m_s2,
                                                config.max_speed_m_s, area)
    return safe, held
