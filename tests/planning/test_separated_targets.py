"""The planners' targets keep the UAVs' minimum separation: learned peaks, refinement, assignment, motion."""

import numpy as np
import pytest
from scipy.spatial.distance import pdist

from learning.peaks import find_peaks
from typed_config import ConfigError
from uav_swarm.missions.wifi.task import WifiConfig
from uav_swarm.planning.assignment import assign_targets
from uav_swarm.planning.planner import PlannerConfig, make_planner
from uav_swarm.planning.spacing import separate_targets
from uav_swarm.runs.simulate_config import SimulateConfig
from uav_swarm.world.comms import RadioConfig
from uav_swarm.world.uav import UAVConfig

ADMISSION = WifiConfig(strategy=2, radio=RadioConfig(station_limit="auto"))


def dense_crowd(seed: int = 3) -> np.ndarray:
    """A very dense group of 90 (two co-located UAVs would admit 80) and two groups 2 m apart."""
    rng = np.random.default_rng(seed)
    return np.concatenate([rng.normal([100.0, 100.0], 1.5, (90, 2)), rng.normal([40.0, 150.0], 1.0, (40, 2)),
                           rng.normal([42.0, 150.0], 1.0, (40, 2))])


def test_peaks_refined_to_subpixel_keep_the_separation_in_pixels():
    u = np.zeros((16, 16))
    u[8, 4], u[8, 3], u[8, 5] = 1.0, 0.2, 0.9  # a peak pulled right by its neighbour
    u[8, 7], u[8, 6], u[8, 8] = 0.95, 0.85, 0.1  # one 3 px away, pulled left
    loose = find_peaks(u)  # the suppression's 2 px hold on the pixel centres, 3 px apart
    assert len(loose) == 2 and pdist(loose).min() < 2.5
    separated = find_peaks(u, min_separation_px=2.5)
    assert len(separated) == 1 and separated[0, 0] == pytest.approx(loose[0, 0])


@pytest.mark.parametrize("mode", ["snapshot", "motion"])
@pytest.mark.parametrize("kind, task, refine", [
    ("learned", ADMISSION, True), ("learned", ADMISSION, False), ("learned", WifiConfig(strategy=1), False),
    ("expert", ADMISSION, False)])
def test_planners_keep_every_pair_of_targets_apart(kind, task, refine, mode):
    uav = UAVConfig(min_separation_m=6.0)
    config = PlannerConfig(mode=mode, refine=refine, engine="torch-eager")
    planner = make_planner(kind, n_uavs=6, task_config=task, config=config, uav_config=uav)
    crowd = dense_crowd()
    uavs = np.array([[100.0, 100.0], [100.5, 100.2], [99.8, 100.4], [41.0, 150.0], [41.5, 150.0],
                     [10.0, 10.0]])
    for step in range(4):  # replans: held spares, kept followers and fresh proposals
        result = planner.plan(crowd + 0.3 * step, uavs)
        assert pdist(result.targets_m).min() >= 6.0 - 1e-9, (step, result.targets_m)
        uavs = result.targets_m


def test_snapshot_assignment_keeps_no_previous_target_near_another_candidate():
    uavs = np.array([[0.0, 0.0], [50.0, 0.0], [90.0, 90.0]])
    previous = np.array([[10.0, 10.0], [50.0, 10.0], [90.0, 90.0]])
    candidates = np.array([[8.0, 10.0], [13.5, 10.0], [50.0, 12.0]])  # separated by 5.5 m and more
    result = assign_targets(uavs, candidates, previous, hysteresis_m=5.0, min_gap_m=5.0,
                            upper_m=np.array([100.0, 100.0]))
    assert pdist(result.targets_m).min() >= 5.0
    assert result.kept.tolist() == [False, True, False]  # keeping (10, 10) would stand 3.5 m from (13.5, 10)
    loose = assign_targets(uavs, candidates, previous, hysteresis_m=5.0, min_gap_m=0.0)
    assert loose.kept[0] and pdist(loose.targets_m).min() < 5.0


def test_the_projection_moves_only_what_it_must():
    targets = np.array([[50.0, 50.0], [51.0, 50.0], [80.0, 80.0], [0.0, 0.0], [0.5, 0.0]])
    out = separate_targets(targets, 5.0, upper_m=np.array([100.0, 100.0]))
    assert pdist(out).min() >= 5.0
    assert np.array_equal(out[[0, 2, 3]], targets[[0, 2, 3]])  # the first of each pair stays
    assert np.all((out >= 0.0) & (out <= 100.0))
    assert np.linalg.norm(out[1] - targets[1]) < 5.0


@pytest.mark.parametrize("side_m", [50.0, 40.0])
def test_crowded_targets_are_separated_whenever_the_fleet_check_accepts_the_fleet(side_m):
    rng = np.random.default_rng(14)
    area = np.array([side_m, side_m])
    for _ in range(25):  # 10 targets pulled onto one or two groups, 14 m apart, in a small square
        groups = rng.uniform(0.0, side_m, (2, 2))
        targets = np.clip(groups[rng.integers(0, 2, 10)] + rng.normal(0.0, 4.0, (10, 2)), 0.0, side_m)
        out = separate_targets(targets, 14.0, rng.permutation(10), area)
        assert pdist(out).min() >= 14.0 - 1e-9
        assert np.all((out >= 0.0) & (out <= side_m))
    with pytest.raises(ConfigError, match=r"uav.min_separation_m = 30 m cannot be kept by 10 UAVs"):
        separate_targets(targets, 30.0, upper_m=area)


def test_simulate_threads_the_uav_minimum_and_refuses_a_contradiction():
    assert SimulateConfig.from_dict({"uav": {"min_separation_m": 8.0}}).task.min_separation_m == 8.0
    with pytest.raises(ConfigError, match=r"task.min_separation_m = 7 differs from uav.min_separation_m = 5"):
        SimulateConfig.from_dict({"task": {"min_separation_m": 7.0}})
    with pytest.raises(ConfigError, match=r"uav.min_separation_m = 90 m cannot be kept by 10 UAVs"):
        SimulateConfig.from_dict({"uav": {"min_separation_m": 90.0}})
    assert SimulateConfig.from_dict({"n_uavs": 2, "uav": {"min_separation_m": 90.0},
                                     "task": {"expert": {"max_uavs": 2}}}).task.min_separation_m == 90.0


def test_fly_and_the_env_refuse_a_minimum_the_fleet_cannot_keep():
    from uav_swarm.env.config import EnvConfig
    from uav_swarm.runs.fly_config import FlyConfig

    with pytest.raises(ConfigError, match=r"uav.min_separation_m = 90 m cannot be kept by 10 UAVs"):
        FlyConfig.from_dict({"bridge_config": "bridge.toml", "uav": {"min_separation_m": 90.0}})
    fly = FlyConfig.from_dict({"bridge_config": "bridge.toml", "uav": {"min_separation_m": 9.0}})
    assert fly.task.min_separation_m == 9.0
    with pytest.raises(ConfigError, match=r"uav.min_separation_m = 90 m cannot be kept by 10 UAVs"):
        EnvConfig.from_dict({"n_uavs": 10, "uav": {"min_separation_m": 90.0}})
    assert EnvConfig.from_dict({"n_uavs": 4, "uav": {"min_separation_m": 90.0}}).uav.min_separation_m == 90.0
