"""The flight guard's adapter: the vehicles' own limits, late positions, unanswered points, broken bounds."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bridge.flight.limits import HorizontalLimits
from typed_config import ConfigError
from uav_swarm.runs.flight.guard import FlightGuard, GuardConfig
from uav_swarm.runs.fly_config import FlyConfig


def _rows(positions, goals, stamp_s=0.0, velocities=None):
    velocities = velocities or [(0.0, 0.0)] * len(positions)
    return [(i, p, v, stamp_s, g, True)
            for i, (p, v, g) in enumerate(zip(positions, velocities, goals, strict=True))]


def _joined(guard, rows, now_s):
    """The first decision: each vehicle is sent the point it hovers at; acknowledged at once."""
    for (row, *_), decision in zip(rows, guard.decide(rows, now_s), strict=True):
        assert decision.state == "on"
        guard.acknowledged(row, decision.seq, now_s)


def test_each_vehicle_is_planned_with_the_smaller_of_its_own_and_the_stated_limits():
    guard = FlightGuard(GuardConfig(accel_m_s2=3.0, jerk_m_s3=0.0), min_separation_m=5.0, n_vehicles=2)
    soft = guard.set_limits(0, HorizontalLimits(10.0, 2.5, 5.0, "WPNAV_SPEED, WPNAV_ACCEL, PSC_JERK_XY"))
    hard = guard.set_limits(1, HorizontalLimits(12.0, 4.0, 4.0, "MPC_XY_VEL_MAX, MPC_ACC_HOR, MPC_JERK_AUTO"))
    assert (soft.accel_m_s2, soft.jerk_m_s3) == (2.5, 5.0)
    assert (hard.accel_m_s2, hard.jerk_m_s3) == (3.0, 4.0)
    assert not soft.per_axis and hard.per_axis  # PX4 limits each axis: its energy is bounded per axis
    assert guard.set_limits(1, None).jerk_m_s3 == math.inf  # stated: no jerk limit given


def test_a_late_position_holds_the_vehicle_and_is_reported():
    guard = FlightGuard(GuardConfig(position_age_s=1.0), min_separation_m=5.0, n_vehicles=2)
    positions, goals = [(0.0, 0.0), (50.0, 0.0)], [(0.0, 30.0), (50.0, 30.0)]
    _joined(guard, _rows(positions, goals, stamp_s=9.4), now_s=9.9)
    fresh = guard.decide(_rows(positions, goals, stamp_s=9.5), now_s=10.0)
    assert [d.state for d in fresh] == ["free", "free"]
    late = guard.decide([(0, (0.0, 1.0), (0.0, 1.0), 10.9, (0.0, 30.0), True),
                         (1, (50.0, 1.0), (0.0, 1.0), 10.0, (50.0, 30.0), True)], now_s=11.2)
    assert late[1].state == "stale" and late[1].point_m is None
    assert [kind for _, _, kind in guard.fleet.events] == ["position_stale"]


def test_an_unacknowledged_point_stays_possible_and_is_reported():
    guard = FlightGuard(GuardConfig(command_delay_s=1.0), min_separation_m=5.0, n_vehicles=2)
    rows = _rows([(0.0, 0.0), (60.0, 0.0)], [(12.0, 0.0), (60.0, 0.0)])
    _joined(guard, rows, now_s=0.05)
    first = guard.decide(rows, now_s=0.1)
    assert first[0].point_m == (12.0, 0.0)
    guard.unacknowledged(0, first[0].seq, now_s=1.1)
    assert guard.fleet.centre_m(0).tolist() == [12.0, 0.0]  # it may have arrived: the disc still covers it
    assert [kind for _, _, kind in guard.fleet.events] == ["command_unacknowledged"]


def test_a_vehicle_outside_its_disc_is_stopped_and_reported():
    guard = FlightGuard(GuardConfig(), min_separation_m=5.0, n_vehicles=2)
    rows = _rows([(0.0, 0.0), (60.0, 0.0)], [(10.0, 0.0), (60.0, 0.0)])
    _joined(guard, rows, now_s=0.05)
    decision = guard.decide(rows, now_s=0.1)[0]
    guard.acknowledged(0, decision.seq, now_s=0.2)
    # it was sent 10 m and is found 25 m away at speed: braking weaker than stated
    late = guard.decide([(0, (25.0, 0.0), (8.0, 0.0), 1.3, (10.0, 0.0), True),
                         (1, (60.0, 0.0), (0.0, 0.0), 1.3, (60.0, 0.0), True)], now_s=1.35)
    assert late[0].state == "outside" and late[0].point_m == (25.0, 0.0)
    assert [kind for _, _, kind in guard.fleet.events] == ["outside_bounds"]


def test_the_certified_discs_keep_the_minimum_in_a_head_on_swap():
    guard = FlightGuard(GuardConfig(margin_m=1.0), min_separation_m=5.0, n_vehicles=2)
    rows = _rows([(0.0, 0.0), (40.0, 0.0)], [(40.0, 0.0), (0.0, 0.0)])
    _joined(guard, rows, now_s=0.05)
    assert [d.state for d in guard.decide(rows, now_s=0.1)] == ["free", "free"]
    assert guard.gap_m(0, 1) >= 6.0


def test_guard_settings_out_of_range_and_removed_keys_are_refused():
    with pytest.raises(ConfigError, match="accel_m_s2"):
        FlyConfig.from_dict({"bridge_config": "b.toml", "guard": {"accel_m_s2": 0.0}})
    with pytest.raises(ConfigError, match="latency_s"):
        FlyConfig.from_dict({"bridge_config": "b.toml", "guard": {"latency_s": 0.5}})


def test_a_climbing_vehicle_is_an_obstacle_the_others_keep_off():
    guard = FlightGuard(GuardConfig(margin_m=0.0), min_separation_m=5.0, n_vehicles=2)
    rows = [(0, (0.0, 0.0), (0.0, 0.0), 0.0, (30.0, 0.0), True),
            (1, (30.0, 0.0), (0.0, 0.0), 0.0, None, False)]
    guard.acknowledged(0, guard.decide(rows, now_s=0.05)[0].seq, now_s=0.05)
    decision = guard.decide(rows, now_s=0.1)[0]
    assert decision.point_m is not None and np.hypot(*np.subtract(decision.point_m, (30.0, 0.0))) >= 5.0


def _disc_distance(guard, a, point):
    """Distance from ``point`` to vehicle ``a``'s certified disc."""
    return float(np.hypot(*(guard.fleet.centre_m(a) - np.asarray(point)))) - guard.fleet.radius_m(a)


