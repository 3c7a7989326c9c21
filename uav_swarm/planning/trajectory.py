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

import numpy as np

from uav_swarm.world.uav import UAVConfig

__all__ = ["Legs", "along_m", "arrival_s", "closest_approach_m", "leg_positions_m", "tracks_m"]


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
    first = leg_positions_m(legs.start, legs.turn, legs.speed0, t_s, config)
    finite = np.isfinite(legs.depart)
    depart = np.where(finite, legs.depart, 0.0)
    second = leg_positions_m(legs.turn, legs.end, np.zeros_like(legs.speed0), t_s[None, :] - depart[:, None],
                            config)
    later = finite[:, None] & (t_s[None, :] >= depart[:, None])
    return np.where(later[..., None], second, first)


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
