"""Compiled kernels of the env's guard: one world's decision, UAV after UAV (numba, scalar loops).

:func:`decide_world` is :func:`uav_swarm.world.step_guard.guard_commands`'s sequential decision for one
world where some command conflicts: the same kinematics as :func:`uav_swarm.world.uav.fly_step`, the
same braking paths as :func:`uav_swarm.world.guard.reach.braking_paths` (4-point polylines: the step,
then braking clamped to the area), the same options (the command, turned by 45 and 90 degrees either
way, then braking) and the same acceptance (every gap to the decided paths at least its threshold), in
loops over scalars instead of arrays of a few elements.

Examples:
    >>> import numpy as np
    >>> p, v = np.array([[0.0, 0.0], [5.5, 0.0]]), np.array([[2.0, 0.0], [-2.0, 0.0]])  # closing
    >>> current = np.zeros((2, 4, 2))  # their braking paths: 0.3 m on from each
    >>> current[0, 1:, 0], current[1, :, 0] = 0.3, [5.5, 5.5, 5.2, 5.2]
    >>> safe, held = decide_world(p, v, np.array([[10.0, 0.0], [-10.0, 0.0]]), current, np.full((2, 2), 4.5),
    ...                           0.1, 5.0, 10.0, np.array([100.0, 100.0]))
    >>> held.tolist(), safe.round(2).tolist()  # the first turns away, the second brakes
    ([True, True], [[7.07, 7.07], [0.0, 0.0]])
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["decide_world", "TURNS_RAD"]

TURNS_RAD = np.array([0.0, math.pi / 4, -math.pi / 4, math.pi / 2, -math.pi / 2])
"""The command, then turned round a neighbour; braking is the last option."""


@numba.njit(cache=True, nogil=True)
def _point_segment(px: float, py: float, ax: float, ay: float, bx: float, by: float) -> float:
    dx, dy = bx - ax, by - ay
    length2 = dx * dx + dy * dy
    t = 0.0
    if length2 > 0:
        t = min(max(((px - ax) * dx + (py - ay) * dy) / length2, 0.0), 1.0)
    gx, gy = px - (ax + t * dx), py - (ay + t * dy)
    return math.sqrt(gx * gx + gy * gy)


@numba.njit(cache=True, nogil=True)
def _orientation(ax: float, ay: float, bx: float, by: float, cx: float, cy: float) -> float:
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)


@numba.njit(cache=True, nogil=True)
def _segments(a0: np.ndarray, a1: np.ndarray, b0: np.ndarray, b1: np.ndarray) -> float:
    """Least distance between segments ``[a0, a1]`` and ``[b0, b1]``."""
    if (_orientation(a0[0], a0[1], a1[0], a1[1], b0[0], b0[1])
            * _orientation(a0[0], a0[1], a1[0], a1[1], b1[0], b1[1]) < 0
            and _orientation(b0[0], b0[1], b1[0], b1[1], a0[0], a0[1])
            * _orientation(b0[0], b0[1], b1[0], b1[1], a1[0], a1[1]) < 0):
        return 0.0
    return min(min(_point_segment(a0[0], a0[1], b0[0], b0[1], b1[0], b1[1]),
                   _point_segment(a1[0], a1[1], b0[0], b0[1], b1[0], b1[1])),
               min(_point_segment(b0[0], b0[1], a0[0], a0[1], a1[0], a1[1]),
                   _point_segment(b1[0], b1[1], a0[0], a0[1], a1[0], a1[1])))


@numba.njit(cache=True, nogil=True)
def _polylines(a: np.ndarray, b: np.ndarray) -> float:
    """Least distance between polylines ``a`` (P, 2) and ``b`` (Q, 2)."""
    best = np.inf
    for i in range(a.shape[0] - 1):
        for j in range(b.shape[0] - 1):
            best = min(best, _segments(a[i], a[i + 1], b[j], b[j + 1]))
    return best


@numba.njit(cache=True, nogil=True)
def _path(p: np.ndarray, v: np.ndarray, command: np.ndarray, dt_s: float, accel: float, v_max: float,
          upper: np.ndarray, out: np.ndarray) -> None:
    """The step from ``p`` under ``command`` (fly_step), then braking (braking_paths), into ``out`` (4, 2)."""
    cx, cy = command[0], command[1]
    norm = math.hypot(cx, cy)
    scale = v_max / max(norm, v_max)
    dx, dy = cx * scale - v[0], cy * scale - v[1]
    norm = math.hypot(dx, dy)
    cap = accel * dt_s
    scale = cap / max(norm, cap)
    vx, vy = v[0] + dx * scale, v[1] + dy * scale
    nx, ny = p[0] + vx * dt_s, p[1] + vy * dt_s
    qx, qy = min(max(nx, 0.0), upper[0]), min(max(ny, 0.0), upper[1])
    if qx != nx:
        vx = 0.0
    if qy != ny:
        vy = 0.0
    out[0, 0], out[0, 1], out[1, 0], out[1, 1] = p[0], p[1], qx, qy
    speed = math.hypot(vx, vy)
    step = accel * dt_s
    steps = math.floor(speed / step)
    reach = dt_s * (steps * speed - step * steps * (steps + 1.0) / 2.0)
    ux, uy = (vx / speed, vy / speed) if speed > 1e-12 else (0.0, 0.0)
    ex, ey = qx + ux * reach, qy + uy * reach
    to_wall = np.inf
    for unit, here, top in ((ux, qx, upper[0]), (uy, qy, upper[1])):
        if unit > 0:
            to_wall = min(to_wall, (top - here) / unit)
        elif unit < 0:
            to_wall = min(to_wall, -here / unit)
    hit = min(to_wall, reach)
    out[2, 0], out[2, 1] = qx + ux * hit, qy + uy * hit
    out[3, 0], out[3, 1] = min(max(ex, 0.0), upper[0]), min(max(ey, 0.0), upper[1])


@numba.njit(cache=True, nogil=True)
def decide_world(p: np.ndarray, v: np.ndarray, wanted: np.ndarray, current: np.ndarray, threshold: np.ndarray,
                 dt_s: float, accel: float, v_max: float, upper: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Safe commands (K, 2) and ``held`` (K,) of one world, UAV ``k`` before UAV ``k + 1`` (module docstring).

    ``current`` (K, 4, 2) are the braking paths from now; ``threshold`` (K, K) the gap each pair keeps.
    """
    k = p.shape[0]
    decided = current.copy()
    safe = np.zeros((k, 2))
    held = np.zeros(k, dtype=np.bool_)
    option = np.zeros(2)
    path = np.zeros((4, 2))
    n_options = TURNS_RAD.shape[0] + 1
    for uav in range(k):
        for t in range(n_options):
            if t < n_options - 1:
                c, s = math.cos(TURNS_RAD[t]), math.sin(TURNS_RAD[t])
                option[0] = c * wanted[uav, 0] - s * wanted[uav, 1]
                option[1] = s * wanted[uav, 0] + c * wanted[uav, 1]
            else:
                option[0], option[1] = 0.0, 0.0
            _path(p[uav], v[uav], option, dt_s, accel, v_max, upper, path)
            ok = True
            if t < n_options - 1:  # braking is always accepted
                for other in range(k):
                    if other != uav and _polylines(path, decided[other]) < threshold[uav, other]:
                        ok = False
                        break
            if ok:
                safe[uav] = option
                held[uav] = t > 0
                decided[uav] = path
                break
    return safe, held
