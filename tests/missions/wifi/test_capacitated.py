"""The strategy-2 expert under admission control (the capacitated maximal covering problem)."""

import numpy as np
import pytest

from typed_config import ConfigError
from uav_swarm.missions.wifi.capacitated import admitted_users, place_uavs_capacitated
from uav_swarm.missions.wifi.exact import capacitated_optimum
from uav_swarm.missions.wifi.rules import candidate_grid
from uav_swarm.missions.wifi.task import WifiConfig, WifiTask
from uav_swarm.world.comms import RadioConfig, evaluate_coverage
from uav_swarm.world.scenario import ScenarioConfig

ADMISSION = RadioConfig(station_limit="auto")


def small_task() -> WifiTask:
    scenario = ScenarioConfig(width_m=100.0, height_m=100.0, n_groups_min=3, n_groups_max=4, n_obstacles=2)
    return WifiTask(WifiConfig(strategy=2, radio=ADMISSION, scenario=scenario))


def test_auto_picks_the_capacitated_expert_under_admission_control_only():
    assert WifiConfig(strategy=2, radio=ADMISSION).expert.method_for(WifiTask(
        WifiConfig(strategy=2, radio=ADMISSION)).rules) == "capacitated"
    assert WifiConfig(strategy=2).expert.method_for(WifiTask(WifiConfig(strategy=2)).rules) == "groups"
    expert = WifiConfig().expert.replace(method="capacitated")
    with pytest.raises(ConfigError, match="needs admission control"):
        WifiTask(WifiConfig(strategy=2, expert=expert)).expert_placement_m(np.zeros((40, 2)))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_every_uav_admits_between_31_and_40_users_judged_by_the_radio(seed):
    task = WifiTask(WifiConfig(strategy=2, radio=ADMISSION))
    scene = task.sample(np.random.default_rng(seed))
    placement = task.expert_placement_m(scene.users_m)
    coverage = evaluate_coverage(scene.users_m, placement, ADMISSION)
    assert 1 <= len(placement) <= 10
    assert coverage.users_per_uav.min() >= 31 and coverage.users_per_uav.max() <= 40
    assert coverage.qos_s2 == coverage.qos_s1  # every admitted user gets >= 5 Mbps
    assert np.array_equal(admitted_users(scene.users_m, placement, task.rules) >= 0, coverage.covered)


@pytest.mark.parametrize("seed", [3, 4])
def test_at_rest_it_admits_at_least_as_many_users_as_the_other_experts(seed):
    task = WifiTask(WifiConfig(strategy=2, radio=ADMISSION))
    scene = task.sample(np.random.default_rng(seed))
    ours = evaluate_coverage(scene.users_m, task.expert_placement_m(scene.users_m), ADMISSION).qos_s2
    for method in ("search", "groups"):
        other = WifiTask(WifiConfig(strategy=2, expert=task.config.expert.replace(method=method)))
        placement = other.expert_placement_m(scene.users_m, scene.velocities_m_s)
        assert ours >= evaluate_coverage(scene.users_m, placement, ADMISSION).qos_s2


def test_the_same_crowd_gives_the_same_placement():
    task = WifiTask(WifiConfig(strategy=2, radio=ADMISSION))
    scene = task.sample(np.random.default_rng(5))
    assert np.array_equal(task.expert_placement_m(scene.users_m), task.expert_placement_m(scene.users_m))


def test_a_crowd_too_small_for_any_uav_gets_none_and_bad_rules_are_refused():
    task = WifiTask(WifiConfig(strategy=2, radio=ADMISSION))
    assert task.expert_placement_m(np.full((30, 2), 50.0)).shape == (0, 2)
    with pytest.raises(ValueError, match="station limit"):
        place_uavs_capacitated(np.zeros((50, 2)), WifiTask(WifiConfig(strategy=1)).rules, 200.0, 200.0)


def test_against_the_exact_capacitated_optimum_on_a_small_scene():
    """The MILP's optimum bounds what any placement on its grid admits; the expert is judged by the radio."""
    task = small_task()
    scene = task.sample(np.random.default_rng(0))
    admitted = int(evaluate_coverage(scene.users_m, task.expert_placement_m(scene.users_m), ADMISSION)
                   .covered.sum())
    optimum = capacitated_optimum(scene.users_m, task.rules, candidate_grid(100.0, 100.0, 5.0)[0], 30.0)
    radio_judged = int((admitted_users(scene.users_m, optimum.uavs_m, task.rules) >= 0).sum())
    assert admitted >= radio_judged  # the optimum's own positions, under the radio's admission
    assert admitted >= 0.9 * optimum.n_served


def test_completing_a_proposal_admits_no_fewer_users_and_keeps_the_rule():
    from uav_swarm.missions.wifi.capacitated import complete_capacitated

    task = WifiTask(WifiConfig(strategy=2, radio=ADMISSION))
    scene = task.sample(np.random.default_rng(8))
    expert = task.expert_placement_m(scene.users_m)
    rough = expert[: max(1, len(expert) // 2)] + 4.0  # half the UAVs, 4 m off
    before = evaluate_coverage(scene.users_m, rough, ADMISSION)
    done = complete_capacitated(scene.users_m, rough, task.rules, 200.0, 200.0)
    after = evaluate_coverage(scene.users_m, done, ADMISSION)
    assert after.covered.sum() >= before.covered.sum()
    assert len(done) >= len(rough) and after.users_per_uav.min() >= 31
