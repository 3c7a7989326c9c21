"""Every Wi-Fi placement keeps its UAVs at least the minimum separation apart, on crowds that pull two
UAVs onto one dense group (judged by scipy's pdist, independently of the optimisers' own checks)."""

import numpy as np
import pytest
from scipy.spatial.distance import pdist

from uav_swarm.missions.wifi.exact import capacitated_optimum, exact_placement
from uav_swarm.missions.wifi.expert import WifiExpertConfig
from uav_swarm.missions.wifi.refine import WifiRefineConfig, refine_placement, strategy_refinement
from uav_swarm.missions.wifi.rules import far_from, is_separated, keep_separated
from uav_swarm.missions.wifi.task import WifiConfig, WifiTask, coverage_rules
from uav_swarm.world.comms import RadioConfig

ADMISSION = RadioConfig(station_limit="auto")  # 40 stations per UAV


def closest_m(placement: np.ndarray) -> float:
    return float(pdist(placement).min()) if len(placement) > 1 else np.inf


def dense(n: int, spread_m: float = 1.5, seed: int = 3, centre=(100.0, 100.0)) -> np.ndarray:
    return np.random.default_rng(seed).normal(centre, spread_m, size=(n, 2))


def two_clusters_2m_apart(seed: int = 3) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.concatenate([rng.normal([99.0, 100.0], 1.0, (45, 2)), rng.normal([101.0, 100.0], 1.0, (45, 2))])


def task(minimum_m: float, **fields) -> WifiTask:
    return WifiTask(WifiConfig(min_separation_m=minimum_m, **fields))


def test_the_capacitated_expert_no_longer_stacks_two_uavs_on_one_dense_group():
    users = dense(90)  # two co-located UAVs would admit 80 of them
    stacked = task(0.0, strategy=2, radio=ADMISSION).expert_placement_m(users)
    assert len(stacked) == 2 and closest_m(stacked) < 5.0  # what the crowd pulls the optimiser to
    separated = task(5.0, strategy=2, radio=ADMISSION).expert_placement_m(users)
    assert len(separated) == 2 and closest_m(separated) >= 5.0


@pytest.mark.parametrize("minimum_m", [5.0, 12.0])
@pytest.mark.parametrize("fields, users", [
    ({"strategy": 1}, two_clusters_2m_apart()),
    ({"strategy": 2, "expert": WifiExpertConfig(method="search")}, two_clusters_2m_apart()),
    ({"strategy": 2, "expert": WifiExpertConfig(method="groups")}, dense(72, spread_m=3.0)),
    ({"strategy": 2, "radio": ADMISSION}, dense(90)),
    ({"strategy": 2, "radio": ADMISSION}, two_clusters_2m_apart()),
])
def test_every_expert_keeps_the_minimum(fields, users, minimum_m):
    placement = task(minimum_m, **fields).expert_placement_m(users)
    assert len(placement) >= 1
    assert closest_m(placement) >= minimum_m


@pytest.mark.parametrize("fields, users", [
    ({"strategy": 1}, dense(90)), ({"strategy": 2}, dense(70)),
    ({"strategy": 2, "radio": ADMISSION}, dense(90))])
def test_the_refinement_of_stacked_proposals_keeps_the_minimum(fields, users):
    rules = task(5.0, **fields).rules
    stacked = np.array([[100.0, 100.0], [100.5, 100.0], [101.0, 100.5]])
    refined = refine_placement(users, stacked, rules, 200.0, 200.0, strategy_refinement(fields["strategy"]))
    assert len(refined) >= 1 and closest_m(refined) >= 5.0
    searched = refine_placement(users, stacked, rules, 200.0, 200.0, WifiRefineConfig(max_moves=4))
    assert closest_m(searched) >= 5.0


def test_the_exact_milps_exclude_candidate_pairs_closer_than_the_minimum():
    offsets = np.array([[0.0, 0.0], [1.0, 0.0], [-3.0, 0.0], [3.0, 0.0], [0.0, -3.0], [0.0, 3.0], [2.0, 2.0]])
    candidates = 100.0 + offsets  # only sites near the group: two of them must share it
    for minimum_m in (0.0, 5.0):
        rules = coverage_rules(WifiConfig(strategy=2, min_separation_m=minimum_m))
        served = exact_placement(dense(70), rules, candidates, time_limit_s=20.0)
        assert len(served.uavs_m) == 2 and served.optimal
        capacitated = capacitated_optimum(
            dense(90), coverage_rules(WifiConfig(strategy=2, radio=ADMISSION, min_separation_m=minimum_m)),
            candidates, time_limit_s=20.0)
        assert len(capacitated.uavs_m) == 2 and capacitated.n_served == 80
        if minimum_m:
            assert closest_m(served.uavs_m) >= minimum_m and closest_m(capacitated.uavs_m) >= minimum_m


def test_the_separation_helpers():
    uavs = np.array([[0.0, 0.0], [3.0, 0.0], [6.0, 0.0]])
    assert keep_separated(uavs, 5.0).tolist() == [0, 2]
    assert not is_separated(uavs, 5.0) and is_separated(uavs, 3.0) and is_separated(uavs, 0.0)
    assert far_from(np.array([[0.0, 4.9], [0.0, 5.0]]), uavs[:1], 5.0).tolist() == [False, True]


def test_a_task_minimum_the_fleet_cannot_keep_in_the_area_is_refused():
    from typed_config import ConfigError

    with pytest.raises(ConfigError, match=r"task.min_separation_m = 90 m cannot be kept by 10 UAVs"):
        WifiConfig(min_separation_m=90.0)
    assert coverage_rules(WifiConfig(min_separation_m=8.0)).min_separation_m == 8.0


def test_a_config_saved_with_the_group_experts_own_minimum_reads_as_the_tasks():
    from typed_config import ConfigError

    saved = WifiConfig(strategy=2).to_dict()
    saved.pop("min_separation_m")
    saved["expert"]["groups"]["min_separation_m"] = 7.0  # as the checkpoints before one minimum kept it
    assert WifiConfig.from_dict(saved).min_separation_m == 7.0
    with pytest.raises(ConfigError, match="expert.groups.min_separation_m = 7.0 differs from min_sep"):
        WifiConfig.from_dict({**saved, "min_separation_m": 5.0})