def test_a_silent_vehicle_keeps_its_disc_and_no_one_is_sent_through_it():
    """Vehicle 1 goes unheard (link lost or no fix) between two others: 0 may not be sent across its disc."""
    guard = FlightGuard(GuardConfig(margin_m=0.0), min_separation_m=5.0, n_vehicles=2)
    guard.homes_m = {0: (0.0, 0.0), 1: (40.0, 0.0)}
    rows = _rows([(0.0, 0.0), (40.0, 0.0)], [(80.0, 0.0), (40.0, 0.0)])
    _joined(guard, rows, now_s=0.05)
    for step in range(1, 200):  # 20 s of decisions with vehicle 1 silent from the start
        now_s = 0.05 + 0.1 * step
        x0 = float(guard.fleet.centre_m(0)[0])
        for decision in guard.decide([(0, (x0, 0.0), (0.0, 0.0), now_s, (80.0, 0.0), True)], now_s):
            if decision.point_m is not None:
                guard.acknowledged(0, decision.seq, now_s)
        assert guard.fleet.is_silent(1) and guard.fleet.joined(1)
        assert guard.gap_m(0, 1) >= 5.0 - 1e-9
    assert float(guard.fleet.centre_m(0)[0]) < 40.0  # it never passed through the silent one


def test_a_vehicle_never_measured_blocks_every_step_near_it():
    guard = FlightGuard(GuardConfig(margin_m=0.0, position_age_s=1.0), min_separation_m=5.0, n_vehicles=2)
    rows = _rows([(0.0, 0.0)], [(60.0, 0.0)])
    _joined(guard, rows, now_s=0.05)
    stale = (1, (30.0, 0.0), (0.0, 0.0), -5.0, (30.0, 0.0), True)  # its first row already too old
    decisions = guard.decide([(0, (0.0, 0.0), (0.0, 0.0), 0.1, (60.0, 0.0), True), stale], now_s=0.1)
    assert math.isinf(guard.fleet.radius_m(1))
    assert decisions[0].point_m is None or decisions[0].point_m[0] < 1.0 + 1e-9  # not towards it


