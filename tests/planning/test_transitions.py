"""Transitions between plans: scripted geometry, predicted and flown closest approach against the minimum."""

from __future__ import annotations

import numpy as np
import pytest

from uav_swarm.planning.assignment import assign_targets
from uav_swarm.planning.trajectory import closest_approach_m
from uav_swarm.planning.transitions import plan_transition, predict_positions_m, squared_assignment
from uav_swarm.world.separation import closest_distances_m
from uav_swarm.world.uav import UAVConfig, fly_step, waypoint_velocity

CONFIG = UAVConfig(min_separation_m=5.0)
AREA_M = np.array([200.0, 200.0])
DT_S = 0.1


def fly(transition, positions_m, velocities_m_s, config=CONFIG, altitudes_m=None, seconds=60.0):
    """Fly the transition with the env's kinematics and waypoint controller; (closest m, worst miss m)."""
    p, v = np.array(positions_m, float), np.array(velocities_m_s, float)
    closest = np.inf
    for step in range(int(seconds / DT_S)):
        wanted = transition.targets_at(step * DT_S)
        p, v = fly_step(p, v, waypoint_velocity(p, wanted, DT_S, config), DT_S, config, AREA_M)
        closest = min(closest, float(closest_distances_m(p, altitudes_m)))
    return closest, float(np.abs(p - transition.targets_m).max())


def check(positions_m, targets_m, velocities_m_s=None, config=CONFIG, altitudes_m=None):
    """The transition's predicted and flown closest approach both keep the minimum; the UAVs arrive."""
    v = np.zeros_like(positions_m) if velocities_m_s is None else velocities_m_s
    transition = plan_transition(positions_m, v, targets_m, config, altitudes_m)
    assert transition.unresolved.shape == (0, 2)
    assert transition.closest_m >= config.min_separation_m
    closest, miss = fly(transition, positions_m, v, config, altitudes_m)
    assert closest >= config.min_separation_m and miss < 0.05
    return transition


def test_crossing_flights_collide_unless_one_waits():
    starts = np.array([[20.0, 50.0], [50.0, 20.0]])
    targets = np.array([[80.0, 50.0], [50.0, 80.0]])  # both reach (50, 50) after the same time
    at_once = plan_transition(starts, np.zeros((2, 2)), targets, UAVConfig(min_separation_m=0.0))
    assert fly(at_once, starts, np.zeros((2, 2)))[0] < 1.0  # without the transition they meet
    transition = check(starts, targets)
    assert transition.held.tolist().count(True) == 1


def test_a_head_on_swap_is_assigned_away():
    uavs = np.array([[20.0, 50.0], [80.0, 50.0]])
    candidates = np.array([[78.0, 53.0], [22.0, 47.0]])  # the same sides, listed swapped
    assignment = assign_targets(uavs, candidates)
    np.testing.assert_allclose(assignment.targets_m, candidates[::-1])  # nobody crosses
    check(uavs, assignment.targets_m)


def test_a_forced_head_on_swap_holds_one_uav_until_the_other_has_passed():
    starts = np.array([[20.0, 50.0], [80.0, 57.0]])
    targets = np.array([[80.0, 50.0], [20.0, 50.0]])  # UAV 1 takes UAV 0's place; they meet head-on
    at_once = plan_transition(starts, np.zeros((2, 2)), targets, UAVConfig(min_separation_m=0.0))
    assert fly(at_once, starts, np.zeros((2, 2)))[0] < CONFIG.min_separation_m
    transition = check(starts, targets)
    assert transition.held.tolist() == [False, True]  # the one whose target is the other's start waits


def test_a_head_on_swap_on_one_line_detours_or_passes_in_altitude_layers():
    starts = np.array([[20.0, 50.0], [80.0, 50.0]])
    targets = starts[::-1].copy()  # on one line: no delay lets them pass
    flat = check(starts, targets)
    detour = flat.hold_m[flat.held][0]
    assert flat.held.sum() == 1 and abs(detour[1] - 50.0) >= CONFIG.min_separation_m  # beside the line
    config = UAVConfig(min_separation_m=5.0, layer_step_m=6.0)
    layered = check(starts, targets, config=config, altitudes_m=config.altitudes_m(2))
    assert not layered.held.any()  # 6 m apart in altitude, they pass without waiting


def test_four_uavs_converging_on_one_point_keep_the_minimum():
    centre = np.array([100.0, 100.0])
    angles = np.arange(4) * np.pi / 2
    uavs = centre + 60.0 * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    corners = centre + 4.0 * np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])  # 8 m apart
    assignment = assign_targets(uavs, corners)
    check(uavs, assignment.targets_m)


