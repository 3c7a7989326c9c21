"""The vectorised motion horizon: exactly the radio model's QoS, instant by instant and option by option."""

from __future__ import annotations

import numpy as np
import pytest

from uav_swarm.planning import horizon as horizon_module
from uav_swarm.planning.horizon import coverage_qos_batch, horizon_qos, travelled_m
from uav_swarm.planning.planner import PlannerConfig, make_planner
from uav_swarm.runs.simulate import run_sequence
from uav_swarm.runs.simulate_config import SimulateConfig
from uav_swarm.world.comms import RadioConfig, evaluate_coverage
from uav_swarm.world.uav import UAVConfig

RADIOS = [RadioConfig(), RadioConfig(altitude_m=12.0, capacity_mbps=40.0), RadioConfig(sigma_sq_m2=450.0)]


def crowd(rng, n_worlds, n_users, n_uavs, spread=200.0):
    users = rng.uniform(0.0, spread, size=(n_worlds, n_users, 2))
    uavs = rng.uniform(0.0, spread, size=(n_worlds, n_uavs, 2))
    uavs[:, -1] = users[:, 0] + [29.999, 0.0]  # users near the edge of coverage
    if n_users > 2:
        users[:, 1] = users[:, 2]  # a tie between two users
    return users, uavs


@pytest.mark.parametrize("radio", RADIOS, ids=["default", "altitude", "paper-sigma"])
def test_batched_qos_equals_the_radio_model_exactly(radio):
    rng = np.random.default_rng(5)
    for n_users, n_uavs in [(1, 1), (40, 3), (567, 10), (300, 1)]:
        users, uavs = crowd(rng, 16, n_users, n_uavs)
        s1, s2 = coverage_qos_batch(users, uavs, radio)
        for b in range(16):
            cov = evaluate_coverage(users[b], uavs[b], radio)
            assert (s1[b], s2[b]) == (cov.qos_s1, cov.qos_s2)  # bit for bit, not approximately


def test_batched_qos_of_empty_worlds_and_bad_shapes():
    s1, s2 = coverage_qos_batch(np.zeros((3, 0, 2)), np.zeros((3, 2, 2)), RadioConfig())
    assert s1.tolist() == s2.tolist() == [0.0, 0.0, 0.0]
    with pytest.raises(ValueError, match=r"\(B, N, 2\)"):
        coverage_qos_batch(np.zeros((2, 5, 2)), np.zeros((3, 2, 2)), RadioConfig())


def test_a_station_limit_falls_back_to_the_snapshot_function(monkeypatch):
    radio = RadioConfig()
    object.__setattr__(radio, "station_limit", 4)  # the admission-control field of the radio model
    calls = []

    def counting(users, uavs, config):
        calls.append(len(users))
        return evaluate_coverage(users, uavs, config)

    monkeypatch.setattr(horizon_module, "evaluate_coverage", counting)
    users, uavs = crowd(np.random.default_rng(1), 6, 50, 4)
    s1, s2 = coverage_qos_batch(users, uavs, radio)
    assert calls == [50] * 6
    assert s1.tolist() == [evaluate_coverage(u, k, radio).qos_s1 for u, k in zip(users, uavs, strict=True)]


def per_instant(peds, vels, uavs, targets, target_vel, radio, strategy, horizon_s, samples, uav):
    """The horizon as judged before the batch: one radio-model call per instant."""
    total = 0.0
    for t in np.linspace(horizon_s / samples, horizon_s, samples):
        offset = targets + target_vel * t - uavs
        distance = np.linalg.norm(offset, axis=1)
        reach = travelled_m(float(t), uav.max_speed_m_s, uav.max_accel_m_s2)
        scale = np.where(distance > reach, reach / np.maximum(distance, 1e-9), 1.0)
        coverage = evaluate_coverage(peds + vels * t, uavs + offset * scale[:, None], radio)
        total += coverage.qos_s1 if strategy == 1 else coverage.qos_s2
    return total / samples


@pytest.mark.parametrize("strategy", [1, 2])
def test_horizon_qos_equals_one_radio_call_per_instant_and_option(strategy):
    rng = np.random.default_rng(strategy)
    uav = UAVConfig()
    radio = RadioConfig(capacity_mbps=100.0)
    for _ in range(20):
        peds = rng.uniform(0.0, 200.0, size=(int(rng.integers(1, 500)), 2))
        vels = rng.normal(0.0, 1.0, size=peds.shape)
        uavs = rng.uniform(0.0, 200.0, size=(10, 2))
        options = [rng.uniform(0.0, 200.0, size=(10, 2)) for _ in range(2)]
        velocities = [rng.normal(0.0, 1.0, size=(10, 2)) for _ in range(2)]
        samples = int(rng.integers(1, 6))
        got = horizon_qos(peds, vels, uavs, options, velocities, radio, strategy, 6.0, samples,
                          uav.max_speed_m_s, uav.max_accel_m_s2)
        assert got == [per_instant(peds, vels, uavs, o, v, radio, strategy, 6.0, samples, uav)
                       for o, v in zip(options, velocities, strict=True)]
    assert horizon_qos(np.zeros((0, 2)), np.zeros((0, 2)), uavs, options, velocities, radio, 1, 6.0, 4,
                       1.0, 1.0) == [0.0, 0.0]


def test_the_motion_planner_takes_the_decisions_of_the_per_instant_horizon(monkeypatch):
    """A flown sequence with the batched horizon and with the per-instant one: the same plans."""
    from uav_swarm.planning import motion as motion_module

    config = SimulateConfig.from_dict({  # the paper's radio: the per-instant reference is the paper's
        "duration_s": 12.0, "n_uavs": 6, "replan_every": 10, "seed": 4, "publish_telemetry": False,
        "gif": False, "static_reference": False, "task": {"radio": {"propagation": "paper"}}})

    def flown():
        planner = make_planner("expert", config.n_uavs, config.task, config=PlannerConfig(),
                               uav_config=config.uav)
        return run_sequence(config, planner, "expert")

    batched = flown()

    def reference(peds, vels, uavs, options, velocities, radio, strategy, horizon_s, samples, speed, accel,
                  serving=None):
        uav = UAVConfig(max_speed_m_s=speed, max_accel_m_s2=accel)
        return [per_instant(peds, vels, uavs, o, v, radio, strategy, horizon_s, samples, uav)
                for o, v in zip(options, velocities, strict=True)]

    monkeypatch.setattr(motion_module, "horizon_qos", reference)
    looped = flown()
    np.testing.assert_array_equal(batched.final_targets_m, looped.final_targets_m)
    np.testing.assert_array_equal(batched.qos_s1, looped.qos_s1)  # every step flew the same plans
    np.testing.assert_array_equal(batched.target_changes, looped.target_changes)
