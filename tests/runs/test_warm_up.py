"""simulate replans once untimed before its first step: compilation stays out of the reported latencies."""

from __future__ import annotations

import numpy as np

from uav_swarm.planning.planner import make_planner
from uav_swarm.runs.simulate import run_sequence
from uav_swarm.runs.simulate_config import SimulateConfig


def test_one_untimed_replan_then_a_fresh_planner_flies_the_same_sequence():
    config = SimulateConfig(duration_s=3.0, n_uavs=4, seed=2, gif=False, publish_telemetry=False,
                            compare_expert=False, static_reference=False)
    planner = make_planner("expert", config.n_uavs, config.task, config=config.planning,
                           uav_config=config.uav)
    calls: list[str] = []
    plan, reset = planner.plan, planner.reset
    planner.plan = lambda *args, **kwargs: (calls.append("plan"), plan(*args, **kwargs))[1]
    planner.reset = lambda: (calls.append("reset"), reset())[1]
    run = run_sequence(config, planner, "expert")
    n_timed = run.latency_ms.size
    assert n_timed == 3  # one replan a second
    assert calls == ["plan", "reset"] + ["plan"] * n_timed  # the warm-up, forgotten, then the timed ones
    again = run_sequence(config, make_planner("expert", config.n_uavs, config.task, config=config.planning,
                                              uav_config=config.uav), "expert")
    np.testing.assert_array_equal(run.qos_s1, again.qos_s1)
