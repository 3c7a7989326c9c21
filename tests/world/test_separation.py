import numpy as np
import pytest
from scipy.spatial.distance import pdist

from typed_config import ConfigError
from uav_swarm.world.separation import (
    SeparationMonitor,
    check_fleet_fits,
    closest_pair,
    max_spread_m,
)
from uav_swarm.world.step_guard import guard_commands, stopping_distance_m
from uav_swarm.world.uav import UAVConfig, fly_step, waypoint_velocity

DT_S = 0.1
AREA_M = np.array([100.0, 100.0])


def _fly(start_m, targets_m, config, steps, *, policy=None, altitudes_m=None, seed=0):
    """Fly a fleet through the guard; returns the closest distance at any step (scipy) and the end."""
    rng = np.random.default_rng(seed)
    p, v = np.array(start_m, dtype=float), np.zeros((len(start_m), 2))
    closest, holds = np.inf, 0
    for _ in range(steps):
        wanted = (waypoint_velocity(p, targets_m, DT_S, config) if policy is None
                  else rng.uniform(-policy, policy, size=p.shape))
        command, held = guard_commands(p, v, wanted, DT_S, config, altitudes_m, upper_m=AREA_M)
        holds += int(held.sum())
        p, v = fly_step(p, v, command, DT_S, config, AREA_M)
        horizontal = pdist(p)
        if altitudes_m is not None:
            horizontal = np.sqrt(horizontal**2 + pdist(np.asarray(altitudes_m)[:, None]) ** 2)
        closest = min(closest, horizontal.min())
    return closest, p, holds


def test_head_on_swap_keeps_the_minimum_and_arrives():
    config = UAVConfig(min_separation_m=5.0)
    start = np.array([[20.0, 50.0], [80.0, 50.0]])
    closest, end, holds = _fly(start, start[::-1], config, 400)
    assert closest >= 5.0
    assert holds > 0  # without the guard they would meet head-on
    np.testing.assert_allclose(end, start[::-1], atol=0.1)


def test_four_converging_on_one_point_never_meet():
    config = UAVConfig(min_separation_m=5.0)
    start = np.array([[10.0, 50.0], [90.0, 50.0], [50.0, 10.0], [50.0, 90.0]])
    closest, end, _ = _fly(start, np.full((4, 2), 50.0), config, 300)
    assert closest >= 5.0
    assert np.linalg.norm(end - 50.0, axis=1).max() <= 5.0  # packed around the point as tight as allowed


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_ten_reassigned_by_a_permutation(seed):
    config = UAVConfig(min_separation_m=5.0)
    grid = np.stack(np.meshgrid([15.0, 32.5, 50.0, 67.5, 85.0], [35.0, 65.0]), -1).reshape(-1, 2)
    targets = grid[np.random.default_rng(seed).permutation(10)]
    closest, end, holds = _fly(grid, targets, config, 800)
    assert closest >= 5.0
    assert holds > 0
    assert np.median(np.linalg.norm(end - targets, axis=1)) < 1.0


@pytest.mark.parametrize("seed", range(4))
def test_random_commands_never_break_the_minimum(seed):
    config = UAVConfig(min_separation_m=6.0, max_speed_m_s=12.0, max_accel_m_s2=4.0)
    rng = np.random.default_rng(100 + seed)
    start = []
    while len(start) < 10:
        candidate = rng.uniform(0.0, 60.0, 2)
        if all(np.linalg.norm(candidate - other) >= 7.0 for other in start):
            start.append(candidate)
    closest, _, holds = _fly(np.array(start), None, config, 300, policy=12.0, seed=seed)
    assert closest >= 6.0 - 1e-9
    assert holds > 0


def test_layers_at_least_the_minimum_apart_never_hold():
    config = UAVConfig(min_separation_m=5.0, layer_step_m=5.0)
    start = np.array([[20.0, 50.0], [80.0, 50.0]])
    altitudes = config.altitudes_m(2)
    closest, end, holds = _fly(start, start[::-1], config, 300, altitudes_m=altitudes)
    assert holds == 0 and closest >= 5.0
    np.testing.assert_allclose(end, start[::-1], atol=0.1)


def test_a_batch_equals_its_worlds_one_by_one():
    config = UAVConfig(min_separation_m=5.0)
    rng = np.random.default_rng(4)
    p = rng.uniform(0.0, 40.0, size=(6, 5, 2))
    v = rng.uniform(-5.0, 5.0, size=(6, 5, 2))
    wanted = rng.uniform(-10.0, 10.0, size=(6, 5, 2))
    batch, held = guard_commands(p, v, wanted, DT_S, config, upper_m=AREA_M)
    for world in range(6):
        one, one_held = guard_commands(p[world], v[world], wanted[world], DT_S, config, upper_m=AREA_M)
        np.testing.assert_array_equal(batch[world], one)
        np.testing.assert_array_equal(held[world], one_held)


def test_stopping_distance_is_what_the_kinematics_fly():
    config = UAVConfig(max_accel_m_s2=3.0)
    for speed in (0.0, 0.2, 4.0, 9.7):
        p, v = np.zeros((1, 2)), np.array([[speed, 0.0]])
        for _ in range(200):
            p, v = fly_step(p, v, np.zeros((1, 2)), DT_S, config, np.array([1e6, 1e6]))
        assert p[0, 0] == pytest.approx(float(stopping_distance_m(np.array(speed), 3.0, DT_S)), abs=1e-9)


def test_fleet_that_cannot_fit_is_refused_naming_the_field():
    with pytest.raises(ConfigError, match=r"uav.min_separation_m = 90 m .* 10 UAVs .* <= 83.3"):
        check_fleet_fits(10, 90.0, 200.0, 200.0)
    check_fleet_fits(10, 83.0, 200.0, 200.0)
    assert max_spread_m(4, 300.0, 10.0) == pytest.approx(100.0)  # four in a row


def test_monitor_counts_entries_below_the_minimum_by_pair():
    monitor = SeparationMonitor(5.0)
    tracks = [[[0, 0], [10, 0], [30, 0]], [[0, 0], [4, 0], [30, 0]], [[0, 0], [4, 0], [33, 0]],
              [[0, 0], [9, 0], [34, 0]], [[0, 0], [9, 0], [12, 0]]]
    for t_s, positions in enumerate(tracks):
        monitor.observe(float(t_s), np.array(positions, dtype=float))
    summary = monitor.summary()
    assert summary["conflicts"] == 2  # (0, 1) at t = 1, (1, 2) at t = 4
    assert summary["closest_m"] == 3.0 and summary["closest_pair"] == [1, 2] and summary["closest_t_s"] == 4.0
    assert summary["time_below_min_s"] == 3.0
    assert closest_pair(np.array(tracks[1], dtype=float)).distance_m == 4.0
