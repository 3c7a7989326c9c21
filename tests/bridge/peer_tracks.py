"""How close test vehicles came, judged from their own tracks (not from anything the bridge measured).

Each :class:`ArduCopter` keeps where it flew (``track``: its clock, East, North, Up from its own
home). Its motion between two records is a straight line at constant speed (its kinematics), so the
tracks, put in one frame and interpolated on a common clock, give every pair's distance at any instant.
Also a planner that flies fixed targets, for scripted geometry (a swap, a crossing).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bridge.geo import Home, geodetic_to_enu
from uav_swarm.planning.base import PlanResult

__all__ = ["Approach", "closest_approach", "FixedTargets"]


@dataclass(frozen=True)
class Approach:
    """The closest two vehicles came: distance (3-D, metres), their system ids, when (their clock)."""

    distance_m: float
    pair: tuple[int, int]
    time_s: float


def _world_track(vehicle, origin: Home, start_s: float, end_s: float) -> np.ndarray:
    home = vehicle.geo_home
    offset = np.array(geodetic_to_enu(origin, home.lat_deg, home.lon_deg, home.alt_m))
    rows = np.array([row for row in list(vehicle.track) if start_s <= row[0] <= end_s], dtype=np.float64)
    return np.column_stack([rows[:, 0], rows[:, 1:4] + offset])


def closest_approach(vehicles, origin: Home | None = None, start_s: float = -math.inf,
                     end_s: float = math.inf, step_s: float = 0.01) -> Approach:
    """The closest approach of every pair of ``vehicles`` between ``start_s`` and ``end_s`` (monotonic)."""
    origin = origin or Home()
    tracks = [_world_track(v, origin, start_s, end_s) for v in vehicles]
    first = max(t[0, 0] for t in tracks)
    last = min(t[-1, 0] for t in tracks)
    clock = np.arange(first, last, step_s)
    points = np.stack([np.column_stack([np.interp(clock, t[:, 0], t[:, c]) for c in (1, 2, 3)])
                       for t in tracks])  # (K, T, 3)
    best = Approach(math.inf, (-1, -1), math.nan)
    for i in range(len(vehicles)):
        for j in range(i + 1, len(vehicles)):
            gaps = np.linalg.norm(points[i] - points[j], axis=1)
            k = int(np.argmin(gaps))
            if gaps[k] < best.distance_m:
                pair = (vehicles[i].system_id, vehicles[j].system_id)
                best = Approach(float(gaps[k]), pair, float(clock[k]))
    return best


class FixedTargets:
    """A planner that sends UAV ``k`` to ``targets_m[k]`` at every replan (scripted geometry)."""

    name = "fixed-targets"

    def __init__(self, targets_m: list[tuple[float, float]]) -> None:
        self.targets_m = np.asarray(targets_m, dtype=np.float64)
        self.n_uavs = len(targets_m)

    def plan(self, pedestrians_m: np.ndarray, uav_positions_m: np.ndarray,
             pedestrian_velocities_m_s: np.ndarray | None = None) -> PlanResult:
        n = self.n_uavs
        return PlanResult(targets_m=self.targets_m.copy(), peaks_m=self.targets_m.copy(), utility=None,
                          candidate_index=np.arange(n), kept=np.zeros(n, dtype=bool), latency_ms=0.0)

    def reset(self) -> None:
        """Nothing to forget."""
