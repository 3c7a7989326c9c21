"""The stable strategy-2 expert: the consensus of seeded jittered solves, made valid on the crowd itself."""

import numpy as np
import pytest

from typed_config import ConfigError
from uav_swarm.missions.wifi.rules import assign_users, is_valid_placement
from uav_swarm.missions.wifi.stable_expert import StableExpertConfig, place_uavs_stable
from uav_swarm.missions.wifi.task import WifiConfig, WifiTask
from uav_swarm.world.comms import RadioConfig, evaluate_coverage
from uav_swarm.world.scenario import ScenarioConfig

SMALL = ScenarioConfig(width_m=100.0, height_m=100.0, n_groups_min=3, n_groups_max=4, n_obstacles=2)


def _task(radio: RadioConfig | None = None, **stable) -> WifiTask:
    expert = WifiConfig().expert.replace(method="stable", stable=StableExpertConfig(**stable))
    return WifiTask(WifiConfig(strategy=2, radio=radio or RadioConfig(), scenario=SMALL, expert=expert))


def test_the_majority_of_the_solves_wins_over_the_crowds_own_outlier():
    users = np.random.default_rng(0).uniform(0.0, 100.0, (50, 2))
    consensus, outlier = np.array([[20.0, 20.0], [70.0, 70.0]]), np.array([[50.0, 5.0]])
    seen = []

    def solve(crowd):
        seen.append(crowd)
        return outlier if np.array_equal(crowd, users) else consensus + 0.1 * len(seen)

    placement = place_uavs_stable(users, StableExpertConfig(copies=5), solve, lambda crowd, uavs: uavs)
    assert np.array_equal(seen[0], users) and len(seen) == 5
    assert 0.0 < np.abs(seen[1] - users).max() < 5.0  # jittered copies, near the crowd
    assert placement.shape == (2, 2) and np.abs(placement - consensus).max() <= 0.5
    alone = place_uavs_stable(users, StableExpertConfig(copies=1), solve, lambda crowd, uavs: uavs)
    assert np.array_equal(alone, outlier)


def test_the_paper_radios_placement_keeps_the_rule_and_the_same_crowd_gives_the_same_placement():
    task = _task(copies=3)
    scene = task.sample(np.random.default_rng(1))
    placement = task.expert_placement_m(scene.users_m)
    assert 1 <= len(placement) <= 10
    assert is_valid_placement(assign_users(scene.users_m, placement, task.rules.radius_m), task.rules)
    assert np.array_equal(placement, task.expert_placement_m(scene.users_m))


def test_under_admission_control_every_uav_admits_31_to_40_users():
    radio = RadioConfig(station_limit="auto")
    task = _task(radio, copies=3)
    scene = task.sample(np.random.default_rng(2))
    placement = task.expert_placement_m(scene.users_m)
    coverage = evaluate_coverage(scene.users_m, placement, radio)
    assert 1 <= len(placement) <= 10
    assert coverage.users_per_uav.min() >= 31 and coverage.users_per_uav.max() <= 40


def test_strategy_one_and_bad_settings_are_refused():
    expert = WifiConfig().expert.replace(method="stable")
    with pytest.raises(ConfigError, match="strategy 2"):
        WifiTask(WifiConfig(strategy=1, expert=expert)).expert_placement_m(np.zeros((40, 2)))
    with pytest.raises(ConfigError, match="copies"):
        StableExpertConfig(copies=0)
