"""Transitions between plans: scripted geometry, predicted and flown closest approach against the minimum."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.distance import pdist, squareform

from uav_swarm.planning.assignment import assign_targets
from uav_swarm.planning.trajectory import fly_track, segment_gap
from uav_swarm.planning.transitions import plan_transition, squared_assignment
from uav_swarm.world.separation import closest_distances_m, draw_apart_m, required_distances_m
from uav_swarm.world.uav import UAVConfig, fly_step, waypoint_velocity

CONFIG = UAVConfig(min_separation_m=5.0)
AREA_M = np.array([200.0, 200.0])
DT_S = 0.1


def fly(transition, positions_m, velocities_m_s, config=CONFIG, altitudes_m=None, seconds=60.0, area_m=AREA_M,
        step_s=DT_S):
    """Fly the transition with the env's kinematics and waypoint controller, no guard.

    Returns (closest m, worst miss of the targets m, (K, K) closest of every pair, flown positions (T, K, 2)).
    """
    p, v = np.array(positions_m, float), np.array(velocities_m_s, float)
    pairs = pdist_m(p, altitudes_m)
    flown = [p]
    for step in range(int(seconds / step_s)):
        wanted = transition.targets_at(step * step_s)
        p, v = fly_step(p, v, waypoint_velocity(p, wanted, step_s, config), step_s, config, area_m)
        pairs = np.minimum(pairs, pdist_m(p, altitudes_m))
        flown.append(p)
    return float(pairs.min()), float(np.abs(p - transition.targets_m).max()), pairs, np.array(flown)


def pdist_m(p, altitudes_m=None):
    """The judge: scipy's distances of every pair (3-D with layers), inf on the diagonal."""
    z = np.zeros((len(p), 1)) if altitudes_m is None else np.asarray(altitudes_m)[:, None]
    lifted = np.hstack([p, z])
    d = squareform(pdist(lifted))
    np.fill_diagonal(d, np.inf)
    return d


def check(positions_m, targets_m, velocities_m_s=None, config=CONFIG, altitudes_m=None):
    """The transition's predicted and flown closest approach both keep the minimum; the UAVs arrive."""
    v = np.zeros_like(positions_m) if velocities_m_s is None else velocities_m_s
    transition = plan_transition(positions_m, v, targets_m, config, altitudes_m)
    assert transition.unresolved.shape == (0, 2)
    assert transition.closest_m >= config.min_separation_m
    closest, miss, _, _ = fly(transition, positions_m, v, config, altitudes_m)
    assert closest >= config.min_separation_m and miss < 1e-6
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


def test_the_prediction_is_the_flight_of_the_env_kinematics():
    rng = np.random.default_rng(3)
    p = rng.uniform(20.0, 180.0, (6, 2))
    targets = rng.uniform(20.0, 180.0, (6, 2))
    angle = rng.uniform(0.0, 2 * np.pi, 6)  # flying in any direction: across, away from the target
    v = np.array([0.0, 3.0, 6.0, 9.0, 10.0, 10.0])[:, None] * np.stack([np.cos(angle), np.sin(angle)], 1)
    transition = plan_transition(p, v, targets, CONFIG, area_m=AREA_M)
    _, _, _, flown = fly(transition, p, v, seconds=transition.tracks_m.shape[1] * DT_S)
    predicted = transition.tracks_m.transpose(1, 0, 2)
    np.testing.assert_allclose(flown[:len(predicted)], predicted, atol=1e-9)


def test_one_track_is_the_flight_of_one_uav_braking_while_it_turns():
    config = UAVConfig(max_accel_m_s2=2.5)
    track, settle = fly_track(np.array([10.0, 10.0]), np.array([12.0, 0.0]), np.array([0.0, 40.0]), config,
                              0.2, 400)
    p, v = np.array([[10.0, 10.0]]), np.array([[12.0, 0.0]])
    for n in range(settle):
        p, v = fly_step(p, v, waypoint_velocity(p, np.array([[0.0, 40.0]]), 0.2, config), 0.2, config,
                        np.array([np.inf, np.inf]))
        np.testing.assert_allclose(track[n + 1], p[0], atol=1e-9)
    assert track[:, 0].max() > 10.0 + 12.0**2 / (2 * 5.0)  # shared acceleration: it overshoots further


def test_momentum_across_and_away_is_part_of_the_plan():
    starts = np.array([[50.0, 50.0], [62.0, 44.0]])
    velocities = np.array([[10.0, 0.0], [0.0, 0.0]])  # UAV 0 flies east, at UAV 1, its target lies west
    targets = np.array([[20.0, 50.0], [62.0, 80.0]])
    transition = plan_transition(starts, velocities, targets, CONFIG, area_m=AREA_M)
    closest, _, _, _ = fly(transition, starts, velocities)
    assert len(transition.unresolved) or closest >= CONFIG.min_separation_m
    assert closest >= CONFIG.min_separation_m  # here a schedule exists: UAV 1 waits for UAV 0 to turn


