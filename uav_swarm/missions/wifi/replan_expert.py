"""The strategy-2 expert in flight: each replan warm-started from the placement flying, with a move cost.

A fresh solve of the strategy-2 experts (:mod:`uav_swarm.missions.wifi.expert`, the 802.11 expert of
:mod:`uav_swarm.missions.wifi.ieee80211_expert`) picks one of many placements that serve about as many
users: a crowd that walked a second later gets another of them, and the swarm chases targets that
jump across the area. :class:`ReplanExpert` answers a replan from the placement it gave last:

1. **Warm start.** The last placement is made valid on the crowd of now and improved locally
   (:func:`warm_placement`): under the paper's radio the search expert's repair, centring and greedy
   fill from it (a UAV moves to the centroid of its own users only when nobody it serves is lost,
   so users stay with their UAV while they can); under the 802.11 radio the 802.11 expert's greedy,
   polish and prune from it, the polish limited to ``warm_moves`` moves.
2. **A fresh solve, now and then.** Every ``fresh_every`` replans (and at the first) the expert's own
   solve of the crowd is computed too. It replaces the warm placement only when it serves more users
   than the warm one by ``move_cost_users_per_100m`` users per 100 m of the travel it asks for (the
   least-total-distance pairing of the UAVs, a UAV without partner counted ``unpaired_m``): a
   placement that moves less is worth more in flight.

Everything is deterministic: the same sequence of crowds gives the same sequence of placements.

Example:
    >>> travel_m(np.array([[0.0, 0.0], [10.0, 0.0]]), np.array([[3.0, 4.0]]), unpaired_m=50.0)
    55.0
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from typed_config import Config, param

__all__ = ["ReplanExpertConfig", "ReplanExpert", "travel_m"]


@dataclass(frozen=True)
class ReplanExpertConfig(Config):
    """Settings of the strategy-2 expert's replans in flight ([task.expert.replan])."""

    warm_start: bool = param(
        True, doc="start each replan from the last placement (false: a fresh solve every replan, as before)")
    fresh_every: int = param(
        10, ge=0, le=100_000, doc="replans between two fresh solves that may replace the warm placement "
        "(0: only the first)")
    move_cost_users_per_100m: float = param(
        2.0, ge=0.0, le=10_000.0, doc="a fresh solve replaces the warm placement only when it serves this "
        "many more users per 100 m of the UAVs' travel to it")
    unpaired_m: float = param(
        50.0, ge=0.0, le=10_000.0, doc="travel counted for a UAV added or removed by a placement, metres")
    warm_moves: int = param(
        4, ge=0, le=1000, doc="802.11 radio: polish moves allowed from the warm start (the fresh solve keeps "
        "its own max_moves)")


def travel_m(previous_m: np.ndarray, new_m: np.ndarray, unpaired_m: float) -> float:
    """Metres the UAVs travel from ``previous_m`` to ``new_m``: least-total-distance pairs plus the unpaired.

    >>> travel_m(np.zeros((0, 2)), np.array([[1.0, 1.0]]), 20.0)
    20.0
    """
    previous_m = np.asarray(previous_m, np.float64).reshape(-1, 2)
    new_m = np.asarray(new_m, np.float64).reshape(-1, 2)
    unpaired = abs(len(previous_m) - len(new_m)) * unpaired_m
    if len(previous_m) == 0 or len(new_m) == 0:
        return float(unpaired)
    distance = np.linalg.norm(previous_m[:, None, :] - new_m[None, :, :], axis=2)
    rows, cols = linear_sum_assignment(distance)
    return float(distance[rows, cols].sum() + unpaired)


class ReplanExpert:
    """The expert's placements of a sequence of crowds, each warm-started from the last (module docstring).

    Args:
        config: Warm start, fresh solves and move cost.
        fresh: The expert's own solve: ``(users_m, velocities_m_s)`` to ``(k, 2)`` UAV positions, metres.
        warm: The warm start: ``(users_m, last_m)`` to ``(k, 2)`` UAV positions, metres.
        served: Users a placement serves: ``(users_m, uavs_m)`` to a count.
    """

    def __init__(self, config: ReplanExpertConfig,
                 fresh: Callable[[np.ndarray, np.ndarray | None], np.ndarray],
                 warm: Callable[[np.ndarray, np.ndarray], np.ndarray],
                 served: Callable[[np.ndarray, np.ndarray], int]) -> None:
        self.config = config
        self._fresh, self._warm, self._served = fresh, warm, served
        self.last_m: np.ndarray | None = None
        self.replans = 0
        self.fresh_taken = 0

    def reset(self) -> None:
        """Forget the last placement: the next replan solves afresh."""
        self.last_m = None
        self.replans = 0

    def place(self, users_m: np.ndarray, velocities_m_s: np.ndarray | None = None) -> np.ndarray:
        """The placement of this crowd: warm from the last one, or the fresh solve where it is worth it."""
        users_m = np.asarray(users_m, np.float64).reshape(-1, 2)
        config = self.config
        first = self.last_m is None or not config.warm_start
        due = config.fresh_every > 0 and self.replans % config.fresh_every == 0
        self.replans += 1
        if first or self.last_m is None:
            placement = np.asarray(self._fresh(users_m, velocities_m_s), np.float64).reshape(-1, 2)
            self.fresh_taken += 1
        else:
            placement = np.asarray(self._warm(users_m, self.last_m), np.float64).reshape(-1, 2)
            if due:
                placement = self._better(users_m, velocities_m_s, placement)
        self.last_m = placement
        return placement

    def _better(self, users_m: np.ndarray, velocities_m_s: np.ndarray | None, warm_m: np.ndarray
                ) -> np.ndarray:
        """The fresh solve when its gain pays for its extra travel, else the warm placement."""
        assert self.last_m is not None
        fresh_m = np.asarray(self._fresh(users_m, velocities_m_s), np.float64).reshape(-1, 2)
        cost = self.config.move_cost_users_per_100m / 100.0
        unpaired_m = self.config.unpaired_m
        warm_value = self._served(users_m, warm_m) - cost * travel_m(self.last_m, warm_m, unpaired_m)
        fresh_value = self._served(users_m, fresh_m) - cost * travel_m(self.last_m, fresh_m, unpaired_m)
        if fresh_value > warm_value:
            self.fresh_taken += 1
            return fresh_m
        return warm_m
