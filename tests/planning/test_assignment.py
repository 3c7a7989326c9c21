import itertools

import numpy as np
import pytest

from uav_swarm.planning.assignment import assign_targets


def _total_squared_distance(uavs, targets):
    return float((np.linalg.norm(uavs - targets, axis=1) ** 2).sum())


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 6])
def test_assignment_minimises_the_squared_travel_against_brute_force(n):
    rng = np.random.default_rng(n)
    for _ in range(20):
        uavs = rng.uniform(0, 200, size=(n, 2))
        cands = rng.uniform(0, 200, size=(n, 2))
        result = assign_targets(uavs, cands)
        best = min(_total_squared_distance(uavs, cands[list(p)]) for p in itertools.permutations(range(n)))
        assert _total_squared_distance(uavs, result.targets_m) == pytest.approx(best, rel=1e-12)
        assert sorted(result.candidate_index.tolist()) == list(range(n))


def test_more_candidates_than_uavs_keeps_the_best_ranked():
    uavs = np.array([[0.0, 0.0], [10.0, 0.0]])
    cands = np.array([[50.0, 50.0], [60.0, 50.0], [1.0, 0.0]])  # best first: the third is dropped
    result = assign_targets(uavs, cands)
    assert set(result.candidate_index.tolist()) == {0, 1}


def test_targets_are_never_duplicated():
    rng = np.random.default_rng(0)
    for trial in range(50):
        n = int(rng.integers(1, 11))
        uavs = rng.uniform(0, 100, size=(n, 2))
        uavs[: n // 2] = uavs[0]  # co-located UAVs
        cands = rng.uniform(0, 100, size=(int(rng.integers(0, n + 1)), 2))
        targets = assign_targets(uavs, cands, min_gap_m=1.0).targets_m
        gaps = np.linalg.norm(targets[:, None] - targets[None], axis=-1) + np.eye(n) * 1e9
        assert gaps.min() >= 1.0 - 1e-9, trial


def test_hysteresis_keeps_targets_under_small_motion():
    rng = np.random.default_rng(1)
    uavs = rng.uniform(0, 200, size=(6, 2))
    peaks = rng.uniform(0, 200, size=(6, 2))
    first = assign_targets(uavs, peaks)
    moved = peaks + rng.normal(0, 1.0, size=peaks.shape)
    shuffled = moved[rng.permutation(6)]
    second = assign_targets(uavs, shuffled, previous_targets_m=first.targets_m, hysteresis_m=5.0)
    np.testing.assert_array_equal(second.targets_m, first.targets_m)
    assert second.kept.all()
    without = assign_targets(uavs, shuffled)
    assert not np.array_equal(without.targets_m, first.targets_m)


def test_hysteresis_releases_a_target_that_moved_far():
    uavs = np.array([[0.0, 0.0], [100.0, 0.0]])
    first = assign_targets(uavs, np.array([[0.0, 10.0], [100.0, 10.0]]))
    second = assign_targets(uavs, np.array([[0.0, 11.0], [100.0, 60.0]]),
                            previous_targets_m=first.targets_m, hysteresis_m=5.0)
    assert second.kept.tolist() == [True, False]
    np.testing.assert_array_equal(second.targets_m[1], [100.0, 60.0])


def test_fallback_with_no_peak_holds_position():
    uavs = np.array([[5.0, 5.0], [50.0, 50.0], [90.0, 10.0]])
    result = assign_targets(uavs, np.empty((0, 2)))
    np.testing.assert_array_equal(result.targets_m, uavs)
    assert (result.candidate_index == -1).all()


def test_fallback_with_one_peak_sends_the_nearest_uav():
    uavs = np.array([[5.0, 5.0], [50.0, 50.0], [90.0, 10.0]])
    result = assign_targets(uavs, np.array([[55.0, 45.0]]))
    assert result.candidate_index.tolist() == [-1, 0, -1]
    np.testing.assert_array_equal(result.targets_m[[0, 2]], uavs[[0, 2]])


def test_bad_shapes_are_rejected():
    with pytest.raises(ValueError, match="uav_positions_m"):
        assign_targets(np.zeros(3), np.zeros((1, 2)))
    with pytest.raises(ValueError, match="hysteresis_m"):
        assign_targets(np.zeros((1, 2)), np.zeros((1, 2)), hysteresis_m=-1)
