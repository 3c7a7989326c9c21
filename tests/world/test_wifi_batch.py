"""The 802.11 radio of many worlds at once against one world at a time, step after step.

The batch keeps its incumbents in one :class:`StackedIncumbents`; each world alone keeps its own in an
:class:`Association`. Users move, worlds are reset and their crowds replaced (more or fewer users), the
radio's choices stay those of each world alone: associations, MCS and throughput equal.
"""

import numpy as np
import pytest

from uav_swarm.world.comms import Association, RadioConfig
from uav_swarm.world.comms_batch import StackedIncumbents, coverage_batch
from uav_swarm.world.wifi.config import Ieee80211Config

RADIOS = {
    "shipped": RadioConfig(propagation="802.11"),
    "rate admission, few channels": RadioConfig(
        propagation="802.11", min_user_rate_mbps=5.0,
        ieee80211=Ieee80211Config(rate_admission=True, channels=(36, 40))),
    "station limit, deaf": RadioConfig(
        propagation="802.11", station_limit=6, ieee80211=Ieee80211Config(cca_threshold_20mhz_dbm=-62.0)),
}


def crowd(rng, counts, side_m):
    return rng.uniform(0, side_m, (int(np.sum(counts)), 2)), np.repeat(np.arange(len(counts)), counts)


@pytest.mark.parametrize("name", sorted(RADIOS))
def test_stacked_incumbents_follow_each_world_alone(name):
    radio, rng = RADIOS[name], np.random.default_rng(len(name))
    n_worlds, n_uavs, side_m = 6, 5, 160.0
    counts = rng.integers(0, 70, n_worlds)
    users, copy = crowd(rng, counts, side_m)
    heights = rng.uniform(10, 40, (n_worlds, n_uavs))
    stacked, alone = StackedIncumbents(n_worlds), [Association(radio) for _ in range(n_worlds)]
    kept = 0
    for step in range(8):
        if step == 4:  # worlds 1 and 4 restart: world 1 with other users, world 4 with as many as before
            stacked.reset([1, 4])
            alone[1].reset()
            alone[4].reset()
            counts[1] += 5
            users = _replace(users, copy, counts, rng, side_m, [1, 4])
            copy = np.repeat(np.arange(n_worlds), counts)
        uavs = rng.uniform(0, side_m, (n_worlds, n_uavs, 2))
        plan = rng.choice(radio.ieee80211.usable_channels[:3], (n_worlds, n_uavs))
        batch = coverage_batch(users, copy, uavs, radio, stacked, heights, plan)
        for c in range(n_worlds):
            rows = copy == c
            one = alone[c].update(users[rows], uavs[c], altitudes_m=heights[c], channels=plan[c])
            together = batch.copy(c)
            np.testing.assert_array_equal(together.association, one.association)
            np.testing.assert_array_equal(together.mcs, one.mcs)
            np.testing.assert_array_equal(together.throughput_mbps, one.throughput_mbps)
            kept += int(np.count_nonzero(one.association >= 0))
        users = users + rng.normal(0, 4.0, users.shape)  # the users walk on
    assert kept > 200


def _replace(users, copy, counts, rng, side_m, worlds):
    """The stacked users with those of ``worlds`` drawn again (``counts``: the new number per world)."""
    parts = []
    for c in range(len(counts)):
        parts.append(rng.uniform(0, side_m, (counts[c], 2)) if c in worlds else users[copy == c])
    return np.concatenate(parts)
