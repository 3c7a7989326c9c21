"""The jerk-limited autopilots: within their acceleration and jerk limits always, at their target at last."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bridge.simulated.dynamics import ARDUCOPTER_LIMITS, PX4_LIMITS, AutopilotLimits, PointMassCopter, Realism
from bridge.simulated.jerk_limited import (
    ARDUCOPTER_JERK,
    PX4_JERK,
    ArduCopterLikeCopter,
    JerkLimits,
    PX4LikeCopter,
)

FAST = AutopilotLimits(max_speed_m_s=15.0, max_accel_m_s2=2.5, climb_m_s=3.0, descent_m_s=1.5,
                       vertical_accel_m_s2=2.0)
MODELS = {
    "arducopter": (ArduCopterLikeCopter, ARDUCOPTER_LIMITS, ARDUCOPTER_JERK),
    "arducopter-fast": (ArduCopterLikeCopter, FAST, JerkLimits(jerk_m_s3=3.0, vertical_jerk_m_s3=5.0)),
    "px4": (PX4LikeCopter, PX4_LIMITS, PX4_JERK),
    "px4-fast": (PX4LikeCopter, FAST, JerkLimits(jerk_m_s3=6.0, vertical_jerk_m_s3=4.0)),
}


def _track(copter: PointMassCopter, seconds: float, dt_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions, velocities and accelerations after every control tick."""
    positions, velocities, accelerations = [], [], []
    for _ in range(round(seconds / dt_s)):
        copter.advance(dt_s)
        positions.append(copter.position_m)
        velocities.append(copter.velocity_m_s)
        accelerations.append(copter.acceleration_m_s2)  # type: ignore[attr-defined]
    return np.array(positions), np.array(velocities), np.array(accelerations)


def _assert_within_limits(copter: ArduCopterLikeCopter | PX4LikeCopter, velocities: np.ndarray,
                          accelerations: np.ndarray) -> None:
    limits, jerk, dt = copter.limits, copter.jerk, copter.jerk.control_dt_s
    change = np.diff(np.vstack([np.zeros(3), accelerations]), axis=0) / dt
    a, j, tol = limits.max_accel_m_s2, jerk.jerk_m_s3, 1e-9
    if isinstance(copter, PX4LikeCopter):  # each horizontal axis on its own
        assert np.abs(accelerations[:, :2]).max() <= a + tol
        assert np.abs(change[:, :2]).max() <= j + tol
    else:
        assert np.hypot(*accelerations[:, :2].T).max() <= a + tol
        assert np.hypot(*change[:, :2].T).max() <= j + tol
    assert np.abs(accelerations[:, 2]).max() <= limits.vertical_accel_m_s2 + tol
    assert np.abs(change[:, 2]).max() <= jerk.vertical_jerk_m_s3 + tol
    assert np.hypot(*velocities[:, :2].T).max() <= limits.max_speed_m_s * 1.001
    assert velocities[:, 2].max() <= limits.climb_m_s * 1.001
    assert velocities[:, 2].min() >= -limits.descent_m_s * 1.001


@pytest.mark.parametrize("model", list(MODELS))
def test_a_goto_is_flown_within_the_limits_reached_and_held(model):
    cls, limits, jerk = MODELS[model]
    copter = cls(np.array([0.0, 0.0, 10.0]), limits, Realism(), np.random.default_rng(1), jerk)
    target = np.array([160.0, -120.0, 14.0])
    assert copter.send(0.0, target)
    positions, velocities, accelerations = _track(copter, 60.0, jerk.control_dt_s)
    _assert_within_limits(copter, velocities, accelerations)
    assert np.hypot(*velocities[:, :2].T).max() > 0.9 * limits.max_speed_m_s  # uses its speed on 200 m
    along = positions[:, :2] @ (target[:2] / np.linalg.norm(target[:2]))
    assert along.max() <= np.linalg.norm(target[:2]) + 1.0  # a little overshoot at most
    held_p, held_v, _ = _track(copter, 10.0, jerk.control_dt_s)  # and it stays there
    assert np.abs(held_p - target).max() < 1e-3
    assert np.abs(held_v).max() < 1e-3


@pytest.mark.parametrize("model", list(MODELS))
def test_random_commands_at_speed_never_break_the_limits(model):
    """Targets that jump about every 0.3-3 s, reversals at full speed included."""
    cls, limits, jerk = MODELS[model]
    rng = np.random.default_rng(7)
    copter = cls(np.array([0.0, 0.0, 10.0]), limits, Realism(), rng, jerk)
    tracks = []
    for _ in range(40):
        target = np.array([*rng.uniform(-150.0, 150.0, 2), rng.uniform(2.0, 30.0)])
        copter.send(copter.now_s, target)
        tracks.append(_track(copter, float(rng.uniform(0.3, 3.0)), jerk.control_dt_s))
    velocities = np.vstack([v for _, v, _ in tracks])
    accelerations = np.vstack([acc for _, _, acc in tracks])
    _assert_within_limits(copter, velocities, accelerations)
    assert np.hypot(*accelerations[:, :2].T).max() > 0.99 * limits.max_accel_m_s2  # the limits are used


