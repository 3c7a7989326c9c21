"""Failsafe flights and the launch (:mod:`uav_swarm.world.guard.failsafe`), judged by flying them.

Each failsafe flight is flown as the autopilots fly RTL (climb where it is, straight home at its layer,
descend), with ArduCopter's default speeds, from every start time of a grid: the theorem says two
flights found apart keep the minimum whatever their start times.
"""

from __future__ import annotations

import numpy as np
import pytest

from uav_swarm.world.guard.failsafe import (
    FailsafeFlight,
    crossing_order,
    flights_apart,
    launch_spacing_m,
)

MIN_M, MARGIN_M = 5.0, 1.0
NEED_M = MIN_M + MARGIN_M
CRUISE_M = 10.0
UP_M_S, ACROSS_M_S, DOWN_M_S = 2.5, 10.0, 1.5  # ArduCopter's WPNAV_SPEED_UP, WPNAV_SPEED, WPNAV_SPEED_DN
DT_S = 0.05


def _fly(start: tuple[float, float], home: tuple[float, float], layer_m: float, t_s: np.ndarray,
         begin_s: float) -> np.ndarray:
    """(T, 3) positions of a failsafe flight begun at ``begin_s`` (hovering at its start before)."""
    start_v, home_v = np.array(start), np.array(home)
    way_m = float(np.hypot(*(home_v - start_v)))
    climb_s, across_s = (layer_m - CRUISE_M) / UP_M_S, way_m / ACROSS_M_S
    down_s = layer_m / DOWN_M_S
    t = np.clip(t_s - begin_s, 0.0, None)
    up = np.clip(t / climb_s, 0.0, 1.0)
    along = np.clip((t - climb_s) / across_s, 0.0, 1.0) if across_s > 0 else (t >= climb_s).astype(float)
    down = np.clip((t - climb_s - across_s) / down_s, 0.0, 1.0)
    xy = start_v + along[:, None] * (home_v - start_v)
    z = CRUISE_M + up * (layer_m - CRUISE_M) - down * layer_m
    return np.column_stack([xy, z])


def _closest_m(a: FailsafeFlight, b: FailsafeFlight, offsets_s: np.ndarray,
               a_start: tuple[float, float] | None = None,
               b_start: tuple[float, float] | None = None) -> float:
    """Least 3-D distance of the two flights flown, over every start offset of ``b`` after ``a``."""
    t_s = np.arange(0.0, 120.0, DT_S)
    pa = _fly(a_start or a.start_m, a.home_m, a.layer_m, t_s, 0.0)
    best = np.inf
    for offset_s in offsets_s:
        pb = _fly(b_start or b.start_m, b.home_m, b.layer_m, t_s, float(offset_s))
        best = min(best, float(np.linalg.norm(pa - pb, axis=1).min()))
    return best


def test_an_rtl_cleared_by_the_old_rule_meets_a_silent_vehicle_s_failsafe_climb():
    """The reproducer: an RTL whose way home passes over a silent vehicle. The rule before checked only
    its home against the silent vehicle's disc (28 m clear); the silent vehicle's own failsafe, begun a
    few seconds later, climbs through the RTL's layer where the RTL flies: they meet."""
    rtl = FailsafeFlight((0.0, 0.0), 0.0, (0.0, -60.0), 0.0, layer_m=16.0)
    silent = FailsafeFlight((0.0, -30.0), 2.0, (40.0, -30.0), 1.0, layer_m=22.0)
    home_to_disc_m = float(np.hypot(*(np.array(rtl.home_m) - np.array(silent.start_m))))
    old_rule_gap_m = home_to_disc_m - silent.start_radius_m
    assert old_rule_gap_m >= NEED_M  # the rule before sent this RTL
    closest_m = _closest_m(rtl, silent, np.arange(0.0, 12.0, 0.25))
    assert closest_m < 1.0, closest_m  # 0.00 m in the words
    assert not flights_apart(rtl, silent, NEED_M)  # refused now
    order = crossing_order([rtl, silent], NEED_M)
    assert order == [1, 0]  # the RTL's way passes over the silent one's column: it flies higher
    rtl_above = rtl.at_layer(28.0)
    assert flights_apart(rtl_above, silent, NEED_M)
    assert _closest_m(rtl_above, silent, np.arange(-20.0, 20.0, 0.25)) >= MIN_M


