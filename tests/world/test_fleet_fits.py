"""Feasibility: the fleet check, the env's start positions and the separation of targets follow one rule."""

import numpy as np
import pytest

from typed_config import ConfigError
from uav_swarm.world.separation import (
    check_fleet_fits,
    closest_distances_m,
    draw_apart_m,
    fleet_slots_m,
    max_spread_m,
)


def test_every_fleet_the_check_accepts_starts_and_every_fleet_it_refuses_does_not():
    """A seeded quick version of benchmarks/flight/feasibility_fuzz.py: fleets at the edge of the rule."""
    rng = np.random.default_rng(4)
    accepted = refused = 0
    for _ in range(60):
        n = int(rng.integers(2, 13))
        area = rng.uniform(5.0, 80.0, 2)
        minimum = max_spread_m(n, *area) * float(rng.uniform(0.85, 1.1))
        fits = True
        try:
            check_fleet_fits(n, minimum, *area)
        except ConfigError:
            fits = False
        required = np.full((n, n), minimum)
        np.fill_diagonal(required, 0.0)
        if fits:
            accepted += 1
            start = draw_apart_m(rng, n, area, required, max_tries=200)
            assert np.all((start >= 0.0) & (start <= area))
            assert closest_distances_m(start) >= minimum - 1e-9
            assert len(fleet_slots_m(minimum, *area)) >= n
        else:
            refused += 1
            with pytest.raises(ConfigError, match="uav.min_separation_m"):
                draw_apart_m(rng, n, area, required)
            assert len(fleet_slots_m(minimum, *area)) < n
    assert accepted >= 20 and refused >= 10


def test_the_fleet_the_env_could_not_start_now_starts_at_the_minimum():
    required = np.full((10, 10), 5.0)
    check_fleet_fits(10, 5.0, 12.0, 12.0)  # accepted: 3-2-3-2 staggered points exactly 5 m apart
    start = draw_apart_m(np.random.default_rng(0), 10, np.array([12.0, 12.0]), required)
    assert closest_distances_m(start) >= 5.0 - 1e-9
