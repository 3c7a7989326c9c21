"""The compiled pair forces against every pair summed by numpy, over worlds of various shapes."""

from __future__ import annotations

import numpy as np
import pytest

from uav_swarm.world.pair_forces import pair_forces

CUTOFF, A, B, RADIUS, LAMBDA = 1.5, 2.1, 0.3, 0.25, 0.5


def _all_pairs(p, d, starts):
    """The forces of the crowd's formula over every pair of each world (no sweep), ``(N, 2)``."""
    force = np.zeros_like(p)
    half = 0.5 * (1.0 - LAMBDA)
    for start, end in zip(starts[:-1], starts[1:], strict=True):
        for i in range(start, end):
            for j in range(i + 1, end):
                delta = p[i] - p[j]
                dist = np.hypot(*delta)
                if dist > CUTOFF:
                    continue
                if dist < 1e-9:
                    angle = 2.399963229728653 * ((i - start) * 7 + (j - start))
                    delta, dist = np.array([np.cos(angle), np.sin(angle)]), 1.0
                magnitude = A * np.exp((2 * RADIUS - dist) / B) / dist
                force[i] += magnitude * (LAMBDA + half - half * (d[i] @ delta) / dist) * delta
                force[j] -= magnitude * (LAMBDA + half + half * (d[j] @ delta) / dist) * delta
    return force


def _directions(rng, n):
    d = rng.normal(size=(n, 2))
    d /= np.linalg.norm(d, axis=1)[:, None]
    d[rng.random(n) < 0.2] = 0.0  # some stand still
    return d


@pytest.mark.parametrize("seed", range(4))
def test_forces_are_those_of_every_close_pair(seed):
    rng = np.random.default_rng(seed)
    counts = rng.integers(0, 120, size=5)
    starts = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    sizes = (6.0, 10.0, 3.0, 40.0, 8.0)
    # dense worlds of different sizes, some pedestrians outside [0, size] and some on the same spot
    p = np.concatenate([rng.uniform(-2.0, size, (n, 2)) for n, size in zip(counts, sizes, strict=True)])
    if len(p) > 3:
        p[1] = p[0]
    d = _directions(rng, len(p))
    order = np.arange(len(p))
    if seed == 0:  # any order that keeps each world's pedestrians in its range
        order = np.concatenate([start + rng.permutation(n) for start, n in zip(starts, counts, strict=False)])
    force = pair_forces(p, d, starts, order, CUTOFF, A, B, RADIUS, LAMBDA)
    np.testing.assert_allclose(force, _all_pairs(p, d, starts), rtol=1e-12, atol=1e-12)
    for start, end in zip(starts[:-1], starts[1:], strict=True):  # sorted by (row, x) within its world
        assert sorted(order[start:end]) == list(range(start, end))
        keys = [(np.floor(p[k, 1] / (CUTOFF * (1 + 1e-9))), p[k, 0], k) for k in order[start:end]]
        assert keys == sorted(keys)


def test_a_world_moved_into_a_batch_gets_the_same_forces_to_the_bit():
    rng = np.random.default_rng(7)
    world = rng.uniform(0.0, 12.0, (300, 2))
    others = rng.uniform(0.0, 12.0, (500, 2))  # the same area: only the world boundaries separate them
    d = _directions(rng, 800)
    alone = pair_forces(world, d[200:500], np.array([0, 300]), np.arange(300), CUTOFF, A, B, RADIUS, LAMBDA)
    batch = np.concatenate([others[:200], world, others[200:]])
    starts = np.array([0, 200, 500, 800])
    together = pair_forces(batch, d, starts, np.arange(800), CUTOFF, A, B, RADIUS, LAMBDA)
    np.testing.assert_array_equal(together[200:500], alone)


def test_pairs_at_the_cutoff_and_no_pedestrians():
    p = np.array([[0.0, 0.0], [CUTOFF, 0.0], [0.0, 10.0], [0.0, 10.0 + CUTOFF * (1 + 1e-12)]])
    force = pair_forces(p, np.zeros((4, 2)), np.array([0, 4]), np.arange(4), CUTOFF, A, B, RADIUS, LAMBDA)
    assert force[0, 0] < 0.0 < force[1, 0]  # exactly at the cutoff: counted
    assert (force[2:] == 0.0).all()  # just beyond: not
    none = np.zeros((0, 2))
    empty = pair_forces(none, none, np.array([0, 0, 0]), np.zeros(0, np.int64), CUTOFF, A, B, RADIUS, LAMBDA)
    assert empty.shape == (0, 2)