def test_failsafe_flights_found_apart_keep_the_minimum_whatever_their_start_times():
    """Fuzz of the theorem: random starts (each anywhere in its disc), homes and layers; every pair found
    apart is flown from 81 start offsets and keeps the minimum; some pairs are refused and some not."""
    rng = np.random.default_rng(62)
    apart = refused = 0
    for _ in range(120):
        flights = []
        for _ in range(2):
            start = tuple(rng.uniform(-60.0, 60.0, 2))
            home = tuple(rng.uniform(-60.0, 60.0, 2))
            flights.append(FailsafeFlight(start, float(rng.uniform(0.5, 6.0)), home, 1.0,
                                          layer_m=float(rng.choice([16.0, 22.0, 28.0]))))
        a, b = flights
        if not flights_apart(a, b, NEED_M):
            refused += 1
            continue
        apart += 1
        for _ in range(2):  # where each starts inside its disc
            a_start = _inside(rng, a)
            b_start = _inside(rng, b)
            assert _closest_m(a, b, np.arange(-20.0, 20.5, 0.5), a_start, b_start) >= MIN_M, (a, b)
    assert apart >= 20 and refused >= 20, (apart, refused)


def _inside(rng: np.random.Generator, flight: FailsafeFlight) -> tuple[float, float]:
    angle, r = rng.uniform(0, 2 * np.pi), flight.start_radius_m * np.sqrt(rng.uniform())
    return flight.start_m[0] + r * np.cos(angle), flight.start_m[1] + r * np.sin(angle)


def test_a_cycle_of_crossings_has_no_order_and_layers_apart_are_required():
    a = FailsafeFlight((0.0, 0.0), 1.0, (40.0, 0.0), 1.0)
    b = FailsafeFlight((40.0, 2.0), 1.0, (0.0, 2.0), 1.0)  # a swap: each way over the other's columns
    assert crossing_order([a, b], NEED_M) is None
    far = FailsafeFlight((0.0, 100.0), 1.0, (40.0, 100.0), 1.0)
    assert crossing_order([a, far], NEED_M) == [0, 1]  # free: the given order
    assert not flights_apart(a.at_layer(16.0), far.at_layer(19.0), NEED_M)  # layers closer than the need


@pytest.mark.parametrize(("spacing_m", "keeps"), [(MIN_M, False), (None, True)],
                         ids=["homes-at-the-minimum", "homes-at-the-launch-spacing"])
def test_climbing_together_keeps_the_minimum_from_the_launch_spacing_on(spacing_m, keeps):
    """1,000 launches of two vehicles climbing together: homes measured ``spacing_m`` apart, each true home
    within the position error of its measure, each vehicle within the tracking error of its column at
    every instant (drawn at random, half of them pushed towards the other). From the launch spacing the
    minimum holds in every launch; from homes the minimum apart it does not."""
    e_t, e_p = 0.5, 0.5
    spacing = spacing_m if spacing_m is not None else launch_spacing_m(
        MIN_M, margin_m=MARGIN_M, tracking_error_m=e_t, position_error_m=e_p)
    rng = np.random.default_rng(7)
    closest = np.inf
    for launch in range(1000):
        heading = rng.uniform(0, 2 * np.pi)
        measured = np.array([[0.0, 0.0], [spacing * np.cos(heading), spacing * np.sin(heading)]])
        toward = (measured[1] - measured[0]) / spacing
        worst = launch % 2 == 0
        true_homes = measured + (np.array([toward, -toward]) * e_p if worst
                                 else _disc(rng, (2, 2), e_p))
        steps = 200  # the climb, sampled
        drift = (np.broadcast_to(np.array([toward, -toward]) * e_t, (steps, 2, 2)) if worst
                 else _disc(rng, (steps, 2, 2), e_t))
        heights = np.linspace(0.0, CRUISE_M, steps)[:, None] + rng.uniform(-0.3, 0.3, (steps, 2))
        xy = true_homes[None] + drift
        gap = np.sqrt(np.sum((xy[:, 0] - xy[:, 1]) ** 2, axis=1) + (heights[:, 0] - heights[:, 1]) ** 2)
        closest = min(closest, float(gap.min()))
    assert (closest >= MIN_M) == keeps, closest
    if not keeps:
        assert closest == pytest.approx(MIN_M - 2 * (e_t + e_p), abs=0.35)  # 3.0 m in the words


def _disc(rng: np.random.Generator, shape: tuple[int, ...], radius_m: float) -> np.ndarray:
    angle = rng.uniform(0, 2 * np.pi, shape[:-1])
    r = radius_m * np.sqrt(rng.uniform(size=shape[:-1]))
    return np.stack([r * np.cos(angle), r * np.sin(angle)], axis=-1)
