"""Waypoint mode keeps every pair of UAVs at least ``uav.min_separation_m`` apart, whatever the targets.

The closest distance is computed here from ``env.uav_positions_m`` after every step, independently of the
environment's own ``closest_separation_m``.
"""

from __future__ import annotations

import numpy as np

from uav_swarm.env.batched import BatchedUAVSwarm
from uav_swarm.env.parallel import parallel_env

MIN_M = 5.0
WORLD = {"scenario": {"n_groups_min": 1, "n_groups_max": 1, "group_size_min": 5, "group_size_max": 5},
         "density_shape": (16, 16), "patch_px": 3, "action_mode": "waypoint",
         "uav": {"min_separation_m": MIN_M}}


def _closest_m(positions_m):
    d = np.linalg.norm(positions_m[:, None, :] - positions_m[None, :, :], axis=-1)
    return d[np.triu_indices(len(positions_m), k=1)].min()


def _fly(starts_m, targets_m, steps):
    """Place the UAVs at ``starts_m`` (at rest), fly to ``targets_m``; the closest distance at every step."""
    env = parallel_env(n_uavs=len(starts_m), max_cycles=steps + 400, **WORLD)
    env.reset(seed=0)
    for _ in range(400):  # reach the start positions (spread well apart) first
        env.step(dict(zip(env.agents, starts_m, strict=True)))
    assert np.allclose(env.uav_positions_m, starts_m, atol=1e-3)
    closest, reported, held = [], [], 0
    for _ in range(steps):
        _, _, _, _, infos = env.step(dict(zip(env.agents, targets_m, strict=True)))
        closest.append(_closest_m(np.array(env.uav_positions_m)))
        reported.append(infos["uav_0"]["closest_separation_m"])
        held += sum(info["separation_held"] for info in infos.values())
    return env, np.array(closest), np.array(reported), held


def test_two_uavs_swapping_sides_head_on_keep_the_minimum():
    starts = np.array([[40.0, 100.0], [160.0, 100.0]])
    env, closest, reported, held = _fly(starts, starts[::-1], 600)
    assert closest.min() >= MIN_M - 1e-9
    np.testing.assert_allclose(reported, closest, rtol=1e-12)
    assert held > 0  # the straight lines cross: the guard had to act
    np.testing.assert_allclose(env.uav_positions_m, starts[::-1], atol=0.05)  # and both still arrive


def test_four_converging_on_one_point_keep_the_minimum():
    starts = np.array([[100.0, 20.0], [180.0, 100.0], [100.0, 180.0], [20.0, 100.0]])
    env, closest, _, held = _fly(starts, np.full((4, 2), 100.0), 600)
    assert closest.min() >= MIN_M - 1e-9
    assert held > 0
    assert np.linalg.norm(env.uav_positions_m - 100.0, axis=1).min() < MIN_M  # one holds the point


def test_ten_reassigned_by_a_permutation_keep_the_minimum():
    rng = np.random.default_rng(3)
    angles = np.linspace(0.0, 2 * np.pi, 10, endpoint=False)
    starts = 100.0 + 60.0 * np.column_stack([np.cos(angles), np.sin(angles)])
    targets = starts[rng.permutation(10)]
    env, closest, _, held = _fly(starts, targets, 1200)
    assert closest.min() >= MIN_M - 1e-9
    assert held > 0


def test_batched_waypoint_copies_keep_the_minimum_too():
    envs = BatchedUAVSwarm(3, n_uavs=4, max_cycles=500, **WORLD)
    envs.reset(seed=1)
    target = np.full((3, 4, 2), 100.0)
    for _ in range(500):
        _, _, _, _, info = envs.step(target)
        positions = envs.uav_positions_m
        closest = [_closest_m(p) for p in positions]
        assert min(closest) >= MIN_M - 1e-9, closest
        np.testing.assert_allclose(info["closest_separation_m"], closest, rtol=1e-12)
