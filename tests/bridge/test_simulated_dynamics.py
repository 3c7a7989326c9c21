"""The simulated multicopter's core: it stops within its limits; its imperfections are the stated ones."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bridge.simulated.dynamics import (
    ARDUCOPTER_LIMITS,
    MAX_STEP_S,
    PX4_LIMITS,
    AutopilotLimits,
    PointMassCopter,
    Realism,
)

LIMITS = AutopilotLimits(max_speed_m_s=12.0, max_accel_m_s2=2.5, climb_m_s=3.0, descent_m_s=1.5,
                         vertical_accel_m_s2=2.0)


Track = list[tuple[np.ndarray, np.ndarray]]


def _fly(copter: PointMassCopter, seconds: float, dt_s: float = MAX_STEP_S) -> Track:
    """Advance, keeping (position, velocity) after every step."""
    states = []
    for _ in range(round(seconds / dt_s)):
        copter.advance(dt_s)
        states.append((copter.position_m, copter.velocity_m_s))
    return states


@pytest.mark.parametrize("limits", [LIMITS, ARDUCOPTER_LIMITS, PX4_LIMITS], ids=["fast", "arducopter", "px4"])
@pytest.mark.parametrize("dt_s", [0.01, 0.05, 0.3], ids=["10ms", "50ms", "300ms"])
def test_a_goto_is_flown_within_the_limits_and_stops_at_the_target(limits, dt_s):
    copter = PointMassCopter(np.array([0.0, 0.0, 10.0]), limits, Realism(), np.random.default_rng(1))
    target = np.array([60.0, -35.0, 4.0])
    assert copter.send(0.0, target)
    states = _fly(copter, 60.0, dt_s)
    velocities = np.array([v for _, v in states])
    horizontal = np.linalg.norm(velocities[:, :2], axis=1)
    assert horizontal.max() <= limits.max_speed_m_s + 1e-9
    assert horizontal.max() > 0.9 * limits.max_speed_m_s  # it does use its speed on a 70 m leg
    assert velocities[:, 2].min() >= -limits.descent_m_s - 1e-9
    steps = np.diff(np.vstack([np.zeros(3), velocities]), axis=0)
    inner = [min(dt_s, MAX_STEP_S)] * len(steps)
    assert np.all(np.linalg.norm(steps[:, :2], axis=1) <= np.array(inner) * limits.max_accel_m_s2 * math.ceil(
        dt_s / MAX_STEP_S) + 1e-9)
    along = np.array([p[:2] @ (target[:2] / np.linalg.norm(target[:2])) for p, _ in states])
    assert along.max() <= np.linalg.norm(target[:2]) + 1e-9  # never passes a target it heads for
    np.testing.assert_allclose(copter.position_m, target, atol=1e-6)
    np.testing.assert_allclose(copter.velocity_m_s, 0.0, atol=1e-6)


def test_a_turn_at_speed_swings_wide_by_about_what_braking_forces():
    copter = PointMassCopter(np.array([0.0, 0.0, 10.0]), LIMITS, Realism(), np.random.default_rng(2))
    copter.send(0.0, np.array([500.0, 0.0, 10.0]))
    _fly(copter, 20.0)
    east_m, speed_m_s = copter.position_m[0], copter.velocity_m_s[0]
    assert speed_m_s == pytest.approx(LIMITS.max_speed_m_s)
    copter.send(copter.now_s, np.array([east_m - 20.0, 30.0, 10.0]))  # back and to the left
    furthest = max(p[0] for p, _ in _fly(copter, 30.0))
    overshoot_m = furthest - east_m
    forced_m = speed_m_s**2 / (2 * LIMITS.max_accel_m_s2)
    assert 0.9 * forced_m < overshoot_m < 1.1 * forced_m  # braking and turning share the acceleration
    np.testing.assert_allclose(copter.position_m, [east_m - 20.0, 30.0, 10.0], atol=1e-6)


def test_a_hold_stops_at_the_braking_point():
    copter = PointMassCopter(np.array([0.0, 0.0, 10.0]), LIMITS, Realism(), np.random.default_rng(3))
    copter.send(0.0, np.array([0.0, 300.0, 10.0]))
    _fly(copter, 10.0)
    predicted = copter.stopping_point_m()
    assert predicted[1] - copter.position_m[1] == pytest.approx(12.0**2 / (2 * 2.5))
    copter.send(copter.now_s, None)
    np.testing.assert_allclose(copter.target_m, predicted)
    _fly(copter, 15.0)
    assert copter.position_m[1] <= predicted[1] + 1e-9
    np.testing.assert_allclose(copter.position_m, predicted, atol=1e-6)


def test_a_command_takes_effect_after_the_latency():
    copter = PointMassCopter(np.zeros(3), LIMITS, Realism(command_latency_s=0.7), np.random.default_rng(4))
    copter.advance(1.0)
    assert copter.send(1.0, np.array([10.0, 0.0, 0.0]))
    copter.advance(0.7)
    assert copter.position_m[0] == 0.0 and copter.target_m is not None
    copter.advance(MAX_STEP_S)
    assert copter.position_m[0] > 0.0


def test_lost_commands_change_nothing_and_come_at_the_stated_rate():
    copter = PointMassCopter(np.zeros(3), LIMITS, Realism(command_loss=0.3), np.random.default_rng(5))
    arrived = [copter.send(0.0, np.array([float(i), 0.0, 0.0])) for i in range(2000)]
    assert 0.27 < 1 - np.mean(arrived) < 0.33
    last_arrived = max(i for i, ok in enumerate(arrived) if ok)
    np.testing.assert_allclose(copter.target_m, [last_arrived, 0.0, 0.0])


def test_reports_are_as_old_as_stated_at_the_stated_rate():
    realism = Realism(position_age_s=0.4, position_rate_hz=5.0)
    copter = PointMassCopter(np.array([0.0, 0.0, 5.0]), LIMITS, realism, np.random.default_rng(6))
    copter.send(0.0, np.array([100.0, 0.0, 5.0]))
    truth: dict[float, float] = {0.0: 0.0}
    stamps = set()
    for _ in range(100):
        copter.advance(0.05)
        truth[round(copter.now_s, 6)] = float(copter.position_m[0])
        report = copter.report()
        stamps.add(round(report.stamp_s, 6))
        assert copter.now_s - 0.2 - 1e-9 <= report.stamp_s + 0.4 <= copter.now_s + 1e-9
        if report.stamp_s >= 0.0:
            assert report.position_m[0] == pytest.approx(truth[round(report.stamp_s, 6)])
    assert len(stamps) == 26  # 5 Hz over 5 s, the first at t = 0


def test_report_noise_has_the_stated_sigma():
    realism = Realism(position_noise_m=0.5, position_rate_hz=20.0)
    copter = PointMassCopter(np.array([3.0, 4.0, 5.0]), LIMITS, realism, np.random.default_rng(7))
    errors = []
    for _ in range(2000):
        copter.advance(0.05)
        errors.append(copter.report().position_m - [3.0, 4.0, 5.0])
    assert np.std(errors, axis=0) == pytest.approx([0.5] * 3, rel=0.1)


def test_wind_error_stays_within_its_stated_bound_and_moves_the_vehicle():
    realism = Realism(wind_m_s=8.0, gust_m_s=4.0, wind_response_s=0.5)
    copter = PointMassCopter(np.array([0.0, 0.0, 10.0]), LIMITS, realism, np.random.default_rng(8))
    copter.send(0.0, np.array([0.0, 0.0, 10.0]))
    offsets = np.array([np.linalg.norm(p[:2]) for p, _ in _fly(copter, 120.0)])
    assert offsets.max() <= realism.tracking_error_bound_m + 1e-9
    assert offsets[:20].max() > 0.5 * 8.0 * 0.5  # the steady wind pushes it right after take-off
    assert np.median(offsets[-600:]) > 0.1  # gusts keep pushing it


def test_a_steady_wind_is_learned():
    realism = Realism(wind_m_s=8.0)
    copter = PointMassCopter(np.array([0.0, 0.0, 10.0]), LIMITS, realism, np.random.default_rng(10))
    offsets = [np.linalg.norm(p[:2]) for p, _ in _fly(copter, 40.0)]
    assert max(offsets) > 1.0 and offsets[-1] < 0.01


def test_the_same_seed_flies_the_same_flight():
    realism = Realism(command_latency_s=0.3, command_loss=0.2, position_age_s=0.5, position_noise_m=0.4,
                      wind_m_s=5.0, gust_m_s=3.0)

    def flight(seed: int) -> list[float]:
        copter = PointMassCopter(np.array([0.0, 0.0, 10.0]), LIMITS, realism, np.random.default_rng(seed))
        trace = []
        for i in range(40):
            copter.send(copter.now_s, np.array([10.0 * (i % 7), 5.0 * (i % 3), 10.0]))
            copter.advance(0.45)
            trace += [*copter.position_m, *copter.report().position_m]
        return trace

    assert flight(11) == flight(11)
    assert flight(11) != flight(12)


@pytest.mark.parametrize("bad", [{"command_loss": 1.0}, {"position_rate_hz": 0.0}, {"wind_m_s": -1.0},
                                 {"command_latency_s": math.nan}], ids=lambda d: next(iter(d)))
def test_bad_realism_names_the_field(bad):
    with pytest.raises(ValueError, match=next(iter(bad))):
        Realism(**bad)


def test_time_does_not_run_backwards():
    copter = PointMassCopter(np.zeros(3), LIMITS, Realism(), np.random.default_rng(9))
    copter.advance(2.0)
    with pytest.raises(ValueError, match="before the vehicle's clock"):
        copter.send(1.0, None)


def _turned_at_speed(rng: np.random.Generator) -> tuple[PointMassCopter, np.ndarray]:
    """A vehicle flying in a random direction at some speed, then sent a random point (in effect at once)."""
    copter = PointMassCopter(np.array([0.0, 0.0, 10.0]), LIMITS, Realism(), rng)
    heading = rng.uniform(0.0, 2.0 * math.pi)
    copter.send(0.0, np.array([1e4 * math.cos(heading), 1e4 * math.sin(heading), 10.0]))
    copter.advance(float(rng.uniform(0.0, 6.0)))
    target = copter.position_m + np.array([*rng.uniform(-80.0, 80.0, size=2), 0.0])
    copter.send(copter.now_s, target)
    return copter, target[:2]


def test_angular_momentum_about_the_target_keeps_its_sign_and_never_grows():
    """The guard's tube lemma: ``L = (x - c) x v`` is multiplied by a factor in [0, 1] at every step."""
    rng = np.random.default_rng(7)
    for _ in range(80):
        copter, target = _turned_at_speed(rng)
        moments = []
        for position, velocity in _fly(copter, 30.0, 0.05):
            offset = position[:2] - target
            moments.append(float(offset[0] * velocity[1] - offset[1] * velocity[0]))
        moments = np.array(moments)
        assert np.all(moments * moments[0] >= -1e-9)  # one sign
        assert np.all(np.abs(moments[1:]) <= np.abs(moments[:-1]) + 1e-9)  # never grows


