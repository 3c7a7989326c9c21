"""Reachable sets: where a vehicle can be from now on, for the guard's two models (numpy).

- **Known kinematics, no delay** (the env, :func:`uav_swarm.world.uav.fly_step`): a UAV that brakes from
  now on flies a ray of its stopping distance (:func:`stopping_distance_m`, :func:`braking_paths`),
  polylines compared by :func:`path_distances_m`.
- **An autopilot flying to a point, late and measured with errors** (a real vehicle): the energy
  ``E = |x - c| + |v|^2 / (2 a)`` of a vehicle flying to ``c`` never grows (:mod:`uav_swarm.world.guard`
  proves it), so it stays within ``E`` of ``c``: :func:`energy_radius_m` bounds ``E`` from a
  measurement and its errors; :func:`axis_energy_radius_m` does so for an autopilot that limits its
  acceleration on each axis (PX4), whose energy never grows on each axis.
"""

from __future__ import annotations

import numpy as np

from uav_swarm.world.uav import UAVConfig

__all__ = ["axis_energy_radius_m", "braking_paths", "energy_radius_m", "path_distances_m",
           "segment_distances_m", "stopping_distance_m"]


def energy_radius_m(offset_m: np.ndarray, speed_m_s: np.ndarray, accel_m_s2: float, *,
                    position_error_m: float = 0.0, velocity_error_m_s: float = 0.0,
                    tracking_error_m: float = 0.0, jerk_m_s3: float = np.inf) -> np.ndarray:
    """Distance from its target ``c`` that a vehicle flying to ``c`` never exceeds again (its true position).

    ``|x - c| + e_p + 2 e_t + u^2 / (2 a) + 2 u a / j + a^3 / j^2`` with ``u = |v| + e_v``: the measured
    distance ``offset_m`` (..., 2) and speed, widened by the measurement's position and velocity errors
    and the tracking error (true position vs the autopilot's set point, once for the measurement and
    once for the position bounded), plus the run-on of a jerk-limited autopilot (0 for
    ``jerk_m_s3 = inf``): one still accelerating away at ``a`` when it is told to come back needs
    ``2 a / j`` to turn its acceleration round, over which it flies at most ``2 u a / j + a^3 / j^2``
    further than one that brakes at once (its speed grows by at most ``a^2 / 2j`` meanwhile).

    Examples:
        >>> float(energy_radius_m(np.array([3.0, 4.0]), np.array(10.0), 5.0))  # 5 m + 10^2 / (2 * 5)
        15.0
    """
    speed = np.asarray(speed_m_s, dtype=np.float64) + velocity_error_m_s
    distance = np.hypot(np.asarray(offset_m)[..., 0], np.asarray(offset_m)[..., 1])
    run_on = (2.0 * speed * accel_m_s2 / jerk_m_s3 + accel_m_s2**3 / jerk_m_s3**2) if np.isfinite(jerk_m_s3) \
        else 0.0
    return distance + position_error_m + 2.0 * tracking_error_m + speed**2 / (2.0 * accel_m_s2) + run_on


def axis_energy_radius_m(offset_m: np.ndarray, velocity_m_s: np.ndarray, accel_m_s2: float, *,
                         position_error_m: float = 0.0, velocity_error_m_s: float = 0.0,
                         tracking_error_m: float = 0.0, jerk_m_s3: float = np.inf) -> np.ndarray:
    """Distance from its target that an autopilot limited on each axis never exceeds again (true position).

    On each axis ``i`` the 1-D energy ``|x_i - c_i| + u_i^2 / (2 a)`` never grows
    (:mod:`uav_swarm.world.guard`, (B1x)), with the jerk run-on ``2 u_i a / j + a^3 / j^2`` on each axis
    (``u_i = |v_i| + e_v``): the vehicle stays in that box around ``c``, within the distance of its
    corner, ``hypot`` over the axes; the position error and the tracking error, vectors, are added once.

    Examples:
        >>> float(axis_energy_radius_m(np.array([3.0, 4.0]), np.array([0.0, 0.0]), 5.0))  # at rest: |offset|
        5.0
        >>> float(axis_energy_radius_m(np.array([0.0, 0.0]), np.array([10.0, 10.0]), 5.0))  # 10 m per axis
        14.142135623730951
    """
    offset = np.abs(np.asarray(offset_m, dtype=np.float64))
    speed = np.abs(np.asarray(velocity_m_s, dtype=np.float64)) + velocity_error_m_s
    run_on = (2.0 * speed * accel_m_s2 / jerk_m_s3 + accel_m_s2**3 / jerk_m_s3**2) if np.isfinite(jerk_m_s3) \
        else 0.0
    energy = offset + speed**2 / (2.0 * accel_m_s2) + run_on  # (..., 2): each axis
    return np.hypot(energy[..., 0], energy[..., 1]) + position_error_m + 2.0 * tracking_error_m


