"""The strategy-2 group expert: rules obeyed, margins kept, stable, symmetric, selectable."""

from __future__ import annotations

import numpy as np
import pytest

from learning.data import sample_seed
from learning.symmetry import SYMMETRIES, transform_positions
from typed_config import ConfigError
from uav_swarm.missions.wifi.expert import WifiExpertConfig
from uav_swarm.missions.wifi.group_expert import (
    GroupExpertConfig,
    find_groups,
    place_uavs_by_groups,
    service_units,
)
from uav_swarm.missions.wifi.rules import assign_users, is_valid_placement
from uav_swarm.missions.wifi.task import WifiConfig, WifiTask
from uav_swarm.world.comms import evaluate_coverage
from uav_swarm.world.crowd import CrowdSim
from uav_swarm.world.scenario import random_scenario

S2 = WifiTask(WifiConfig(strategy=2))


def blob(centre, n, spread_m=4.0, seed=0):
    rng = np.random.default_rng(seed)
    return np.asarray(centre, dtype=np.float64) + rng.uniform(-spread_m, spread_m, size=(n, 2))


def crowd(i, seed=31):
    """A held-out crowd (seed 31 is used by no dataset) with its velocities."""
    config = S2.config
    rng = np.random.default_rng(sample_seed(seed, "test", i))
    sim = CrowdSim(random_scenario(rng, config.scenario), config.crowd, rng)
    sim.step(int(round(float(rng.uniform(config.warmup_min_s, config.warmup_max_s)) / config.crowd.dt_s)))
    return np.array(sim.positions_m), np.array(sim.velocities_m_s)


def test_groups_are_connected_components_of_the_link_graph():
    users = np.vstack([blob((50, 50), 10, 1.0), blob((150, 150), 10, 1.0, seed=1)])
    labels = find_groups(users, 3.0)
    assert len(set(labels[:10])) == 1 and len(set(labels[10:])) == 1 and labels[0] != labels[10]


@pytest.mark.parametrize("i", range(6))
def test_placements_obey_the_strategy_2_rules_on_real_crowds(i):
    users, vels = crowd(i)
    placement = S2.expert_placement_m(users, vels)
    state = assign_users(users, placement, S2.rules.radius_m)
    assert is_valid_placement(state, S2.rules)
    assert 1 <= len(placement) <= 10
    gaps = np.linalg.norm(placement[:, None] - placement[None], axis=-1)[np.triu_indices(len(placement), 1)]
    assert gaps.size == 0 or gaps.min() >= S2.rules.min_separation_m - 1e-9


def test_a_large_group_is_split_between_uavs_each_under_the_cap():
    users = blob((100.0, 100.0), 72, spread_m=6.0)
    placement = place_uavs_by_groups(users, S2.rules, GroupExpertConfig())
    state = assign_users(users, placement, S2.rules.radius_m)
    assert len(placement) == 2 and state.n_served == 72
    assert np.all((state.counts >= 31) & (state.counts <= 40))


def test_units_keep_their_margins_over_the_horizon():
    users, vels = crowd(2)
    config = GroupExpertConfig()
    reach = S2.rules.radius_m + config.range_margin_m
    for unit in service_units(users, S2.rules, config, vels):
        for t in np.linspace(0.0, config.horizon_s, config.horizon_steps + 1):
            moved = users + vels * t
            near = np.linalg.norm(moved[:, None] - unit.uavs_m[None], axis=-1)
            owner = near.argmin(axis=1)
            within = near.min(axis=1) <= reach
            assert np.bincount(owner[within], minlength=len(unit.uavs_m)).max() <= S2.rules.cap


def test_placement_held_still_keeps_most_of_its_service_a_second_later():
    kept, start = [], []
    for i in range(4):
        config = S2.config
        rng = np.random.default_rng(sample_seed(32, "test", i))
        sim = CrowdSim(random_scenario(rng, config.scenario), config.crowd, rng)
        sim.step(150)
        placement = S2.expert_placement_m(np.array(sim.positions_m), np.array(sim.velocities_m_s))
        start.append(evaluate_coverage(np.array(sim.positions_m), placement, config.radio).qos_s2)
        sim.step(10)  # one second of walking
        kept.append(evaluate_coverage(np.array(sim.positions_m), placement, config.radio).qos_s2)
    assert np.mean(kept) >= 0.8 * np.mean(start)


def test_deterministic_and_equivariant_under_the_grid_symmetries():
    users, vels = crowd(4)
    scene = S2.transform_scene(S2.sample(np.random.default_rng(0)), False, False, False)
    scene = type(scene)(users, 0.0, vels)
    reference = S2.expert(scene)
    np.testing.assert_array_equal(reference, S2.expert(scene))
    for symmetry in SYMMETRIES[1:]:
        moved = S2.expert(S2.transform_scene(scene, *symmetry))
        expected = transform_positions(reference, S2.shape, *symmetry)
        assert len(moved) == len(expected)
        distance = np.linalg.norm(moved[:, None] - expected[None], axis=-1).min(axis=1)
        assert distance.max() < 0.5  # pixels


def test_the_search_expert_stays_selectable_and_groups_refuse_strategy_1():
    users, vels = crowd(1)
    search = WifiTask(WifiConfig(strategy=2, expert=WifiExpertConfig(method="search")))
    assert is_valid_placement(assign_users(users, search.expert_placement_m(users), 30.0), search.rules)
    with pytest.raises(ConfigError, match="strategy 2"):
        WifiTask(WifiConfig(strategy=1, expert=WifiExpertConfig(method="groups"))).expert_placement_m(users)
    with pytest.raises(ConfigError, match="method"):
        WifiExpertConfig(method="greedy")
    with pytest.raises(ValueError, match="strategy 2"):
        place_uavs_by_groups(users, WifiTask(WifiConfig(strategy=1)).rules, GroupExpertConfig())