def test_the_swing_to_one_side_of_a_line_through_the_target_is_bounded():
    """The guard's one-sided swing: ``y + (V + U) / a * max(0, v_y)`` never grows while ``y >= 0``."""
    rng = np.random.default_rng(8)
    a, v_max = LIMITS.max_accel_m_s2, LIMITS.max_speed_m_s
    swings = []
    for _ in range(80):
        copter, target = _turned_at_speed(rng)
        start, v0 = copter.position_m[:2], copter.velocity_m_s[:2]
        along = (target - start) / np.hypot(*(target - start))
        across = np.array([-along[1], along[0]])
        across = across if v0 @ across >= 0.0 else -across  # the side it swings to
        gain = (v_max + max(v_max, float(np.hypot(*v0)))) / a
        bound, swing = gain * float(v0 @ across), 0.0
        for position, velocity in _fly(copter, 30.0, 0.05):
            y = float((position[:2] - target) @ across)
            if y < 0.0:
                break  # crossed the line (past the target: outside the lemma)
            measure = y + gain * max(0.0, float(velocity[:2] @ across))
            assert measure <= bound + 1e-9
            bound, swing = measure, max(swing, y)
        swings.append(swing)
    assert max(swings) > 5.0  # the turns swing wide: the bound is not vacuous here