def stopping_distance_m(speed_m_s: np.ndarray, max_accel_m_s2: float, dt_s: float) -> np.ndarray:
    """Distance flown while braking at ``max_accel_m_s2`` in steps of ``dt_s`` (the kinematics of fly_step).

    After step ``j`` the speed is ``s - j a dt`` (while positive) and the UAV moves that times ``dt``.

    Examples:
        >>> float(stopping_distance_m(np.array(10.0), 5.0, 0.1))  # about v^2 / 2a = 10 m
        9.5
    """
    step = max_accel_m_s2 * dt_s
    steps = np.floor(np.asarray(speed_m_s, dtype=np.float64) / step)
    return dt_s * (steps * speed_m_s - step * steps * (steps + 1.0) / 2.0)


def braking_paths(positions_m: np.ndarray, velocities_m_s: np.ndarray, dt_s: float, config: UAVConfig,
                  upper_m: np.ndarray | None = None) -> np.ndarray:
    """(..., K, 3, 2) polyline each UAV flies if it brakes from now on: start, wall hit (or end), end.

    The ray of the stopping distance, clamped to the area ``[0, upper_m]`` as fly_step clamps (a UAV that
    meets a wall slides along it, never beyond the clamped end).
    """
    p = np.asarray(positions_m, dtype=np.float64)
    v = np.asarray(velocities_m_s, dtype=np.float64)
    speed = np.hypot(v[..., 0], v[..., 1])
    reach = stopping_distance_m(speed, config.max_accel_m_s2, dt_s)
    with np.errstate(invalid="ignore", divide="ignore"):
        unit = np.where(speed[..., None] > 1e-12, v / speed[..., None], 0.0)
    end = p + unit * reach[..., None]
    if upper_m is None:
        return np.stack([p, end, end], axis=-2)
    upper = np.asarray(upper_m, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        to_wall = np.where(unit > 0, (upper - p) / unit, np.where(unit < 0, -p / unit, np.inf))
    hit = np.minimum(to_wall.min(axis=-1), reach)
    wall = p + unit * hit[..., None]
    return np.stack([p, wall, np.clip(end, 0.0, upper)], axis=-2)


def path_distances_m(paths_a: np.ndarray, paths_b: np.ndarray) -> np.ndarray:
    """(..., A, B) least distance between polylines ``paths_a`` (..., A, P, 2) and ``paths_b`` (..., B, Q, 2).

    Examples:
        >>> a = np.array([[[0.0, 0.0], [10.0, 0.0]]])
        >>> b = np.array([[[5.0, 3.0], [5.0, 9.0]], [[5.0, -1.0], [5.0, 1.0]]])
        >>> path_distances_m(a, b).tolist()
        [[3.0, 0.0]]
    """
    a0, a1 = paths_a[..., :, None, :-1, None, :], paths_a[..., :, None, 1:, None, :]
    b0, b1 = paths_b[..., None, :, None, :-1, :], paths_b[..., None, :, None, 1:, :]
    return segment_distances_m(a0, a1, b0, b1).min(axis=(-2, -1))


def segment_distances_m(a0: np.ndarray, a1: np.ndarray, b0: np.ndarray, b1: np.ndarray) -> np.ndarray:
    """Least distance between segments ``[a0, a1]`` and ``[b0, b1]`` (broadcast, last axis x/y)."""
    d = np.minimum(np.minimum(_point_segment(a0, b0, b1), _point_segment(a1, b0, b1)),
                   np.minimum(_point_segment(b0, a0, a1), _point_segment(b1, a0, a1)))
    crossing = ((_orientation(a0, a1, b0) * _orientation(a0, a1, b1) < 0)
                & (_orientation(b0, b1, a0) * _orientation(b0, b1, a1) < 0))
    return np.where(crossing, 0.0, d)


def _point_segment(point: np.ndarray, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    along = end - start
    length2 = np.einsum("...c,...c->...", along, along)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(length2 > 0, np.einsum("...c,...c->...", point - start, along) / length2, 0.0)
    nearest = start + np.clip(t, 0.0, 1.0)[..., None] * along
    gap = point - nearest
    return np.sqrt(np.einsum("...c,...c->...", gap, gap))


def _orientation(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    ab, ac = b - a, c - a
    return ab[..., 0] * ac[..., 1] - ab[..., 1] * ac[..., 0]
