"""The channel plan: greedy colouring of the APs' carrier-sense graph, the previous plan kept while valid."""

import numpy as np
import pytest

from uav_swarm.world.comms import RadioConfig, evaluate_coverage
from uav_swarm.world.wifi.channels import plan_channels, plan_is_valid
from uav_swarm.world.wifi.config import Ieee80211Config
from uav_swarm.world.wifi.coverage import channel_conflicts

THREE = RadioConfig(propagation="802.11", ieee80211=Ieee80211Config(channels=(36, 40, 44)))
TRIANGLE = np.array([[0.0, 0.0], [10.0, 0.0], [5.0, 8.0]])
HEIGHTS = np.full(3, 20.0)


def test_a_triangle_gets_three_channels():
    plan = plan_channels(TRIANGLE, THREE, HEIGHTS)
    assert sorted(plan.tolist()) == [36, 40, 44]


def test_a_valid_previous_plan_is_kept_an_invalid_one_changes_least():
    kept = plan_channels(TRIANGLE, THREE, HEIGHTS, previous=np.array([44, 36, 40]))
    assert kept.tolist() == [44, 36, 40]
    # Two UAVs on one channel: only one of them moves, to the free channel.
    repaired = plan_channels(TRIANGLE, THREE, HEIGHTS, previous=np.array([44, 44, 40]))
    assert sorted(repaired.tolist()) == [36, 40, 44]
    assert int(np.count_nonzero(repaired != np.array([44, 44, 40]))) == 1


def test_too_few_channels_put_the_farthest_aps_together():
    line = np.array([[0.0, 0.0], [10.0, 0.0], [20.0, 0.0], [300.0, 0.0]])
    two = RadioConfig(propagation="802.11", ieee80211=Ieee80211Config(channels=(36, 40)))
    plan = plan_channels(line, two, np.full(4, 20.0))
    assert plan[0] != plan[1] and plan[1] != plan[2]
    power_dbm, _ = channel_conflicts(line[None], two, np.full(4, 20.0))
    shared = [(i, j) for i in range(4) for j in range(i + 1, 4) if plan[i] == plan[j]]
    # The pairs left on one channel hear each other more weakly than the nearest pair (kept apart).
    assert all(power_dbm[0, i, j] < power_dbm[0, 0, 1] for i, j in shared)


@pytest.mark.parametrize("seed", range(5))
def test_with_enough_channels_the_plan_is_valid_and_raises_the_throughput(seed):
    rng = np.random.default_rng(seed)
    uavs = rng.uniform(0, 200, (2, 6, 2))
    heights = np.full((2, 6), 20.0)
    radio = RadioConfig(propagation="802.11")
    plans = plan_channels(uavs, radio, heights)
    _, conflict = channel_conflicts(uavs, radio, heights)
    users = rng.uniform(0, 200, (300, 2))
    for c in range(2):
        assert plan_is_valid(plans[c], conflict[c], radio.ieee80211.usable_channels)
        single = evaluate_coverage(users, uavs[c], radio, heights[c])
        planned = evaluate_coverage(users, uavs[c], radio, heights[c], plans[c])
        assert planned.mean_throughput_mbps > single.mean_throughput_mbps
    again = plan_channels(uavs, radio, heights, previous=plans)
    np.testing.assert_array_equal(again, plans)
