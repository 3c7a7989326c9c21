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


def test_an_operator_target_stays_reserved_in_the_planner_s_targets():
    targets = _targets()
    assert targets.offer(0, "map", 20.0, 20.0, 10.0) is None
    planned = np.array([[1.0, 1.0], [21.0, 20.0], [60.0, 60.0]])  # the plan puts UAV 1 1 m from it
    flown = targets.apply_array(planned)
    assert flown[0].tolist() == [20.0, 20.0] and flown[2].tolist() == [60.0, 60.0]
    assert np.hypot(*(flown[1] - flown[0])) >= 6.0 - 1e-9
    assert np.hypot(*(flown[1] - planned[1])) < 6.0  # moved the least it must
    by_id = targets.apply({0: (1.0, 1.0), 2: (20.5, 19.0)})  # the flight loop's ids
    assert by_id[0] == (20.0, 20.0) and np.hypot(by_id[2][0] - 20.0, by_id[2][1] - 20.0) >= 6.0 - 1e-9


def test_every_plan_of_a_run_keeps_other_uavs_off_a_held_operator_target():
    from uav_swarm.planning.planner import make_planner
    from uav_swarm.runs.simulate import run_sequence
    from uav_swarm.runs.simulate_config import SimulateConfig

    small = {"warmup_min_s": 1.0, "warmup_max_s": 2.0,
             "scenario": {"n_groups_min": 2, "n_groups_max": 3, "group_size_min": 35, "group_size_max": 45}}
    config = SimulateConfig.from_dict({"duration_s": 4.0, "n_uavs": 3, "planner": "expert", "task": small})

    def fly(steering=None):
        planner = make_planner("expert", 3, config.task, config=config.planning, uav_config=config.uav)
        return run_sequence(config, planner, "expert", steering=steering, frame_every=1)

    wanted = fly().frames[0].targets_m[1]  # where the planner sends UAV 1 first
    area = config.task.scenario
    operator = OperatorTargets(width_m=area.width_m, height_m=area.height_m, uav=config.uav, n_uavs=3)
    assert operator.offer(0, "map", float(wanted[0]), float(wanted[1]), 10.0) is None  # UAV 0 is sent there
    frames = fly(operator).frames
    assert len(frames) >= 30
    for frame in frames:  # every step's flown targets, across every replan
        assert np.array_equal(frame.targets_m[0], wanted)
        others = np.hypot(*(frame.targets_m[1:] - wanted).T)
        assert np.all(others >= config.uav.min_separation_m - 1e-9), (frame.time_s, others)
