"""Predicted flights of UAVs along straight legs with the waypoint controller's speed profile (pure numpy).

A leg is flown from an entry speed along it, accelerating at ``max_accel_m_s2`` up to ``max_speed_m_s`` and
braking to a stop at its end (an entry too fast to stop within the leg brakes uniformly onto its end): the
profile :func:`uav_swarm.world.uav.waypoint_velocity` flies, in closed form for every UAV and instant at
once. :class:`Legs` chains two legs per UAV (to a hold point, then from rest at a departure time to the
target); :func:`closest_approach_m` is the least distance of two sampled tracks, exact between samples
for the linear motion in between.

Examples:
    >>> from uav_swarm.world.uav import UAVConfig
    >>> arrival_s(np.array([100.0]), np.array([0.0]), UAVConfig()).tolist()  # 2 s up, 8 s at 10 m/s, 2 s down
    [12.0]
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from uav_swarm.world.uav import UAVConfig

__all__ = ["Legs", "along_m", "arrival_s", "closest_approach_m", "first_clear", "leg_positions_m",
           "pair_closest_m", "tracks_m", "warm_up"]


@dataclass(frozen=True)
class Legs:
    """Predicted flights: a first leg (braking to the hold point, or the whole flight), then maybe a second.

    ``start``, ``turn``, ``end``: ``(K, 2)``; ``speed0``: speed along the first leg; ``depart``: when the
    second leg (turn -> end, from rest) starts (inf: no second leg, the first leg ends at ``end``).
    """

    start: np.ndarray
    turn: np.ndarray
    end: np.ndarray
    speed0: np.ndarray
    depart: np.ndarray


def along_m(distance_m: np.ndarray, speed0_m_s: np.ndarray, t_s: np.ndarray, config: UAVConfig
             ) -> np.ndarray:
    """Distance flown after ``t_s`` along a leg of ``distance_m`` entered at ``speed0_m_s`` (broadcast).

    Accelerate to the peak speed, cruise, brake to a stop at the end; an entry too fast to stop in the leg
    brakes uniformly onto its end.
    """
    a, d = config.max_accel_m_s2, np.maximum(distance_m, 0.0)
    u0 = np.clip(speed0_m_s, 0.0, config.max_speed_m_s)
    t = np.maximum(t_s, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        overshoot = u0 * u0 >= 2.0 * a * d
        a_stop = np.where(d > 0, u0 * u0 / (2.0 * np.where(d > 0, d, 1.0)), a)
        t_stop = np.where(a_stop > 0, u0 / a_stop, 0.0)
        braking = np.where(t < t_stop, u0 * t - 0.5 * a_stop * t * t, d)
        peak = np.minimum(config.max_speed_m_s, np.sqrt(a * d + 0.5 * u0 * u0))
        t1, d1 = (peak - u0) / a, (peak * peak - u0 * u0) / (2.0 * a)
        d2 = np.maximum(d - d1 - peak * peak / (2.0 * a), 0.0)
        t2 = np.where(peak > 0, d2 / np.where(peak > 0, peak, 1.0), 0.0)
        tau = t - t1 - t2
        cruise = np.where(t < t1, u0 * t + 0.5 * a * t * t,
                          np.where(tau < 0, d1 + peak * (t - t1), d1 + d2 + peak * tau - 0.5 * a * tau * tau))
        cruise = np.where(tau >= peak / a, d, cruise)
    return np.where(overshoot, braking, np.minimum(cruise, d))


def arrival_s(distance_m: np.ndarray, speed0_m_s: np.ndarray, config: UAVConfig) -> np.ndarray:
    """Seconds to fly a leg of :func:`along_m` to its end."""
    a, d = config.max_accel_m_s2, np.maximum(distance_m, 0.0)
    u0 = np.clip(speed0_m_s, 0.0, config.max_speed_m_s)
    with np.errstate(divide="ignore", invalid="ignore"):
        braking = np.where(u0 > 0, 2.0 * d / np.where(u0 > 0, u0, 1.0), 0.0)
        peak = np.minimum(config.max_speed_m_s, np.sqrt(a * d + 0.5 * u0 * u0))
        d2 = np.maximum(d - (peak * peak - u0 * u0) / (2.0 * a) - peak * peak / (2.0 * a), 0.0)
        cruise = (peak - u0) / a + np.where(peak > 0, d2 / np.where(peak > 0, peak, 1.0), 0.0) + peak / a
    return np.where(u0 * u0 >= 2.0 * a * d, braking, cruise)


def leg_positions_m(start: np.ndarray, end: np.ndarray, speed0: np.ndarray, t_s: np.ndarray,
                   config: UAVConfig) -> np.ndarray:
    """``(..., T, 2)`` positions along straight legs ``start -> end`` (``(..., 2)``) at times ``t_s`` (T,)."""
    offset = end - start
    length = np.hypot(offset[..., 0], offset[..., 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        unit = np.where(length[..., None] > 1e-12, offset / length[..., None], 0.0)
    s = along_m(length[..., None], speed0[..., None], t_s, config)  # (..., T)
    return start[..., None, :] + s[..., None] * unit[..., None, :]


def tracks_m(legs: Legs, t_s: np.ndarray, config: UAVConfig) -> np.ndarray:
    """``(N, T, 2)`` predicted positions of the N UAVs of ``legs`` at times ``t_s`` (T,)."""
    return _tracks(*_legs_arrays(legs), np.asarray(t_s, np.float64), config.max_speed_m_s,
                   config.max_accel_m_s2)


def pair_closest_m(tracks: np.ndarray) -> np.ndarray:
    """``(N, N)`` closest approach of every pair of sampled tracks ``(N, T, 2)`` (``inf`` on the diagonal)."""
    return _pair_closest(np.ascontiguousarray(tracks, np.float64))


def first_clear(mine: Legs, others: np.ndarray, need_m: np.ndarray, t_s: np.ndarray, config: UAVConfig
                ) -> int:
    """Index of the first of the C flights ``mine`` that keeps its distance from every track of ``others``.

    ``others`` (S, T, 2) is sampled at ``t_s``; flight ``c`` must stay ``need_m[s]`` from track ``s``
    (exact between samples for linear motion); -1 when none does.
    """
    return int(_first_clear(*_legs_arrays(mine), np.ascontiguousarray(others, np.float64),
                            np.asarray(need_m, np.float64), np.asarray(t_s, np.float64), config.max_speed_m_s,
                            config.max_accel_m_s2))


def _legs_arrays(legs: Legs) -> tuple[np.ndarray, ...]:
    return tuple(np.ascontiguousarray(x, np.float64) for x in (legs.start, legs.turn, legs.end, legs.speed0,
                                                                legs.depart))


@numba.njit(cache=True, nogil=True)
def _along(d: float, u0: float, t: float, vmax: float, a: float) -> float:  # pragma: no cover - compiled
    """:func:`along_m` of one leg and instant."""
    if d <= 0.0:
        return 0.0
    u0 = min(max(u0, 0.0), vmax)
    t = max(t, 0.0)
    if u0 * u0 >= 2.0 * a * d:
        a_stop = u0 * u0 / (2.0 * d)
        if t < u0 / a_stop:
            return min(u0 * t - 0.5 * a_stop * t * t, d)
        return d
    peak = min(vmax, np.sqrt(a * d + 0.5 * u0 * u0))
    t1, d1 = (peak - u0) / a, (peak * peak - u0 * u0) / (2.0 * a)
    d2 = max(d - d1 - peak * peak / (2.0 * a), 0.0)
    t2 = d2 / peak if peak > 0.0 else 0.0
    tau = t - t1 - t2
    if tau >= peak / a:
        return d
    if t < t1:
        s = u0 * t + 0.5 * a * t * t
    elif tau < 0.0:
        s = d1 + peak * (t - t1)
    else:
        s = d1 + d2 + peak * tau - 0.5 * a * tau * tau
    return min(s, d)


@numba.njit(cache=True, nogil=True)
def _point(start: np.ndarray, turn: np.ndarray, end: np.ndarray, speed0: float, depart: float, t: float,
           vmax: float, a: float) -> tuple[float, float]:  # pragma: no cover - compiled
    """Where a UAV of one pair of legs is at ``t``."""
    if np.isfinite(depart) and t >= depart:
        x0, y0, x1, y1, u0, t = turn[0], turn[1], end[0], end[1], 0.0, t - depart
    else:
        x0, y0, x1, y1, u0 = start[0], start[1], turn[0], turn[1], speed0
    dx, dy = x1 - x0, y1 - y0
    length = np.sqrt(dx * dx + dy * dy)
    if length <= 1e-12:
        return x0, y0
    s = _along(length, u0, t, vmax, a) / length
    return x0 + s * dx, y0 + s * dy


@numba.njit(cache=True, nogil=True)
def _tracks(start: np.ndarray, turn: np.ndarray, end: np.ndarray, speed0: np.ndarray, depart: np.ndarray,
            times: np.ndarray, vmax: float, a: float) -> np.ndarray:  # pragma: no cover - compiled
    out = np.empty((start.shape[0], times.shape[0], 2))
    for k in range(start.shape[0]):
        for i in range(times.shape[0]):
            out[k, i, 0], out[k, i, 1] = _point(start[k], turn[k], end[k], speed0[k], depart[k], times[i],
                                                vmax, a)
    return out


@numba.njit(cache=True, nogil=True)
def _segment_gap(ax: float, ay: float, bx: float, by: float) -> float:  # pragma: no cover - compiled
    """Least norm of the relative position moving linearly from ``(ax, ay)`` to ``(bx, by)``."""
    sx, sy = bx - ax, by - ay
    length2 = sx * sx + sy * sy
    u = 0.0 if length2 <= 0.0 else min(max(-(ax * sx + ay * sy) / length2, 0.0), 1.0)
    x, y = ax + u * sx, ay + u * sy
    return np.sqrt(x * x + y * y)


@numba.njit(cache=True, nogil=True)
def _pair_closest(tracks: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    n, steps = tracks.shape[0], tracks.shape[1]
    out = np.full((n, n), np.inf)
    for i in range(n):
        for j in range(i + 1, n):
            ax, ay = tracks[i, 0, 0] - tracks[j, 0, 0], tracks[i, 0, 1] - tracks[j, 0, 1]
            low = np.sqrt(ax * ax + ay * ay)
            for t in range(1, steps):
                bx, by = tracks[i, t, 0] - tracks[j, t, 0], tracks[i, t, 1] - tracks[j, t, 1]
                low = min(low, _segment_gap(ax, ay, bx, by))
                ax, ay = bx, by
            out[i, j] = out[j, i] = low
    return out


@numba.njit(cache=True, nogil=True)
def _first_clear(start: np.ndarray, turn: np.ndarray, end: np.ndarray, speed0: np.ndarray, depart: np.ndarray,
                 others: np.ndarray, need: np.ndarray, times: np.ndarray, vmax: float, a: float
                 ) -> int:  # pragma: no cover - compiled
    for c in range(start.shape[0]):
        clear = True
        px, py = 0.0, 0.0
        for i in range(times.shape[0]):
            x, y = _point(start[c], turn[c], end[c], speed0[c], depart[c], times[i], vmax, a)
            for s in range(others.shape[0]):
                bx, by = x - others[s, i, 0], y - others[s, i, 1]
                if i == 0:
                    gap = np.sqrt(bx * bx + by * by)
                else:
                    gap = _segment_gap(px - others[s, i - 1, 0], py - others[s, i - 1, 1], bx, by)
                if gap < need[s]:
                    clear = False
                    break
            if not clear:
                break
            px, py = x, y
        if clear:
            return c
    return -1


def closest_approach_m(a_m: np.ndarray, b_m: np.ndarray) -> np.ndarray:
    """Least distance between sampled tracks ``a_m`` and ``b_m`` (``(..., T, 2)``), linear between samples.

    Examples:
        >>> a = np.array([[0.0, 0.0], [10.0, 0.0]])  # passes (5, 3) at 3 m between its two samples
        >>> float(closest_approach_m(a, np.array([[5.0, 3.0], [5.0, 3.0]])))
        3.0
    """
    rel = np.asarray(a_m, np.float64) - np.asarray(b_m, np.float64)
    r0, step = rel[..., :-1, :], rel[..., 1:, :] - rel[..., :-1, :]
    length2 = np.einsum("...c,...c->...", step, step)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.clip(np.where(length2 > 0, -np.einsum("...c,...c->...", r0, step) / length2, 0.0), 0.0, 1.0)
    nearest = r0 + s[..., None] * step
    gaps = np.sqrt(np.einsum("...c,...c->...", nearest, nearest))
    last = np.hypot(rel[..., -1, 0], rel[..., -1, 1])
    return np.minimum(gaps.min(axis=-1), last) if gaps.shape[-1] else last


def warm_up() -> None:
    """Compile (or load from the cache) the kernels now rather than at the first replan."""
    legs = Legs(np.zeros((1, 2)), np.ones((1, 2)), np.ones((1, 2)), np.zeros(1), np.full(1, np.inf))
    times = np.array([0.0, 1.0])
    pair_closest_m(tracks_m(legs, times, UAVConfig()))
    first_clear(legs, np.zeros((1, 2, 2)), np.zeros(1), times, UAVConfig())
