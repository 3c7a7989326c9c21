"""Many worlds in one pass: the batched planner gives every world the targets of its own single plan."""

from __future__ import annotations

import numpy as np
import pytest

from uav_swarm.missions.wifi.task import WifiConfig, WifiTask
from uav_swarm.planning.batch import plan_batch
from uav_swarm.planning.planner import LearnedPlanner, PlannerConfig, make_planner


def worlds(n, seed=0):
    task = WifiTask(WifiConfig(warmup_min_s=5.0, warmup_max_s=8.0))
    rng = np.random.default_rng(seed)
    scenes = [task.sample(rng) for _ in range(n)]
    return ([s.users_m.copy() for s in scenes], [s.velocities_m_s.copy() for s in scenes],
            rng.uniform(0.0, 200.0, size=(n, 10, 2)))


@pytest.mark.parametrize("engine", ["auto", "torch-eager"])
def test_batched_plans_equal_single_plans_over_a_sequence(engine):
    crowds, velocities, uavs = worlds(6)
    planner = LearnedPlanner(10, config=PlannerConfig(engine=engine))
    batch = [planner.fork() for _ in crowds]
    single = [planner.fork() for _ in crowds]
    options = set()
    for _ in range(4):  # the crowds walk, the UAVs move halfway to their targets
        together = plan_batch(batch, crowds, uavs, velocities)
        alone = [p.plan(c, u, v) for p, c, u, v in zip(single, crowds, uavs, velocities, strict=True)]
        for a, b in zip(together, alone, strict=True):
            np.testing.assert_allclose(a.peaks_m, b.peaks_m, atol=1e-6)
            np.testing.assert_allclose(a.targets_m, b.targets_m, atol=1e-6)
            assert a.option == b.option and a.engine == b.engine == planner.engine
            np.testing.assert_array_equal(a.candidate_index, b.candidate_index)
            np.testing.assert_array_equal(a.kept, b.kept)
            assert a.latency_ms > 0.0
            options.add(a.option)
        crowds = [c + v for c, v in zip(crowds, velocities, strict=True)]
        uavs = (uavs + np.stack([r.targets_m for r in alone])) / 2.0
    assert "hybrid" in options  # the worlds' own sequence states were used (UAVs kept their users)


def test_forks_keep_their_own_sequence_state():
    crowds, velocities, uavs = worlds(2, seed=3)
    planner = LearnedPlanner(10)
    a, b = planner.fork(), planner.fork()
    a.plan(crowds[0], uavs[0], velocities[0])
    assert a._previous is not None and b._previous is None and planner._previous is None
    assert a.engine_choice is planner.engine_choice and a.motion is not planner.motion


def test_expert_worlds_are_planned_one_by_one_and_bad_batches_are_refused(tiny_checkpoint):
    crowds = [np.full((40, 2), 50.0), np.full((40, 2), 150.0)]
    experts = [make_planner("expert", 1) for _ in crowds]
    results = plan_batch(experts, crowds, np.zeros((2, 1, 2)))
    assert [r.targets_m.tolist() for r in results] == [[[50.0, 50.0]], [[150.0, 150.0]]]
    assert plan_batch([], [], []) == []
    with pytest.raises(ValueError, match="one crowd, one UAV array"):
        plan_batch(experts, crowds[:1], np.zeros((2, 1, 2)))
    learned = LearnedPlanner(1, checkpoint=tiny_checkpoint)
    other = LearnedPlanner(1, checkpoint=tiny_checkpoint, config=PlannerConfig(refine=True))
    with pytest.raises(ValueError, match="forks of one planner"):
        plan_batch([learned, other], crowds, np.zeros((2, 1, 2)))
    with pytest.raises(ValueError, match="uav_positions_m must have shape"):
        plan_batch([learned, learned.fork()], crowds, np.zeros((2, 2, 2)))


def test_the_batch_runs_the_network_once(monkeypatch):
    crowds, velocities, uavs = worlds(5, seed=4)
    planner = LearnedPlanner(10)
    engine = planner.engine_choice.engine
    calls = []
    real = engine.maps

    def counting(x):
        calls.append(x.shape)
        return real(x)

    monkeypatch.setattr(engine, "maps", counting)
    plan_batch([planner.fork() for _ in crowds], crowds, uavs, velocities)
    assert calls == [(5, *planner.checkpoint.input_shape)]
