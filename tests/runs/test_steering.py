"""Operator targets: each rule refuses what it should and names itself; accepted ones replace the plan."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bridge.geofence import GeofenceConfig
from uav_swarm.runs.steering import OperatorTargets
from uav_swarm.world.uav import UAVConfig


def _targets(**uav) -> OperatorTargets:
    fence = GeofenceConfig(x_min_m=-10.0, x_max_m=150.0, y_min_m=-10.0, y_max_m=90.0)
    return OperatorTargets(width_m=200.0, height_m=80.0, uav=UAVConfig(min_separation_m=6.0, **uav), n_uavs=3,
                           geofence=fence)


@pytest.mark.parametrize(("uav_id", "frame", "xyz", "words"), [
    (3, "map", (10.0, 10.0, 10.0), "UAV 3 is not in this run"),
    (0, "odom", (10.0, 10.0, 10.0), "frame_id = 'odom'"),
    (0, "map", (math.nan, 10.0, 10.0), "not finite"),
    (0, "map", (10.0, math.inf, 10.0), "not finite"),
    (0, "map", (160.0, 10.0, 10.0), "outside the geofence"),  # inside the area, outside the fence
    (0, "map", (-5.0, 10.0, 10.0), "outside the area"),  # inside the fence, outside the area
    (1, "map", (44.0, 40.0, 10.0), "4.00 m from UAV 2's target: allowed at least 6 m"),  # the plan's
])
def test_each_rule_refuses_and_nothing_is_held(uav_id, frame, xyz, words):
    targets = _targets()
    targets.planned({0: (10.0, 70.0), 2: (40.0, 40.0)})
    version = targets.version
    reason = targets.offer(uav_id, frame, *xyz)
    assert reason is not None and words in reason
    assert targets.held() == {} and targets.version == version


def test_accepted_targets_replace_the_plan_until_released():
    targets = _targets()
    assert targets.offer(0, "map", 20.0, 20.0, 55.0) is None  # the altitude is the UAV's own
    assert "from UAV 0's target" in targets.offer(1, "map", 23.0, 20.0, 10.0)  # another operator target
    planned = np.array([[1.0, 1.0], [100.0, 50.0], [60.0, 60.0]])
    assert targets.apply_array(planned).tolist() == [[20.0, 20.0], [100.0, 50.0], [60.0, 60.0]]
    assert planned[0].tolist() == [1.0, 1.0]  # the plan itself is left alone
    assert targets.release(0) and not targets.release(0)
    assert targets.apply_array(planned) is planned


def test_altitude_layers_let_targets_closer_horizontally():
    layered = _targets(layer_step_m=4.0)  # UAVs 0 and 1 are 4 m apart in height: 4.47 m suffices
    assert layered.offer(0, "map", 20.0, 20.0, 10.0) is None
    assert layered.offer(1, "map", 24.6, 20.0, 10.0) is None
    assert "allowed at least 4.47214 m" in layered.offer(1, "map", 24.0, 20.0, 10.0)
