from itertools import combinations

import numpy as np
import pytest

from uav_swarm.missions.monitoring.setcover import InfeasibleCoverError, min_set_cover


def _brute_force(cover, cost):
    """(fewest columns, smallest total cost among covers of that size) by enumeration."""
    rows, columns = cover.shape
    for k in range(1, columns + 1):
        subsets = [list(s) for s in combinations(range(columns), k)]
        costs = [cost[s].sum() for s in subsets if np.all(cover[:, s].any(axis=1))]
        if costs:
            return k, min(costs)
    raise AssertionError("infeasible")


@pytest.mark.parametrize("seed", range(12))
def test_matches_brute_force_count_then_cost(seed):
    rng = np.random.default_rng(seed)
    rows, columns = rng.integers(6, 16), rng.integers(6, 12)
    cover = rng.random((rows, columns)) < rng.uniform(0.15, 0.4)
    cover[np.arange(rows), rng.integers(columns, size=rows)] = True  # feasible
    cost = rng.integers(0, 4, size=columns).astype(float)  # many ties: exercises the reductions
    chosen = min_set_cover(cover, cost)
    assert np.all(cover[:, chosen].any(axis=1))
    assert (len(chosen), cost[chosen].sum()) == _brute_force(cover, cost)
    np.testing.assert_array_equal(min_set_cover(cover, cost), chosen)


def test_tie_break_never_trades_count_for_cost():
    # Column 0 alone covers everything but is expensive; columns 1 and 2 together are free.
    cover = np.array([[1, 1, 0], [1, 0, 1]], dtype=bool)
    assert min_set_cover(cover, np.array([1000.0, 0.0, 0.0])).tolist() == [0]


def test_identical_columns_keep_the_cheapest():
    cover = np.ones((3, 4), dtype=bool)
    assert min_set_cover(cover, np.array([3.0, 1.0, 2.0, 1.0])).tolist() == [1]


def test_no_rows_gives_no_columns_and_errors_are_precise():
    assert min_set_cover(np.zeros((0, 3), dtype=bool)).tolist() == []
    with pytest.raises(InfeasibleCoverError, match="first: row 1"):
        min_set_cover(np.array([[1, 0], [0, 0]], dtype=bool))
    with pytest.raises(ValueError, match="one per column"):
        min_set_cover(np.ones((2, 3), dtype=bool), np.zeros(2))
    with pytest.raises(ValueError, match="2-D"):
        min_set_cover(np.ones(3, dtype=bool))


def test_single_solve_reaches_the_same_count_and_cost_as_the_two_stages():
    rng = np.random.default_rng(17)
    for _ in range(30):
        cover = rng.random((25, 18)) < 0.2
        cover[np.arange(25), rng.integers(0, 18, size=25)] = True  # every row coverable
        cost = rng.integers(0, 9, size=18).astype(float)
        two = min_set_cover(cover, cost)
        one = min_set_cover(cover, cost, single_solve=True)
        assert np.all(np.any(cover[:, one], axis=1))
        assert len(one) == len(two) and cost[one].sum() == cost[two].sum()
    with pytest.raises(ValueError, match="non-negative"):
        min_set_cover(np.ones((2, 2), dtype=bool), np.array([-1.0, 0.0]), single_solve=True)
