"""The compiled channel plan of all worlds equals, channel for channel, the per-world plan it replaced."""

import numpy as np
import pytest

from uav_swarm.world.comms import RadioConfig
from uav_swarm.world.wifi.channels import plan_channels
from uav_swarm.world.wifi.config import Ieee80211Config
from uav_swarm.world.wifi.coverage import channel_conflicts
from uav_swarm.world.wifi.phy import dbm_to_mw


def reference_valid(plan, conflict, usable):
    if not set(np.asarray(plan).tolist()) <= set(usable):
        return False
    return not bool(np.any((plan[:, None] == plan[None, :]) & conflict))


def reference_colour(conflict, power_mw, usable, previous):
    """The per-world greedy colouring in numpy and Python sets, as it was before it was compiled."""
    n_uavs = conflict.shape[0]
    degree = conflict.sum(axis=1)
    order = np.lexsort((np.arange(n_uavs), -degree))
    plan = np.full(n_uavs, -1, np.int64)
    for k in order:
        taken = conflict[k] & (plan >= 0)
        busy = {int(c) for c in plan[taken]}
        if previous is not None and int(previous[k]) in usable and int(previous[k]) not in busy:
            plan[k] = previous[k]
            continue
        free = [c for c in usable if c not in busy]
        if free:
            plan[k] = free[0]
            continue
        loads = [float(power_mw[k][taken & (plan == c)].sum()) for c in usable]
        plan[k] = usable[int(np.argmin(loads))]
    return plan


def reference_plan(uavs, radio, heights, previous):
    power_dbm, conflict = channel_conflicts(uavs, radio, heights)
    power_mw = dbm_to_mw(power_dbm)
    usable = radio.ieee80211.usable_channels
    plans = np.empty(uavs.shape[:2], np.int64)
    for c in range(len(uavs)):
        old = None if previous is None else previous[c]
        if old is not None and reference_valid(old, conflict[c], usable):
            plans[c] = old
        else:
            plans[c] = reference_colour(conflict[c], power_mw[c], usable, old)
    return plans


@pytest.mark.parametrize("channels", [(36,), (36, 40), (36, 40, 44), None], ids=["1", "2", "3", "default"])
@pytest.mark.parametrize("n_uavs", [1, 4, 10])
def test_every_world_gets_the_reference_plan(channels, n_uavs):
    ieee = Ieee80211Config() if channels is None else Ieee80211Config(channels=channels)
    radio = RadioConfig(propagation="802.11", ieee80211=ieee)
    rng = np.random.default_rng(n_uavs * 10 + len(ieee.usable_channels))
    uavs = rng.uniform(0, 400, (64, n_uavs, 2))
    heights = rng.uniform(8, 30, (64, n_uavs))
    plans = plan_channels(uavs, radio, heights)
    np.testing.assert_array_equal(plans, reference_plan(uavs, radio, heights, None))
    # The UAVs move; the plans in force (some kept, some repaired, some with unusable channels) go on.
    previous = plans.copy()
    previous[::7, 0] = 165 if 165 not in ieee.usable_channels else 1
    moved = uavs + rng.normal(0, 30, uavs.shape)
    np.testing.assert_array_equal(plan_channels(moved, radio, heights, previous),
                                  reference_plan(moved, radio, heights, previous))


def test_one_channel_for_ten_aps_sums_nine_loads_as_numpy_does():
    radio = RadioConfig(propagation="802.11", ieee80211=Ieee80211Config(channels=(36, 40)))
    rng = np.random.default_rng(3)
    uavs = rng.uniform(0, 30, (200, 10, 2))  # everyone hears everyone: the loads decide
    heights = np.full((200, 10), 20.0)
    np.testing.assert_array_equal(plan_channels(uavs, radio, heights),
                                  reference_plan(uavs, radio, heights, None))
