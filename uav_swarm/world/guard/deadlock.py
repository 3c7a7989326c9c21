"""Cycles of holds: vehicles each held by the next, none of which can move first, found and broken.

At a decision, each held vehicle names the one whose set refused its next point (its *blocker*). Each
vehicle names at most one, so the holds form a functional graph, and a deadlock is one of its cycles:
``a`` held by ``b``, ``b`` by ``c``, ..., back to ``a``. :func:`hold_cycles` finds them (each once, from
its smallest member). :func:`yielding` says how one is broken: the member with the most progress (the
least way left to its goal) is decided first from then on (priority by progress), while the others give
way: held, their sets shrink as they slow, and after ``detour_after_s`` they go round the one they wait
for, as any held vehicle (:class:`~uav_swarm.world.guard.fleet.FleetGuard`; sending them round at once
was measured to slow a launch line). Breaking a cycle changes which points are offered and in which
order, never which are accepted: every point sent still passes the guard's rule, so the separation
proof is untouched.

Examples:
    >>> blockers = np.array([1, 2, 0, -1, 3])  # 0 -> 1 -> 2 -> 0, and 4 waits for 3 (parked)
    >>> hold_cycles(blockers)
    [(0, 1, 2)]
    >>> yielding((0, 1, 2), np.array([30.0, 5.0, 12.0, 0.0, 9.0]))  # 1 is nearest its goal: it goes on
    (1, (0, 2))
"""

from __future__ import annotations

import numpy as np

__all__ = ["hold_cycles", "yielding"]


def hold_cycles(blockers: np.ndarray) -> list[tuple[int, ...]]:
    """Every cycle of the hold graph ``i -> blockers[i]`` (-1: not held), each from its smallest member."""
    k = len(blockers)
    state = np.zeros(k, dtype=np.int8)  # 0 unseen, 1 on the current walk, 2 done
    cycles = []
    for start in range(k):
        walk, i = [], start
        while 0 <= i < k and state[i] == 0:
            state[i] = 1
            walk.append(i)
            i = int(blockers[i])
        if 0 <= i < k and state[i] == 1:  # the walk met itself: a cycle from i on
            cycle = walk[walk.index(i):]
            first = cycle.index(min(cycle))
            cycles.append(tuple(cycle[first:] + cycle[:first]))
        for j in walk:
            state[j] = 2
    return cycles


def yielding(cycle: tuple[int, ...], way_left_m: np.ndarray) -> tuple[int, tuple[int, ...]]:
    """``(goes_on, give_way)``: the member with the least way left goes on, the others give way."""
    goes_on = min(cycle, key=lambda i: (float(way_left_m[i]), i))
    return goes_on, tuple(i for i in cycle if i != goes_on)
