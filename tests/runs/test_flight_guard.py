"""The flight guard steering simulated autopilots that answer late: scripted crossings keep the minimum.

Each vehicle is flown as an autopilot flies a reposition (accelerate at its limit, brake to stop on
the point); the guard decides 10 times a second on the positions, and its points reach the vehicles
``latency_s`` later, as commands over a link do.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from uav_swarm.runs.flight_guard import FlightGuard, GuardConfig, braking_track_m, route_track_m
from uav_swarm.world.separation import closest_distances_m
from uav_swarm.world.uav import UAVConfig

DT_S = 0.05


def _autopilot(p: np.ndarray, v: np.ndarray, points: np.ndarray, uav: UAVConfig) -> None:
    """One step of each vehicle toward its point: speed up to the cap, brake to stop on it (in place)."""
    offset = points - p
    distance = np.hypot(offset[:, 0], offset[:, 1])
    braking = np.sqrt(2 * uav.max_accel_m_s2 * distance)
    speed = np.minimum(np.minimum(uav.max_speed_m_s, braking), distance / DT_S)
    with np.errstate(invalid="ignore", divide="ignore"):
        want = np.where(distance[:, None] > 1e-9, offset * (speed / distance)[:, None], 0.0)
    change = want - v
    size = np.hypot(change[:, 0], change[:, 1])
    cap = uav.max_accel_m_s2 * DT_S
    change *= np.minimum(1.0, cap / np.maximum(size, 1e-12))[:, None]
    v += change
    p += v * DT_S


def _fly(starts, goals, speed_m_s: float, latency_s: float, seconds: float = 90.0):
    uav = UAVConfig(min_separation_m=5.0, max_speed_m_s=speed_m_s, max_accel_m_s2=5.0)
    guard = FlightGuard(GuardConfig(rate_hz=10.0), uav)
    p, v = np.array(starts, dtype=np.float64), np.zeros((len(starts), 2))
    points = p.copy()
    pending: list[tuple[float, int, tuple[float, float]]] = []
    closest, holds, states = math.inf, 0, ["free"] * len(starts)
    for step in range(int(seconds / DT_S)):
        now_s = step * DT_S
        if step % 2 == 0:  # 10 Hz
            decisions = guard.decide(p, v, goals, [True] * len(starts), now_s)
            holds += sum(d.state == "held" and s != "held" for d, s in zip(decisions, states, strict=True))
            states = [d.state for d in decisions]
            pending += [(now_s + latency_s, i, d.point_m) for i, d in enumerate(decisions) if d.point_m]
        for due in [c for c in pending if c[0] <= now_s]:
            points[due[1]] = due[2]
            pending.remove(due)
        _autopilot(p, v, points, uav)
        closest = min(closest, float(closest_distances_m(p)))
    reached = float(np.max(np.hypot(*(p - np.asarray(goals)).T)))
    return closest, reached, holds


_TEN = [(10.0 + 20.0 * i, 20.0) for i in range(5)] + [(10.0 + 20.0 * i, 80.0) for i in range(5)]
CASES = {
    "swap-head-on": ([(0.0, 50.0), (40.0, 50.0)], [(40.0, 50.0), (0.0, 50.0)]),
    "four-converging": ([(0.0, 50.0), (100.0, 50.0), (50.0, 0.0), (50.0, 100.0)],
                        [(100.0, 50.0), (0.0, 50.0), (50.0, 100.0), (50.0, 0.0)]),
    "four-reversed-line": ([(0.0, 0.0), (20.0, 0.0), (40.0, 0.0), (60.0, 0.0)],
                           [(60.0, 0.0), (40.0, 0.0), (20.0, 0.0), (0.0, 0.0)]),
    "ten-permuted": (_TEN, [_TEN[j] for j in np.random.default_rng(0).permutation(10)]),
}


@pytest.mark.parametrize("speed_m_s", [5.0, 12.0, 25.0])
@pytest.mark.parametrize("case", list(CASES))
def test_scripted_crossings_keep_the_minimum_and_arrive(case, speed_m_s):
    starts, goals = CASES[case]
    closest, reached, holds = _fly(starts, goals, speed_m_s, latency_s=0.4)
    assert closest >= 5.0, closest
    assert reached <= 0.5, reached  # every vehicle got to its target
    if case != "ten-permuted":
        assert holds >= 1  # flown straight, they would have met


def test_without_the_guard_the_same_swap_collides():
    """The reference: the scripted swap flown straight comes far below the minimum (the test can fail)."""
    uav = UAVConfig(min_separation_m=5.0, max_speed_m_s=12.0, max_accel_m_s2=5.0)
    starts, goals = CASES["swap-head-on"]
    p, v = np.array(starts), np.zeros((2, 2))
    closest = math.inf
    for _ in range(int(20 / DT_S)):
        _autopilot(p, v, np.array(goals), uav)
        closest = min(closest, float(closest_distances_m(p)))
    assert closest < 1.0


def test_predicted_tracks_follow_the_kinematics():
    times = np.arange(0.0, 10.0, 0.1)
    brake = braking_track_m(np.zeros(2), np.array([10.0, 0.0]), times, 0.5, 5.0)
    assert brake[-1, 0] == pytest.approx(10.0 * 0.5 + 10.0**2 / (2 * 5.0))  # latency, then v^2 / 2a
    route = route_track_m(np.zeros(2), np.zeros(2), [(30.0, 0.0), (30.0, 40.0)], times, 0.0, 10.0, 5.0)
    assert route[-1].tolist() == pytest.approx([30.0, 40.0])  # the whole route, then it stays
    assert route[10, 0] == pytest.approx(0.5 * 5.0 * 1.0**2)  # speeding up at 5 m/s^2


def test_a_vehicle_parked_on_the_way_is_gone_round():
    """UAV 0 hovers on its target, on UAV 1's way: UAV 1 goes round it and arrives (no deadlock)."""
    closest, reached, _ = _fly([(30.0, 30.0), (10.0, 0.0)], [(30.0, 30.0), (170.0, 170.0)], 12.0, 0.4)
    assert closest >= 5.0 and reached <= 0.5  # held for ever before it went round (the way passes 6.0 m)
