"""TEMPORARY stand-in until main's separation module lands (replaced at merge)."""

from __future__ import annotations

import numpy as np

from uav_swarm.world.uav import UAVConfig


def pair_distances_m(positions_m, altitudes_m=None):
    d = positions_m[..., :, None, :] - positions_m[..., None, :, :]
    d2 = (d * d).sum(-1)
    if altitudes_m is not None:
        dz = altitudes_m[:, None] - altitudes_m[None, :]
        d2 = d2 + dz * dz
    return np.sqrt(d2)


def closest_distances_m(positions_m, altitudes_m=None):
    k = positions_m.shape[-2]
    d = pair_distances_m(positions_m, altitudes_m)
    d = d + np.where(np.eye(k, dtype=bool), np.inf, 0.0)
    return d.min(axis=(-1, -2))


def separation_penalty(positions_m, min_separation_m, altitudes_m=None):
    k = positions_m.shape[-2]
    if k < 2 or min_separation_m <= 0:
        return np.zeros(positions_m.shape[:-2])
    d = pair_distances_m(positions_m, altitudes_m)
    intrusion = np.where(d < min_separation_m, 1.0 - d / min_separation_m, 0.0)
    return (intrusion.sum(axis=(-1, -2)) - k) / 2.0


def uav_altitudes_m(config: UAVConfig, n_uavs: int):
    return np.full(n_uavs, config.alt_m)


def guard_commands(positions_m, velocities_m_s, command_m_s, dt_s, config, altitudes_m=None):
    return command_m_s, np.zeros(command_m_s.shape[:-1], bool)