def test_a_vehicle_taken_back_in_flight_keeps_the_disc_of_the_point_it_was_sent():
    """Lost with a point 16 m ahead, then climbing back under `launch`: its disc still covers that point."""
    guard = FlightGuard(GuardConfig(margin_m=0.0), min_separation_m=5.0, n_vehicles=1)
    rows = _rows([(0.0, 0.0)], [(100.0, 0.0)])
    _joined(guard, rows, now_s=0.05)
    sent = guard.decide(rows, now_s=0.1)[0]
    assert sent.point_m == (16.0, 0.0)
    guard.decide([], now_s=2.0)  # unheard: kept
    guard.decide([(0, (5.0, 0.0), (3.0, 0.0), 3.0, None, False)], now_s=3.0)  # taken back: not steered yet
    assert guard.fleet.joined(0) and _disc_distance(guard, 0, (16.0, 0.0)) <= 0.0


def test_two_vehicles_over_homes_6_m_apart_part_instead_of_freezing():
    """Closer than the guard can certify (6 m at a 5 m minimum with the default errors): both reach goals
    to the north, apart, instead of being held for as long as they stay close."""
    guard = FlightGuard(GuardConfig(), min_separation_m=5.0, n_vehicles=2)
    here = [np.array([0.0, 0.0]), np.array([6.0, 0.0])]
    goals = [(-20.0, 60.0), (26.0, 60.0)]
    points = [p.copy() for p in here]
    rows = _rows([tuple(p) for p in here], goals)
    _joined(guard, rows, now_s=0.05)
    for step in range(1, 600):  # 60 s at 10 decisions a second; each flies at most 5 m/s to its point
        now_s = 0.05 + 0.1 * step
        rows = [(i, tuple(here[i]), (0.0, 0.0), now_s, goals[i], True) for i in range(2)]
        for (i, *_), decision in zip(rows, guard.decide(rows, now_s), strict=True):
            if decision.point_m is not None:
                guard.acknowledged(i, decision.seq, now_s)
                points[i] = np.array(decision.point_m)
        for i in range(2):
            way = points[i] - here[i]
            here[i] = here[i] + way * min(1.0, 0.5 / max(float(np.hypot(*way)), 1e-9))
        assert np.hypot(*(here[0] - here[1])) >= 6.0 - 1e-9  # parting never closes on the other
    assert all(np.hypot(*(here[i] - goals[i])) < 1.0 for i in range(2))


def test_the_guard_is_one_lock_for_the_loop_and_the_sending_threads():
    import threading

    guard = FlightGuard(GuardConfig(margin_m=0.0), min_separation_m=5.0, n_vehicles=3)
    rows = _rows([(0.0, 0.0), (30.0, 0.0), (60.0, 0.0)], [(0.0, 50.0), (30.0, 50.0), (60.0, 50.0)])
    _joined(guard, rows, now_s=0.05)
    errors: list[BaseException] = []

    def answer() -> None:
        try:
            for seq in range(1, 400):
                for row in range(3):
                    guard.acknowledged(row, seq, now_s=0.06)
        except BaseException as exc:  # noqa: BLE001 - any error is the failure
            errors.append(exc)

    thread = threading.Thread(target=answer)
    thread.start()
    for step in range(200):
        guard.decide(rows, now_s=0.1 + 0.01 * step)
    thread.join()
    assert not errors
    assert guard.fleet._lock is not None
