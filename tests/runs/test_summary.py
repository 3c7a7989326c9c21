"""One results summary for both jobs; the static reference sampled in the run equals a replay of the crowd."""

from __future__ import annotations

import numpy as np

from uav_swarm.planning.planner import make_planner
from uav_swarm.runs.fly_config import FlyConfig
from uav_swarm.runs.outputs.records import QosTrace
from uav_swarm.runs.simulate import run_sequence, sequence_crowds
from uav_swarm.runs.simulate_config import SimulateConfig
from uav_swarm.runs.summary import qos_figures, summarise_flight, summarise_run

SMALL = {"warmup_min_s": 1.0, "warmup_max_s": 2.0,
         "scenario": {"n_groups_min": 2, "n_groups_max": 3, "group_size_min": 35, "group_size_max": 45}}


def test_the_crowd_sampled_during_the_run_is_the_replayed_crowd():
    config = SimulateConfig.from_dict({"duration_s": 25.0, "n_uavs": 3, "planner": "expert", "task": SMALL})
    planner = make_planner("expert", 3, config.task, config=config.planning, uav_config=config.uav)
    run = run_sequence(config, planner, "expert", sample_every_s=10.0)
    replay = list(sequence_crowds(config, 10.0))
    assert [t for t, _, _ in run.crowd_samples] == [t for t, _, _ in replay] == [0.0, 10.0, 20.0]
    for (_, positions, velocities), (_, replayed, replayed_velocities) in zip(run.crowd_samples, replay,
                                                                              strict=True):
        assert np.array_equal(positions, replayed) and np.array_equal(velocities, replayed_velocities)
    figures = summarise_run(run, config)
    assert {k: figures[k] for k in qos_figures(run.qos_s1, run.qos_s2, run.throughput_mbps)} == qos_figures(
        run.qos_s1, run.qos_s2, run.throughput_mbps)


def test_a_flight_reports_the_figures_simulate_reports_with_its_own_static_every_s():
    config = FlyConfig.from_dict({"bridge_config": "unused.toml", "static_every_s": 5.0, "task": SMALL})
    times = np.arange(1, 21) * 0.5
    trace = QosTrace("expert", times, np.linspace(0.2, 0.6, 20), np.linspace(0.1, 0.3, 20), np.full(20, 2.0))
    rng = np.random.default_rng(0)
    crowd = [(t, rng.uniform(0, 200, (80, 2)), np.zeros((80, 2))) for t in (0.0, 5.0)]
    track = [{"uav_id": 0, "time_s": t, "x_m": 10.0 * t, "y_m": 0.0} for t in times]
    summary = summarise_flight(trace, config, 1, [{0: (0.0, 0.0)}, {0: (50.0, 0.0)}], track, crowd)
    reference = summary["static_reference"]
    assert reference["every_s"] == 5.0 and reference["times_s"] == [0.0, 5.0]
    assert summary["min_qos_s1"] == 0.2 and summary["mean_qos_s2"] == np.mean(trace.qos_s2)
    service = summary["service"]
    assert service["target_jumps_per_replan"] == 1.0 and service["flown_qos"] == float(trace.qos_s1.mean())
    assert service["metres_per_uav_minute"] == (95.0 / (10.0 / 60.0))
    assert service["static_reference_qos"] == summary["static_reference"]["mean_qos"]
