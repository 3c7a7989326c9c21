"""Planning in motion: UAVs follow their groups, re-solve only when it pays, and the flight replays."""

from __future__ import annotations

import numpy as np
import pytest

from uav_swarm.missions.wifi.task import WifiConfig, coverage_rules
from uav_swarm.planning.motion import MotionConfig, MotionPlanning, time_to_reach, travelled_m
from uav_swarm.planning.planner import PlannerConfig, make_planner
from uav_swarm.runs.simulate import run_sequence
from uav_swarm.runs.simulate_config import SimulateConfig
from uav_swarm.world.uav import UAVConfig


def group(centre, n, spread_m=4.0, seed=0):
    rng = np.random.default_rng(seed)
    return np.asarray(centre, dtype=np.float64) + rng.uniform(-spread_m, spread_m, size=(n, 2))


def motion(strategy=1, n_uavs=2, **config):
    task = WifiConfig(strategy=strategy)
    return MotionPlanning(n_uavs, coverage_rules(task, max_uavs=n_uavs), task.radio, strategy, (200.0, 200.0),
                          UAVConfig(), MotionConfig(**config))


def test_time_to_reach_and_distance_flown_are_inverse():
    uav = UAVConfig()
    for t in (0.3, 1.0, 2.0, 5.0):
        d = travelled_m(t, uav.max_speed_m_s, uav.max_accel_m_s2)
        assert d > 0
        # from rest to rest takes longer than flying through at full speed
        assert time_to_reach(np.array([d]), uav.max_speed_m_s, uav.max_accel_m_s2)[0] >= t


def test_a_walking_group_keeps_its_uav_which_follows_it_without_jumps():
    planner = motion(strategy=1, n_uavs=2)
    users = group((50.0, 100.0), 36)
    vels = np.tile([1.3, 0.0], (len(users), 1))
    uavs = np.array([[45.0, 95.0], [150.0, 30.0]])
    rng = np.random.default_rng(1)
    first = planner.plan(users, vels, uavs, users.mean(axis=0)[None])
    owner = int(np.argmin(np.linalg.norm(first.targets_m - users.mean(axis=0), axis=1)))
    assert owner == 0
    previous = first.targets_m
    for _ in range(12):
        users = users + vels  # one second of walking
        uavs = previous.copy()  # the UAVs reached their targets
        # a snapshot solver that lands somewhere else in the group every second
        proposal = users.mean(axis=0) + rng.uniform(-8.0, 8.0, size=2)
        plan = planner.plan(users, vels, uavs, proposal[None])
        assert plan.kept[owner] and plan.option == "hybrid"
        step = np.linalg.norm(plan.targets_m[owner] - previous[owner])
        assert 0.8 < step < 2.0  # it walks with the group (1.3 m/s), it does not jump
        centre = users.mean(axis=0) + 1.3 * np.array([1.0, 0.0])  # aimed one second ahead
        assert np.linalg.norm(plan.targets_m[owner] - centre) < 3.0
        previous = plan.targets_m


def test_a_group_that_splits_gets_a_second_uav_within_a_few_replans():
    planner = make_planner("expert", 3, WifiConfig(strategy=1), config=PlannerConfig())
    north, south = group((100.0, 100.0), 36, seed=1), group((100.0, 100.0), 36, seed=2)
    vn, vs = np.tile([0.0, 2.0], (36, 1)), np.tile([0.0, -2.0], (36, 1))
    uavs = np.array([[100.0, 100.0], [20.0, 20.0], [180.0, 20.0]])
    served_both_at = None
    for second in range(40):
        users, vels = np.vstack([north, south]), np.vstack([vn, vs])
        plan = planner.plan(users, uavs, vels)
        near_north = np.linalg.norm(plan.targets_m - north.mean(axis=0), axis=1).min()
        near_south = np.linalg.norm(plan.targets_m - south.mean(axis=0), axis=1).min()
        if served_both_at is None and near_north < 10.0 and near_south < 10.0:
            served_both_at = second
        uavs = plan.targets_m.copy()
        north, south = north + vn, south + vs
    # the groups are 2 x 30 m apart after 15 s: then one UAV can no longer cover both
    assert served_both_at is not None and served_both_at <= 20


