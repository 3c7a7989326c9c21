"""Flights predicted step by step with the env's own kinematics, and their closest approach (numba).

A transition's prediction is not a model of the flight but the flight itself: :func:`fly_track` repeats,
step for step, what :func:`uav_swarm.world.uav.waypoint_velocity` and :func:`uav_swarm.world.uav.fly_step`
do to one UAV (the command ``min(max_speed, d / dt, sqrt(2 a d))`` toward the waypoint, the speed cap, one
acceleration cap shared by braking, turning and speeding up, the clamp to the area), so speed across the
line to the target, speed away from it and the lag of the controller are all in it. A UAV flies no
differently because of another (no guard), so each flight is computed alone.

A *track* is the positions after ``0, 1, 2, ...`` steps; it *settles* at the first step from which the UAV
is at rest on its waypoint (it never moves again). A transition flies each UAV on a *head* (toward its hold
point, or straight to its target) and, from its departure step, a *tail* (from rest at the hold point to
the target): the tail is the same flight whatever the departure, shifted in time, so every departure
costs one lookup. Between two steps the env moves each UAV on a straight line, so the distance of two
UAVs between steps is exact (:func:`segment_gap`).

Examples:
    >>> from uav_swarm.world.uav import UAVConfig, fly_step, waypoint_velocity
    >>> config = UAVConfig()
    >>> track, settle = fly_track(np.zeros(2), np.array([8.0, 0.0]), np.array([0.0, 30.0]), config, 0.1, 200)
    >>> p, v = np.zeros((1, 2)), np.array([[8.0, 0.0]])
    >>> for _ in range(settle):
    ...     command = waypoint_velocity(p, np.array([[0.0, 30.0]]), 0.1, config)
    ...     p, v = fly_step(p, v, command, 0.1, config, np.array([np.inf, np.inf]))
    >>> bool(np.allclose(track[settle], p[0], atol=1e-12)), track[settle].round(6).tolist()
    (True, [0.0, 30.0])
"""

from __future__ import annotations

import math

import numba
import numpy as np

from uav_swarm.world.uav import UAVConfig

__all__ = ["SETTLED_M", "fly_track", "segment_gap", "track_at"]

SETTLED_M = 1e-9
"""A UAV this close to its waypoint, at a speed under this many m/s, is at rest (it never moves again)."""


def fly_track(position_m: np.ndarray, velocity_m_s: np.ndarray, waypoint_m: np.ndarray, config: UAVConfig,
              step_s: float, max_steps: int, upper_m: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    """``((S + 1, 2) positions, settle step)`` of one UAV flown to ``waypoint_m`` by the env's kinematics.

    ``upper_m``: the area's upper corner (the env clamps to ``[0, upper_m]``; None: no border). A flight
    that does not settle within ``max_steps`` returns ``max_steps``.
    """
    out = np.empty((max_steps + 1, 2))
    box = np.empty(4)
    upper = np.full(2, np.inf) if upper_m is None else np.asarray(upper_m, np.float64)
    settle = _fly(float(position_m[0]), float(position_m[1]), float(velocity_m_s[0]), float(velocity_m_s[1]),
                  float(waypoint_m[0]), float(waypoint_m[1]), step_s, config.max_speed_m_s,
                  config.max_accel_m_s2, upper[0], upper[1], out, box)
    return out[:settle + 1], settle


@numba.njit(cache=True, nogil=True)
def _fly(x: float, y: float, vx: float, vy: float, tx: float, ty: float, dt: float, vmax: float, a: float,
         ux: float, uy: float, out: np.ndarray, box: np.ndarray) -> int:  # pragma: no cover - compiled
    """Fill ``out`` with the track to ``(tx, ty)`` until it settles; returns the settle step.

    ``box`` gets the track's bounding box ``(x_min, x_max, y_min, y_max)``.
    """
    out[0, 0], out[0, 1] = x, y
    box[0], box[1], box[2], box[3] = x, x, y, y
    steps = out.shape[0] - 1
    for n in range(steps):
        dx, dy = tx - x, ty - y
        d = math.sqrt(dx * dx + dy * dy)
        if d < SETTLED_M and vx * vx + vy * vy < SETTLED_M * SETTLED_M:
            return n
        cx, cy = 0.0, 0.0
        if d > 1e-9:  # waypoint_velocity
            speed = min(min(vmax, d / dt), math.sqrt(2.0 * a * d))
            cx, cy = dx * (speed / d), dy * (speed / d)
        scale = vmax / max(math.hypot(cx, cy), vmax)  # fly_step: the speed cap, then the acceleration cap
        ex, ey = cx * scale - vx, cy * scale - vy
        scale = a * dt / max(math.hypot(ex, ey), a * dt)
        vx, vy = vx + ex * scale, vy + ey * scale
        x, y = x + vx * dt, y + vy * dt
        if x < 0.0 or x > ux:
            x, vx = min(max(x, 0.0), ux), 0.0
        if y < 0.0 or y > uy:
            y, vy = min(max(y, 0.0), uy), 0.0
        out[n + 1, 0], out[n + 1, 1] = x, y
        box[0], box[1] = min(box[0], x), max(box[1], x)
        box[2], box[3] = min(box[2], y), max(box[3], y)
    return steps


@numba.njit(cache=True, nogil=True)
def track_at(head: np.ndarray, head_settle: int, depart: int, tail: np.ndarray, tail_settle: int, n: int
             ) -> tuple[float, float]:  # pragma: no cover - compiled
    """Position after ``n`` steps of a UAV on ``head`` leaving on ``tail`` at step ``depart`` (-1: never)."""
    if depart < 0 or n <= depart:
        i = min(n, head_settle)
        return head[i, 0], head[i, 1]
    i = min(n - depart, tail_settle)
    return tail[i, 0], tail[i, 1]


@numba.njit(cache=True, nogil=True)
def segment_gap(ax: float, ay: float, bx: float, by: float) -> float:  # pragma: no cover - compiled
    """Least norm of a relative position moving linearly from ``(ax, ay)`` to ``(bx, by)`` over one step."""
    sx, sy = bx - ax, by - ay
    length2 = sx * sx + sy * sy
    u = 0.0 if length2 <= 0.0 else min(max(-(ax * sx + ay * sy) / length2, 0.0), 1.0)
    x, y = ax + u * sx, ay + u * sy
    return math.sqrt(x * x + y * y)