def test_coincident_or_too_close_targets_are_reported():
    starts = np.array([[20.0, 20.0], [60.0, 20.0], [20.0, 80.0]])
    targets = np.array([[50.0, 50.0], [50.0, 50.0], [90.0, 90.0]])  # two UAVs sent to one point
    transition = plan_transition(starts, np.zeros((3, 2)), targets, CONFIG)
    assert transition.unresolved.tolist() == [[0, 1]]
    targets[1] = [53.0, 50.0]  # 3 m apart: closer than the minimum
    assert plan_transition(starts, np.zeros((3, 2)), targets, CONFIG).unresolved.tolist() == [[0, 1]]


def test_targets_exactly_at_the_minimum_keep_it_when_flown_or_are_reported():
    side_by_side = np.array([[50.0, 60.0], [55.0, 60.0]])  # exactly 5 m apart
    parallel = check(np.array([[50.0, 20.0], [55.0, 20.0]]), side_by_side)  # both land heading north
    assert parallel.closest_m >= CONFIG.min_separation_m - 1e-9
    starts = np.array([[20.0, 20.0], [80.0, 20.0]])  # they converge: each lands carried toward the other
    converging = plan_transition(starts, np.zeros((2, 2)), side_by_side, CONFIG)
    assert converging.unresolved.tolist() == [[0, 1]]
    assert fly(converging, starts, np.zeros((2, 2)))[0] < CONFIG.min_separation_m  # the report was due


@pytest.mark.parametrize("seed", range(3))
def test_every_pair_reported_resolved_keeps_the_minimum_when_flown_without_the_guard(seed):
    """A seeded quick fuzz (benchmarks/flight/transitions_fuzz.py runs 1,000 cases): replans in flight,
    crowded."""
    rng = np.random.default_rng(100 + seed)
    resolved_pairs = 0
    for _ in range(12):
        k = int(rng.integers(3, 11))
        area = rng.uniform(40.0, 80.0, 2)
        config = UAVConfig(min_separation_m=5.0, max_speed_m_s=float(rng.uniform(5.0, 20.0)),
                           max_accel_m_s2=float(rng.uniform(2.0, 8.0)))
        step_s = float(rng.choice([0.05, 0.1, 0.2]))
        gaps = required_distances_m(5.0, None, k)
        p = draw_apart_m(rng, k, area, gaps)
        angle = rng.uniform(0.0, 2 * np.pi, k)
        v = rng.uniform(0.0, config.max_speed_m_s, (k, 1)) * np.stack([np.cos(angle), np.sin(angle)], 1)
        targets = draw_apart_m(rng, k, area, gaps)
        transition = plan_transition(p, v, targets, config, step_s=step_s, area_m=area)
        seconds = (transition.tracks_m.shape[1] + 10) * step_s
        _, miss, pairs, _ = fly(transition, p, v, config, seconds=seconds, area_m=area, step_s=step_s)
        reported = np.zeros((k, k), bool)
        reported[tuple(transition.unresolved.T)] = True
        resolved = np.triu(~(reported | reported.T), 1)
        assert np.all(pairs[resolved] >= 5.0 - 1e-9)
        assert miss < 1e-6
        resolved_pairs += int(resolved.sum())
    assert resolved_pairs >= 100  # most pairs are resolved: the check is not vacuous


def test_squared_assignment_prefers_two_short_flights_to_a_long_and_a_zero_one():
    starts = np.array([[0.0, 0.0], [10.0, 0.0]])
    goals = np.array([[10.0, 0.0], [20.0, 0.0]])  # distance ties (20 m either way); squares do not
    assert squared_assignment(starts, goals)[1].tolist() == [0, 1]


def test_the_gap_between_two_steps_is_exact():
    # relative position (-5, 1) -> (5, 1): they pass each other 1 m apart in the middle of the step
    assert segment_gap(-5.0, 1.0, 5.0, 1.0) == pytest.approx(1.0)


def test_no_minimum_means_no_holds():
    starts = np.array([[20.0, 50.0], [50.0, 20.0]])
    transition = plan_transition(starts, np.zeros((2, 2)), np.array([[80.0, 50.0], [50.0, 80.0]]),
                                 UAVConfig(min_separation_m=0.0))
    assert not transition.held.any() and np.isinf(transition.closest_m)
