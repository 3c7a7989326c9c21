"""Cycles of holds: vehicles each held by the next, none of which can move first, found and named.

At a decision, each held vehicle names the one whose set refused its next point (its *blocker*). Each
vehicle names at most one, so the holds form a functional graph, and a deadlock is one of its cycles:
``a`` held by ``b``, ``b`` by ``c``, ..., back to ``a``. :func:`hold_cycles` finds them (each once, from
its smallest member); :class:`~uav_swarm.world.guard.fleet.FleetGuard` records them and ``fly``'s status
line names them. They are broken as any hold is: a vehicle held ``detour_after_s`` goes round the one it
waits for. (Deciding the member with the least way left first was tried and changed nothing measurable on
the liveness cases; it is not used.) Finding a cycle changes no decision, so the separation proof is
untouched.

Examples:
    >>> hold_cycles(np.array([1, 2, 0, -1, 3]))  # 0 -> 1 -> 2 -> 0, and 4 waits for 3 (not held)
    [(0, 1, 2)]
"""

from __future__ import annotations

import numpy as np

__all__ = ["hold_cycles"]


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