def test_px4_limits_each_axis_so_a_diagonal_gets_more():
    """``MPC_ACC_HOR`` on each axis: a diagonal turn accelerates at up to sqrt(2) times it."""
    copter = PX4LikeCopter(np.array([0.0, 0.0, 10.0]), FAST, Realism(), np.random.default_rng(2), PX4_JERK)
    copter.send(0.0, np.array([200.0, 200.0, 10.0]))
    _, _, accelerations = _track(copter, 5.0, PX4_JERK.control_dt_s)
    peak = np.hypot(*accelerations[:, :2].T).max()
    assert peak == pytest.approx(math.sqrt(2.0) * FAST.max_accel_m_s2, rel=1e-6)


@pytest.mark.parametrize("model", ["arducopter", "px4"])
def test_a_reversal_while_accelerating_runs_on_beyond_the_braking_distance(model):
    """Told to turn back at 12 m/s while still accelerating away, it runs on by more than
    ``v^2 / 2a + v a / j``: the jerk delays the braking from ``+a`` to ``-a`` by ``2 a / j``."""
    cls, _, jerk = MODELS[model]
    limits = AutopilotLimits(max_speed_m_s=15.0, max_accel_m_s2=2.5, climb_m_s=3.0, descent_m_s=1.5)
    copter = cls(np.array([0.0, 0.0, 10.0]), limits, Realism(), np.random.default_rng(3), jerk)
    copter.send(0.0, np.array([500.0, 0.0, 10.0]))
    while copter.velocity_m_s[0] < 12.0:
        copter.advance(jerk.control_dt_s)
    start_m, speed = copter.position_m[0], copter.velocity_m_s[0]
    assert copter.acceleration_m_s2[0] == pytest.approx(2.5)  # still accelerating away
    copter.send(copter.now_s, np.array([start_m - 50.0, 0.0, 10.0]))
    positions, _, _ = _track(copter, 20.0, jerk.control_dt_s)
    run_on_m = positions[:, 0].max() - start_m
    a, j = limits.max_accel_m_s2, jerk.jerk_m_s3
    b1_m = speed**2 / (2 * a) + speed * a / j
    assert run_on_m > b1_m + 3.0, (run_on_m, b1_m)
    assert run_on_m < speed**2 / (2 * a) + 2 * speed * a / j + a**3 / j**2 + 1.0  # and not without bound


def test_realism_applies_as_to_the_point_mass():
    """Latency and late reports come from the same machinery as ``PointMassCopter``'s."""
    realism = Realism(command_latency_s=0.5, position_age_s=0.3, position_rate_hz=10.0)
    copter = ArduCopterLikeCopter(np.array([0.0, 0.0, 10.0]), ARDUCOPTER_LIMITS, realism,
                                  np.random.default_rng(4))
    copter.send(0.0, np.array([20.0, 0.0, 10.0]))
    copter.advance(0.5)
    assert copter.position_m[0] == 0.0  # not yet in effect
    copter.advance(2.5)
    report = copter.report()
    assert report.stamp_s == pytest.approx(3.0 - 0.3)
    assert 0.0 < report.position_m[0] < copter.position_m[0]
    copter.settle(np.array([5.0, 5.0, 10.0]))
    assert np.all(copter.acceleration_m_s2 == 0.0) and np.all(copter.velocity_m_s == 0.0)


@pytest.mark.parametrize("model", ["arducopter", "px4"])
def test_a_hold_stops_near_its_own_stopping_point(model):
    cls, limits, jerk = MODELS[model]
    copter = cls(np.array([0.0, 0.0, 10.0]), limits, Realism(), np.random.default_rng(5), jerk)
    copter.send(0.0, np.array([0.0, 300.0, 10.0]))
    _track(copter, 12.0, jerk.control_dt_s)
    predicted = copter.stopping_point_m()
    copter.send(copter.now_s, None)
    np.testing.assert_allclose(copter.target_m, predicted)
    positions, _, _ = _track(copter, 20.0, jerk.control_dt_s)
    assert np.abs(positions[-1] - predicted).max() < 1e-3
    assert positions[:, 1].max() <= predicted[1] + 0.5


def test_jerk_limits_are_checked():
    with pytest.raises(ValueError, match="jerk_m_s3"):
        JerkLimits(jerk_m_s3=0.0, vertical_jerk_m_s3=5.0)