@pytest.mark.parametrize("seed", range(4))
def test_ten_uavs_reassigned_by_a_permutation_keep_the_minimum(seed):
    rng = np.random.default_rng(seed)
    grid = np.stack(np.meshgrid(30.0 + 35.0 * np.arange(5), [70.0, 130.0]), axis=-1).reshape(-1, 2)
    uavs = grid + rng.uniform(-3.0, 3.0, grid.shape)
    plan = grid[rng.permutation(10)] + np.array([12.0, 20.0])  # the next plan: the grid moved, any order
    assignment = assign_targets(uavs, plan)
    check(uavs, assignment.targets_m)


def test_a_forced_permutation_keeps_the_minimum_where_it_resolves():
    rng = np.random.default_rng(7)
    resolved = 0
    for _ in range(6):
        uavs = rng.uniform(20.0, 180.0, (10, 2))
        targets = rng.uniform(20.0, 180.0, (10, 2))
        if closest_distances_m(uavs) < 8.0 or closest_distances_m(targets) < 8.0:
            continue
        transition = plan_transition(uavs, np.zeros((10, 2)), targets, CONFIG)  # no reassignment
        if len(transition.unresolved):
            continue
        resolved += 1
        assert transition.closest_m >= CONFIG.min_separation_m
        assert fly(transition, uavs, np.zeros((10, 2)))[0] >= CONFIG.min_separation_m
    assert resolved >= 3


def test_a_crowd_that_pulls_two_uavs_onto_one_group():
    group = np.array([150.0, 100.0])  # two targets 6 m apart on one dense group
    targets = group + np.array([[0.0, 3.0], [0.0, -3.0]])
    uavs = np.array([[40.0, 94.0], [40.0, 106.0]])  # both come from the same side, side by side
    assignment = assign_targets(uavs, targets)
    check(uavs, assignment.targets_m)


def test_a_uav_moving_at_the_replan_brakes_to_its_hold_point():
    starts = np.array([[20.0, 50.0], [50.0, 30.0]])
    velocities = np.array([[0.0, 0.0], [0.0, 8.0]])  # UAV 1 flies north toward the crossing
    targets = np.array([[80.0, 50.0], [50.0, 80.0]])
    transition = check(starts, targets, velocities)
    if transition.held[1]:  # its hold point is where it stops braking
        np.testing.assert_allclose(transition.hold_m[1], [50.0, 30.0 + 8.0**2 / (2 * CONFIG.max_accel_m_s2)])


def test_the_prediction_follows_the_flown_controller_within_the_margin():
    rng = np.random.default_rng(3)
    p = rng.uniform(20.0, 180.0, (6, 2))
    targets = rng.uniform(20.0, 180.0, (6, 2))
    heading = (targets - p) / np.linalg.norm(targets - p, axis=1)[:, None]
    v = heading * np.array([0.0, 3.0, 6.0, 9.0, 10.0, 0.0])[:, None]  # some already on their way
    times = np.arange(0, 300) * DT_S
    predicted = predict_positions_m(p, v, targets, times + DT_S, CONFIG)
    flown, q, w = [], p.copy(), v.copy()
    for _ in times:
        q, w = fly_step(q, w, waypoint_velocity(q, targets, DT_S, CONFIG), DT_S, CONFIG, AREA_M)
        flown.append(q)
    error = np.linalg.norm(np.stack(flown, axis=1) - predicted, axis=-1)
    assert error.max() < 1.0  # the default margin


def test_squared_assignment_prefers_two_short_flights_to_a_long_and_a_zero_one():
    starts = np.array([[0.0, 0.0], [10.0, 0.0]])
    goals = np.array([[10.0, 0.0], [20.0, 0.0]])  # distance ties (20 m either way); squares do not
    assert squared_assignment(starts, goals)[1].tolist() == [0, 1]


def test_closest_approach_is_exact_between_samples():
    a = np.array([[0.0, 0.0], [10.0, 0.0]])
    b = np.array([[10.0, 1.0], [0.0, 1.0]])  # they pass each other 1 m apart mid-interval
    assert float(closest_approach_m(a, b)) == pytest.approx(1.0)


def test_no_minimum_means_no_holds():
    starts = np.array([[20.0, 50.0], [50.0, 20.0]])
    transition = plan_transition(starts, np.zeros((2, 2)), np.array([[80.0, 50.0], [50.0, 80.0]]),
                                 UAVConfig(min_separation_m=0.0))
    assert not transition.held.any() and np.isinf(transition.closest_m)