def test_a_per_axis_autopilot_stays_within_its_per_axis_energy_radius():
    """(B1x) on the PX4-like model: turned at speed, sent a point, never beyond ``Bounds.radius_m`` of it."""
    from bridge.simulated.jerk_limited import JerkLimits, PX4LikeCopter
    from uav_swarm.world.guard import Bounds

    rng = np.random.default_rng(9)
    for _ in range(40):
        speed, accel, jerk = rng.uniform(5.0, 20.0), rng.uniform(2.0, 5.0), rng.uniform(2.0, 10.0)
        copter = PX4LikeCopter(np.array([0.0, 0.0, 30.0]), AutopilotLimits(speed, accel, 3.0, 1.5), Realism(),
                               rng, JerkLimits(jerk, jerk))
        heading = rng.uniform(0.0, 2.0 * math.pi)
        copter.send(0.0, np.array([1e4 * math.cos(heading), 1e4 * math.sin(heading), 30.0]))
        copter.advance(float(rng.uniform(0.0, 8.0)))
        target = copter.position_m[:2] + rng.uniform(-60.0, 60.0, size=2)
        copter.send(copter.now_s, np.array([*target, 30.0]))
        radius = float(Bounds(accel_m_s2=accel, jerk_m_s3=jerk, per_axis=True).radius_m(
            copter.position_m[:2] - target, copter.velocity_m_s[:2]))
        farthest = max(float(np.hypot(*(p[:2] - target))) for p, _ in _fly(copter, 40.0, 0.05))
        assert farthest <= radius + 1e-9
