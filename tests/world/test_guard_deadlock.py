"""Cycles of holds: found exactly, recorded once while they last, broken by going round."""

from __future__ import annotations

import numpy as np
import pytest

from uav_swarm.world.guard import Bounds, FleetGuard
from uav_swarm.world.guard.deadlock import hold_cycles


def _brute_cycles(blockers: np.ndarray) -> set[tuple[int, ...]]:
    """Every cycle, by following each vertex until it comes back to itself (or not)."""
    found = set()
    for start in range(len(blockers)):
        walk, i = [start], int(blockers[start])
        while 0 <= i and i not in walk:
            walk.append(i)
            i = int(blockers[i])
        if i == start:
            first = walk.index(min(walk))
            found.add(tuple(walk[first:] + walk[:first]))
    return found


@pytest.mark.parametrize("seed", range(5))
def test_hold_cycles_are_exactly_the_cycles_of_the_hold_graph(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for _ in range(200):
        k = int(rng.integers(1, 11))
        blockers = np.where(rng.random(k) < 0.3, -1, rng.integers(0, k, size=k))
        blockers = np.where(blockers == np.arange(k), -1, blockers)  # nobody is held by itself
        cycles = hold_cycles(blockers)
        assert len(cycles) == len(set(cycles))
        assert set(cycles) == _brute_cycles(blockers)


def test_a_head_on_swap_is_found_as_a_cycle_and_both_arrive_apart() -> None:
    guard = FleetGuard(np.full((2, 2), 5.0))
    bounds = Bounds(accel_m_s2=2.5, command_delay_s=0.5)
    position = {0: np.array([0.0, 0.0]), 1: np.array([30.0, 1.0])}
    for i, p in position.items():
        guard.join(i, p, bounds, now_s=0.0, radius_m=0.0)
    goals = np.array([[30.0, 0.0], [0.0, 0.0]])
    now_s = 0.0
    for _ in range(80):  # each vehicle at rest at its newest point when measured (it flew there)
        for i, decision in enumerate(guard.decide(goals, now_s)):
            if decision.point_m is not None:
                guard.acknowledged(i, decision.seq, now_s)
                position[i] = np.array(decision.point_m)
        gap = np.hypot(*(guard.centre_m(0) - guard.centre_m(1))) - guard.radius_m(0) - guard.radius_m(1)
        assert gap >= 5.0 - 1e-9
        now_s += 0.5
        for i, p in position.items():
            guard.measure(i, p, np.zeros(2), now_s, now_s)
    assert [p.tolist() for p in position.values()] == goals.tolist()
    assert guard.deadlocks, "the two held each other at some decision"
    assert {cycle for _, cycle in guard.deadlocks} == {(0, 1)}
    assert len(guard.deadlocks) < 20  # once per spell, not at every decision of it