def test_a_kept_uav_is_never_sent_further_than_it_flies_before_the_next_replan():
    planner = motion(strategy=2, n_uavs=3)
    a, b = group((60.0, 60.0), 36, seed=3), group((140.0, 140.0), 36, seed=4)
    users = np.vstack([a, b])
    vels = np.vstack([np.tile([1.0, 0.5], (36, 1)), np.tile([-0.8, 0.9], (36, 1))])
    uavs = np.array([[55.0, 55.0], [145.0, 135.0], [100.0, 20.0]])
    previous = planner.plan(users, vels, uavs, np.array([a.mean(0), b.mean(0)])).targets_m
    reach = travelled_m(1.0, UAVConfig().max_speed_m_s, UAVConfig().max_accel_m_s2)
    for second in range(8):
        users = users + vels
        proposals = np.array([users[:36].mean(0), users[36:].mean(0)]) + (-1) ** second * 15.0
        plan = planner.plan(users, vels, previous.copy(), proposals)
        moved = np.linalg.norm(plan.targets_m - previous, axis=1)
        assert np.all(moved[plan.kept] <= reach), (second, moved, plan.kept)
        assert plan.kept[:2].all()  # both groups keep their UAV: the far proposals do not pay
        previous = plan.targets_m


def test_strategy_2_spares_park_away_from_every_user():
    planner = motion(strategy=2, n_uavs=3)
    users = group((100.0, 100.0), 36)
    vels = np.zeros_like(users)
    uavs = np.array([[100.0, 100.0], [102.0, 98.0], [98.0, 103.0]])  # all three over the group
    plan = planner.plan(users, vels, uavs, users.mean(axis=0)[None])
    spares = (plan.candidate_index < 0) & ~plan.kept
    assert spares.sum() == 2
    reach = coverage_rules(WifiConfig(strategy=2)).radius_m + MotionConfig().park_margin_m
    distance = np.linalg.norm(users[:, None] - plan.targets_m[None, spares], axis=-1)
    assert distance.min() > reach  # parked spares take no user from the serving UAV


def test_flight_in_motion_replays_with_the_same_seed():
    config = SimulateConfig(duration_s=6.0, seed=3, gif=False, publish_telemetry=False, compare_expert=False)
    runs = []
    for _ in range(2):
        planner = make_planner("expert", config.n_uavs, config.task, config=config.planning,
                               uav_config=config.uav)
        runs.append(run_sequence(config, planner, "expert"))
    np.testing.assert_array_equal(runs[0].qos_s1, runs[1].qos_s1)
    np.testing.assert_array_equal(runs[0].final_targets_m, runs[1].final_targets_m)
    assert runs[0].distance_m == runs[1].distance_m > 0


def test_snapshot_mode_stays_selectable_and_differs():
    config = SimulateConfig(duration_s=4.0, seed=1, gif=False, publish_telemetry=False, compare_expert=False)
    plans = {}
    for mode in ("motion", "snapshot"):
        planning = config.planning.replace(mode=mode)
        planner = make_planner("expert", config.n_uavs, config.task, config=planning, uav_config=config.uav)
        result = planner.plan(np.array(group((100.0, 100.0), 40)), np.full((config.n_uavs, 2), 20.0))
        plans[mode] = result.option
    assert plans == {"motion": "hybrid", "snapshot": "snapshot"}


def test_velocities_must_match_the_crowd():
    planner = make_planner("expert", 2)
    with pytest.raises(ValueError, match="pedestrian_velocities_m_s"):
        planner.plan(group((50.0, 50.0), 40), np.zeros((2, 2)), np.zeros((3, 2)))
