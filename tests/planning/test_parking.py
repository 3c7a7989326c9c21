"""The spares' parking search: the first free point of the rings, in their order, or the start."""

from __future__ import annotations

import numpy as np
import pytest

from uav_swarm.planning.parking import RING_STEP_M, parking_spot

AREA_M = np.array([200.0, 200.0])


def _ring_points(start: np.ndarray) -> np.ndarray:
    """Every point the search may try, in its order (rings outwards, East first, anticlockwise)."""
    rings = []
    for radius in np.arange(0.0, float(np.hypot(*AREA_M)), RING_STEP_M):
        count = max(1, int(np.ceil(2.0 * np.pi * radius / RING_STEP_M)))
        angles = np.linspace(0.0, 2.0 * np.pi, count, endpoint=False)
        rings.append(start + radius * np.stack([np.cos(angles), np.sin(angles)], axis=1))
    return np.clip(np.concatenate(rings), 0.0, AREA_M)


@pytest.mark.parametrize("seed", range(12))
def test_the_spot_is_the_first_free_point_or_the_start(seed):
    rng = np.random.default_rng(seed)
    users = rng.normal(rng.uniform(0.0, 200.0, 2), rng.uniform(5.0, 60.0), (int(rng.integers(1, 400)), 2))
    start, others = rng.uniform(0.0, 200.0, 2), rng.uniform(0.0, 200.0, (9, 2))
    reach_m, gap_m = float(rng.choice([30.0, 60.0, 95.0])), 5.0
    points = _ring_points(start)
    user_d = np.linalg.norm(points[:, None] - users[None], axis=-1).min(axis=1)
    other_d = np.linalg.norm(points[:, None] - others[None], axis=-1).min(axis=1)
    free = (user_d > reach_m + 1e-9) & (other_d >= gap_m + 1e-9)
    spot = parking_spot(users, start, others, AREA_M, reach_m, gap_m)
    if free.any():
        assert spot == pytest.approx(points[int(np.argmax(free))], abs=1e-9)
        assert np.linalg.norm(users - spot, axis=1).min() > reach_m
        assert np.linalg.norm(others - spot, axis=1).min() >= gap_m
    else:
        assert spot.tolist() == start.tolist()


def test_a_crowd_that_leaves_no_free_point_holds_the_start():
    users = np.stack(np.meshgrid(np.arange(0.0, 201.0, 20.0), np.arange(0.0, 201.0, 20.0)), -1).reshape(-1, 2)
    start = np.array([33.0, 71.0])
    assert parking_spot(users, start, np.zeros((0, 2)), AREA_M, 15.0, 5.0).tolist() == start.tolist()
