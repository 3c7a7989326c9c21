"""BatchedCrowd: B copies stepped together move bit for bit as B separate CrowdSims."""

from __future__ import annotations

import weakref

import numpy as np
import pytest

from uav_swarm.world.crowd import CrowdConfig, CrowdSim
from uav_swarm.world.crowd_batch import BatchedCrowd
from uav_swarm.world.scenario import ScenarioConfig, random_scenario

SMALL = {"n_groups_min": 2, "n_groups_max": 4, "group_size_min": 10, "group_size_max": 40}


def _sims(seeds, scenario_config, crowd_config=None):
    sims = []
    for seed in seeds:
        rng = np.random.default_rng(seed)
        sims.append(CrowdSim(random_scenario(rng, scenario_config), crowd_config or CrowdConfig(), rng))
    return sims


def _assert_same(batch, alone):
    for c, sim in enumerate(alone):
        s = slice(batch.offsets[c], batch.offsets[c + 1])
        np.testing.assert_array_equal(batch.positions_m[s], sim.positions_m)
        np.testing.assert_array_equal(batch.velocities_m_s[s], sim.velocities_m_s)
        np.testing.assert_array_equal(batch.waypoints_reached[s], sim.waypoints_reached)
        np.testing.assert_array_equal(batch.current_waypoints[s], sim.current_waypoints)
        assert batch.time_s[c] == pytest.approx(sim.time_s)


@pytest.mark.parametrize(
    ("scenario_config", "seeds"),
    [
        (ScenarioConfig(), (0, 1, 2)),
        (ScenarioConfig(**SMALL, n_obstacles=30, obstacle_gap_m=1.0), (3, 4, 5, 6)),
        (ScenarioConfig(**SMALL, width_m=80.0, height_m=60.0, n_obstacles=15, n_waypoints=4,
                        waypoint_separation_m=10.0, obstacle_length_max_m=30.0, obstacle_gap_m=1.0),
         (7, 8)),
    ],
    ids=["default", "many-obstacles", "small-dense"],
)
def test_batch_steps_as_separate_crowds(scenario_config, seeds):
    batch = BatchedCrowd(_sims(seeds, scenario_config))
    alone = _sims(seeds, scenario_config)
    _assert_same(batch, alone)
    for _ in range(20):
        batch.step(5)
        for sim in alone:
            sim.step(5)
    _assert_same(batch, alone)


def test_fast_coarse_crowd_with_short_cutoff():
    """Steps longer than the cutoff (walls must be listed by reach) and a short neighbour cutoff."""
    crowd_config = CrowdConfig(dt_s=0.3, max_speed_m_s=5.0, desired_speed_max_m_s=3.0, neighbour_cutoff_m=0.8)
    config = ScenarioConfig(**SMALL, n_obstacles=20, obstacle_gap_m=1.0)
    batch = BatchedCrowd(_sims((30, 31, 32), config, crowd_config))
    alone = _sims((30, 31, 32), config, crowd_config)
    for _ in range(60):
        batch.step()
        for sim in alone:
            sim.step()
    _assert_same(batch, alone)


def test_step_only_the_active_copies():
    config = ScenarioConfig(**SMALL)
    batch = BatchedCrowd(_sims((40, 41, 42), config))
    alone = _sims((40, 41, 42), config)
    batch.step(2, active=np.array([True, False, True]))
    for k in (0, 2):
        alone[k].step(2)
    _assert_same(batch, alone)
    batch.step(1, active=np.array([False, False, False]))
    _assert_same(batch, alone)
    with pytest.raises(ValueError, match="active"):
        batch.step(1, active=np.array([True, False]))


def test_partial_replacement_keeps_the_other_copies():
    config = ScenarioConfig(**SMALL)
    batch = BatchedCrowd(_sims((10, 11, 12), config))
    alone = _sims((10, 11, 12), config)
    for _ in range(30):
        batch.step()
        for sim in alone:
            sim.step()
    batch.replace([1], _sims((99,), config))
    alone[1] = _sims((99,), config)[0]
    _assert_same(batch, alone)
    for _ in range(70):
        batch.step()
        for sim in alone:
            sim.step()
    _assert_same(batch, alone)
    assert batch.time_s.tolist() == pytest.approx([10.0, 7.0, 10.0])


def test_copies_with_different_walls_and_coincident_spawns():
    """Different wall counts per copy (padding) and zero-size spawn areas (coincident pedestrians)."""
    configs = [ScenarioConfig(**SMALL, n_obstacles=0, spawn_extent_m=0.0),
               ScenarioConfig(**SMALL, n_obstacles=12)]
    sims = []
    for seed, config in zip((20, 21), configs, strict=True):
        rng = np.random.default_rng(seed)
        sims.append(CrowdSim(random_scenario(rng, config), CrowdConfig(), rng))
    batch = BatchedCrowd(sims)
    alone = []
    for seed, config in zip((20, 21), configs, strict=True):
        rng = np.random.default_rng(seed)
        alone.append(CrowdSim(random_scenario(rng, config), CrowdConfig(), rng))
    for _ in range(100):
        batch.step()
        for sim in alone:
            sim.step()
    _assert_same(batch, alone)


def test_replace_rejects_bad_arguments():
    config = ScenarioConfig(**SMALL)
    batch = BatchedCrowd(_sims((0, 1), config))
    with pytest.raises(ValueError, match="out of range"):
        batch.replace([2], _sims((5,), config))
    with pytest.raises(ValueError, match="distinct"):
        batch.replace([0, 0], _sims((5, 6), config))
    rng = np.random.default_rng(0)
    other = CrowdSim(random_scenario(rng, config), CrowdConfig(dt_s=0.05), rng)
    with pytest.raises(ValueError, match="CrowdConfig"):
        batch.replace([0], [other])
    with pytest.raises(ValueError, match="at least one"):
        BatchedCrowd([])


def test_kept_states_stay_valid_and_unkept_arrays_are_reused():
    batch = BatchedCrowd(_sims((0, 1), ScenarioConfig(**SMALL)))
    batch.step()
    kept = [batch.positions_m, batch.positions_of(1), batch.velocities_m_s]  # arrays and a view
    copies = [array.copy() for array in kept]
    batch.step(4)
    for array, copy in zip(kept, copies, strict=True):
        np.testing.assert_array_equal(array, copy)
    unkept = weakref.ref(batch.positions_m)  # nothing else holds it: two steps on, it is written again
    batch.step(2)
    assert batch.positions_m is unkept()
    assert not batch.positions_m.flags.writeable
