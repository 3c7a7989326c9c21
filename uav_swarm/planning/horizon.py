"""The motion horizon at array speed: every option and instant judged in one pass of the radio model.

Planning in motion (:mod:`uav_swarm.planning.motion`) judges each option by the strategy's QoS on
``samples`` instants of the next ``horizon_s`` seconds: the crowd walks on with its velocities, the
UAVs fly to their (moving) targets at their speed and acceleration limits. :func:`horizon_qos` builds
every (option, instant) pair as one batch of worlds and :func:`coverage_qos_batch` judges the batch in
one pass (worlds x UAVs x users: a compiled loop finds each user's nearest UAV without the large
temporaries of a broadcast, numpy does the rest on ``(B, N)`` arrays), with exactly the arithmetic of
:func:`uav_swarm.world.comms.evaluate_coverage`, so the QoS values, and the decisions taken on them,
are those of one radio-model call per instant and option.

A radio model with a station limit (admission control: the association depends on who asked first)
is judged world by world with :func:`~uav_swarm.world.comms.evaluate_coverage` itself.

Examples:
    >>> users = np.array([[[0.0, 0.0], [29.0, 0.0], [31.0, 0.0]]])
    >>> s1, s2 = coverage_qos_batch(users, np.zeros((1, 1, 2)), RadioConfig())
    >>> round(float(s1[0]), 3), round(float(s2[0]), 3)
    (0.667, 0.667)
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import numba
import numpy as np

from uav_swarm.world.comms import RadioConfig, evaluate_coverage
from uav_swarm.world.wifi.channels import plan_channels
from uav_swarm.world.wifi.coverage import wifi_links

__all__ = ["coverage_qos_batch", "horizon_qos", "travelled_m", "warm_up"]


def travelled_m(t_s: float, max_speed_m_s: float, max_accel_m_s2: float) -> float:
    """Distance flown from rest in ``t_s`` seconds at full acceleration up to the speed cap."""
    t_ramp = max_speed_m_s / max_accel_m_s2
    if t_s <= t_ramp:
        return 0.5 * max_accel_m_s2 * t_s ** 2
    return 0.5 * max_accel_m_s2 * t_ramp ** 2 + max_speed_m_s * (t_s - t_ramp)


@numba.njit(cache=True, nogil=True)
def _nearest(users: np.ndarray, uavs: np.ndarray, altitude_sq: float) -> tuple[np.ndarray, np.ndarray]:
    """``(B, N)`` nearest UAV (the lowest index among equals) and its squared distance, per world and user.

    The squared distance is evaluate_coverage's, operation for operation: ``dx * dx``, plus ``dy * dy``,
    plus the squared altitude when there is one (no fused multiply-add: numba keeps IEEE semantics).
    """
    n_worlds, n_users = users.shape[0], users.shape[1]
    nearest = np.zeros((n_worlds, n_users), np.int64)
    best = np.empty((n_worlds, n_users))
    for b in range(n_worlds):
        for n in range(n_users):
            arg, low = 0, np.inf
            for k in range(uavs.shape[1]):
                dx = uavs[b, k, 0] - users[b, n, 0]
                dy = uavs[b, k, 1] - users[b, n, 1]
                d2 = dx * dx
                d2 += dy * dy
                if altitude_sq != 0.0:
                    d2 += altitude_sq
                if d2 < low:
                    arg, low = k, d2
            nearest[b, n] = arg
            best[b, n] = low
    return nearest, best


def coverage_qos_batch(users_m: np.ndarray, uavs_m: np.ndarray, config: RadioConfig,
                       enabled: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """QoS S1 and S2 of ``B`` worlds, each equal to :func:`~uav_swarm.world.comms.evaluate_coverage`'s.

    Under the 802.11 radio each world is judged with its own channel plan
    (:func:`~uav_swarm.world.wifi.channels.plan_channels`), every UAV at ``config.altitude_m``.

    Args:
        users_m: ``(B, N, 2)`` user positions of each world, metres.
        uavs_m: ``(B, K, 2)`` UAV positions of each world, metres.
        config: The radio model.
        enabled: 802.11 only: ``(B, K)`` bool, the UAVs whose access point is on; None: all.

    Returns:
        ``(qos_s1, qos_s2)``, each ``(B,)`` float64 (0.0 for worlds without users or UAVs).

    Raises:
        ValueError: The arrays are not ``(B, N, 2)`` and ``(B, K, 2)`` with the same ``B``.
    """
    users = np.ascontiguousarray(users_m, dtype=np.float64)
    uavs = np.ascontiguousarray(uavs_m, dtype=np.float64)
    if users.ndim != 3 or uavs.ndim != 3 or users.shape[2] != 2 or uavs.shape[2] != 2 \
            or users.shape[0] != uavs.shape[0]:
        raise ValueError(f"users_m and uavs_m must have shapes (B, N, 2) and (B, K, 2), got {users.shape} "
                         f"and {uavs.shape}")
    n_worlds, n_users, _ = users.shape
    n_uavs = uavs.shape[1]
    if config.propagation == "802.11":
        if n_users == 0 or n_uavs == 0:
            return np.zeros(n_worlds), np.zeros(n_worlds)
        plans = plan_channels(uavs, config, enabled=enabled)
        links = wifi_links(users.reshape(-1, 2), np.repeat(np.arange(n_worlds), n_users), uavs, config,
                           channels=plans, enabled=enabled)
        return np.asarray(links.qos_s1, np.float64), np.asarray(links.qos_s2, np.float64)
    if enabled is not None:
        raise ValueError("access points apply only with RadioConfig.propagation = '802.11'")
    if config.max_stations is not None:  # admission control: the snapshot function
        pairs = [evaluate_coverage(u, k, config) for u, k in zip(users, uavs, strict=True)]
        return (np.array([c.qos_s1 for c in pairs], dtype=np.float64),
                np.array([c.qos_s2 for c in pairs], dtype=np.float64))
    if n_users == 0 or n_uavs == 0:
        return np.zeros(n_worlds), np.zeros(n_worlds)
    nearest, nearest_d2 = _nearest(users, uavs, float(config.altitude_m) ** 2 if config.altitude_m else 0.0)
    best_signal = np.exp(nearest_d2 * (-0.5 / config.effective_sigma_sq_m2))  # numpy's exp, as there
    covered = best_signal >= config.signal_at_range
    world = np.arange(n_worlds)[:, None] * n_uavs
    users_per_uav = np.bincount((world + nearest)[covered],
                                minlength=n_worlds * n_uavs).reshape(n_worlds, n_uavs)
    rate_mbps = config.capacity_mbps / np.maximum(users_per_uav, 1)
    n_fast = np.where(rate_mbps >= config.min_user_rate_mbps, users_per_uav, 0).sum(axis=1)
    n_served = covered.sum(axis=1)
    return n_served / n_users, n_fast / n_users


@functools.cache
def warm_up() -> None:
    """Load the compiled loop once per process (about half a second), so that no replan pays for it."""
    coverage_qos_batch(np.zeros((1, 1, 2)), np.zeros((1, 1, 2)), RadioConfig())


def horizon_qos(peds: np.ndarray, vels: np.ndarray, uavs: np.ndarray, options: Sequence[np.ndarray],
                target_velocities: Sequence[np.ndarray], radio: RadioConfig, strategy: int, horizon_s: float,
                samples: int, max_speed_m_s: float, max_accel_m_s2: float,
                serving: Sequence[np.ndarray] | None = None) -> list[float]:
    """Each option's QoS averaged over ``samples`` instants of the horizon, in one radio-model pass.

    At instant ``t`` the crowd is at ``peds + vels * t``; each UAV flies from ``uavs`` straight
    towards its target ``target + target_velocity * t`` and has covered at most the distance of a
    start from rest (trapezoidal profile) by then.

    Args:
        peds: ``(N, 2)`` pedestrian positions, metres.
        vels: ``(N, 2)`` pedestrian velocities, m/s.
        uavs: ``(n, 2)`` UAV positions now, metres.
        options: Each option's ``(n, 2)`` targets, metres.
        target_velocities: Each option's ``(n, 2)`` target velocities (the users' mean), m/s.
        radio: The radio model.
        strategy: 1 (QoS S1) or 2 (QoS S2).
        horizon_s: The horizon, seconds.
        samples: Instants averaged, the last at ``horizon_s``.
        max_speed_m_s: The UAVs' speed limit.
        max_accel_m_s2: The UAVs' acceleration limit.
        serving: 802.11 only: each option's ``(n,)`` bool, the UAVs it gives users (the others' access
            points are off); None: every AP on.

    Returns:
        One averaged QoS per option (0.0 for every option without pedestrians).
    """
    if len(peds) == 0:
        return [0.0] * len(options)
    times = np.linspace(horizon_s / samples, horizon_s, samples)  # (S,)
    reach = np.array([travelled_m(float(t), max_speed_m_s, max_accel_m_s2) for t in times])
    targets = np.stack(options)  # (O, n, 2)
    velocity = np.stack(target_velocities)
    goal = targets[:, None] + velocity[:, None] * times[None, :, None, None]  # (O, S, n, 2)
    offset = goal - uavs
    distance = np.linalg.norm(offset, axis=-1)  # (O, S, n)
    limit = reach[None, :, None]
    scale = np.where(distance > limit, limit / np.maximum(distance, 1e-9), 1.0)
    flown = uavs + offset * scale[..., None]  # (O, S, n, 2)
    crowd = peds[None] + vels[None] * times[:, None, None]  # (S, N, 2)
    n_options = len(options)
    users = np.broadcast_to(crowd[None], (n_options, *crowd.shape)).reshape(-1, *peds.shape)
    enabled = None if serving is None else np.repeat(np.stack(serving).astype(bool), samples, axis=0)
    s1, s2 = coverage_qos_batch(users, flown.reshape(-1, *uavs.shape), radio, enabled)
    qos = (s1 if strategy == 1 else s2).reshape(n_options, samples)
    out = []
    for row in qos:  # summed instant by instant, as the per-instant loop did
        total = 0.0
        for value in row:
            total += float(value)
        out.append(total / samples)
    return out
