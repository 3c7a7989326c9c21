"""The Wi-Fi model: the paper's numbers and the invariants of coverage."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from typed_config import ConfigError
from uav_swarm.world.comms import RadioConfig, evaluate_coverage, rescaled_signal


def test_signal_is_exactly_threshold_at_range():
    signal = rescaled_signal(np.array([[30.0, 0.0]]), np.zeros((1, 2)), RadioConfig())
    assert signal[0, 0] == pytest.approx(0.1, rel=1e-12)
    assert RadioConfig().effective_sigma_sq_m2 == pytest.approx(900 / (2 * math.log(10)))


def test_signal_is_one_under_the_uav_and_decreasing():
    users = np.column_stack([np.linspace(0, 100, 50), np.zeros(50)])
    signal = rescaled_signal(users, np.zeros((1, 2)), RadioConfig())[:, 0]
    assert signal[0] == 1.0
    assert np.all(np.diff(signal) < 0) and np.all(signal > 0)


def test_paper_sigma_is_reproducible():
    config = RadioConfig(sigma_sq_m2=450.0)
    signal = rescaled_signal(np.array([[30.0, 0.0]]), np.zeros((1, 2)), config)
    assert signal[0, 0] == pytest.approx(math.exp(-1.0))
    # With the paper's sigma the 0.1 threshold is reached further away: sqrt(2 * 450 * ln 10) ~ 45.5 m.
    covered = evaluate_coverage(np.array([[45.0, 0.0], [46.0, 0.0]]), np.zeros((1, 2)), config).covered
    assert covered.tolist() == [True, False]


def test_altitude_uses_3d_distance():
    config = RadioConfig(altitude_m=18.0)
    signal = rescaled_signal(np.array([[24.0, 0.0]]), np.zeros((1, 2)), config)  # 3D distance 30 m
    assert signal[0, 0] == pytest.approx(0.1)
    cov = evaluate_coverage(np.array([[23.0, 0.0], [25.0, 0.0]]), np.zeros((1, 2)), config)
    assert cov.covered.tolist() == [True, False]


@pytest.mark.parametrize("angle", [0.0, 1.0, 2.5, 4.0])
def test_user_at_29_m_covered_and_31_m_uncovered(angle):
    uavs = np.array([[100.0, 100.0], [300.0, 100.0], [100.0, 300.0]])
    direction = np.array([math.cos(angle), math.sin(angle)])
    users = uavs[0] + np.array([29.0, 31.0])[:, None] * direction
    cov = evaluate_coverage(users, uavs, RadioConfig())
    assert cov.covered.tolist() == [True, False]
    assert cov.association.tolist() == [0, -1]
    assert cov.throughput_mbps.tolist() == [200.0, 0.0]


def test_association_to_strongest_and_ties_to_lowest_index():
    uavs = np.array([[0.0, 0.0], [20.0, 0.0]])
    users = np.array([[10.0, 0.0], [12.0, 0.0], [8.0, 0.0], [-5.0, 0.0]])
    cov = evaluate_coverage(users, uavs, RadioConfig())
    assert cov.association.tolist() == [0, 1, 0, 0]
    assert cov.users_per_uav.tolist() == [3, 1]
    assert cov.throughput_mbps.tolist() == pytest.approx([200 / 3, 200.0, 200 / 3, 200 / 3])


def test_capacity_shared_and_strategy_2_threshold():
    users = np.zeros((41, 2))  # 41 users under one UAV: 200 / 41 < 5 Mbps
    cov = evaluate_coverage(users, np.zeros((1, 2)), RadioConfig())
    assert cov.qos_s1 == 1.0 and cov.qos_s2 == 0.0
    cov = evaluate_coverage(users[:40], np.zeros((1, 2)), RadioConfig())  # exactly 5 Mbps each
    assert cov.qos_s2 == 1.0
    assert cov.mean_throughput_mbps == pytest.approx(5.0)


def test_mean_throughput_counts_uncovered_users_as_zero():
    users = np.array([[0.0, 0.0], [500.0, 500.0]])
    cov = evaluate_coverage(users, np.zeros((1, 2)), RadioConfig())
    assert cov.mean_throughput_mbps == pytest.approx(100.0)
    assert cov.qos_s1 == 0.5


def test_no_users_or_no_uavs():
    empty = evaluate_coverage(np.zeros((0, 2)), np.zeros((3, 2)), RadioConfig())
    assert empty.qos_s1 == 0.0 and empty.users_per_uav.tolist() == [0, 0, 0]
    nobody = evaluate_coverage(np.ones((4, 2)), np.zeros((0, 2)), RadioConfig())
    assert nobody.association.tolist() == [-1] * 4 and not nobody.covered.any()
    assert nobody.qos_s1 == 0.0 and nobody.mean_throughput_mbps == 0.0


def test_bad_shapes_are_errors():
    with pytest.raises(ValueError, match="users_m"):
        evaluate_coverage(np.zeros((3, 3)), np.zeros((1, 2)), RadioConfig())
    with pytest.raises(ValueError, match="uavs_m"):
        rescaled_signal(np.zeros((3, 2)), np.zeros(2), RadioConfig())


@pytest.mark.parametrize(
    ("field", "value"),
    [("range_m", 0.0), ("signal_at_range", 1.0), ("signal_at_range", 0.0), ("sigma_sq_m2", -1.0),
     ("capacity_mbps", 0.0), ("min_user_rate_mbps", -1.0), ("altitude_m", -1.0)],
)
def test_config_errors_name_the_field(field, value):
    with pytest.raises(ConfigError, match=f"RadioConfig.{field}"):
        RadioConfig.from_dict({field: value})


def test_config_rejects_unknown_key_and_rate_above_capacity():
    with pytest.raises(ConfigError, match="range_km"):
        RadioConfig.from_dict({"range_km": 3})
    with pytest.raises(ConfigError, match="min_user_rate_mbps"):
        RadioConfig(capacity_mbps=10.0, min_user_rate_mbps=20.0)


scenes = st.tuples(
    st.integers(min_value=0, max_value=2**32 - 1),
    st.integers(min_value=0, max_value=300),
    st.integers(min_value=0, max_value=10),
)


@settings(max_examples=60, deadline=None)
@given(scenes)
def test_coverage_invariants(scene):
    seed, n_users, n_uavs = scene
    rng = np.random.default_rng(seed)
    users = rng.uniform(0, 200, size=(n_users, 2))
    uavs = rng.uniform(0, 200, size=(n_uavs, 2))
    config = RadioConfig()
    cov = evaluate_coverage(users, uavs, config)
    assert cov.covered.sum() <= n_users
    assert cov.users_per_uav.sum() == cov.covered.sum()
    assert 0.0 <= cov.qos_s2 <= cov.qos_s1 <= 1.0
    assert np.all(cov.throughput_mbps <= config.capacity_mbps)
    assert np.all((cov.throughput_mbps > 0) == cov.covered)
    assert np.array_equal(cov.association >= 0, cov.covered)
    # Adding a UAV never lowers strategy-1 coverage.
    more = evaluate_coverage(users, np.vstack([uavs, rng.uniform(0, 200, size=(1, 2))]), config)
    assert more.qos_s1 >= cov.qos_s1
    assert np.all(more.covered[cov.covered])
