"""Separation between UAVs: distances, the fleet's feasibility, start positions and a run's record (numpy).

``[uav] min_separation_m`` is the distance no two UAVs may come closer than; ``[uav] layer_step_m`` puts
UAV ``k`` at ``alt_m + k * layer_step_m``, and distances are then 3-D: a pair whose altitudes differ by
``dz`` needs only ``sqrt(d_min^2 - dz^2)`` horizontally (nothing when ``dz >= d_min``).

The step guard that keeps them apart in flight is :mod:`uav_swarm.world.step_guard`.

Examples:
    >>> import numpy as np
    >>> float(closest_distances_m(np.array([[0.0, 0.0], [3.0, 4.0], [20.0, 0.0]])))
    5.0
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from typed_config import ConfigError

__all__ = [
    "ClosestPair", "SeparationMonitor", "check_fleet_fits", "closest_distances_m", "closest_pair",
    "draw_apart_m", "max_spread_m", "pair_distances_m", "required_distances_m", "separation_penalty",
]

# Best known largest minimum distance of n points in a unit square (n = 2 ... 10; Schaer, Croft et al.).
_UNIT_SQUARE_SPREAD = (math.sqrt(2.0), 1.035276180, 1.0, 0.707106781, 0.600925213, 0.535898384,
                       0.517638090, 0.5, 0.421279543)


def pair_distances_m(positions_m: np.ndarray, altitudes_m: np.ndarray | None = None) -> np.ndarray:
    """(..., K, K) distances between UAVs (3-D with altitudes); the diagonal is ``inf``.

    Args:
        positions_m: (..., K, 2) horizontal positions in metres.
        altitudes_m: (K,) altitudes in metres, or None for one altitude (horizontal distances).
    """
    p = np.asarray(positions_m, dtype=np.float64)
    diff = p[..., :, None, :] - p[..., None, :, :]
    d2 = np.einsum("...c,...c->...", diff, diff)
    if altitudes_m is not None:
        dz = np.asarray(altitudes_m, dtype=np.float64)
        d2 = d2 + (dz[:, None] - dz[None, :]) ** 2
    d = np.sqrt(d2)
    k = p.shape[-2]
    d[..., np.arange(k), np.arange(k)] = np.inf
    return d


def closest_distances_m(positions_m: np.ndarray, altitudes_m: np.ndarray | None = None, *,
                        distances_m: np.ndarray | None = None) -> np.ndarray:
    """(...) distance of the closest pair of UAVs (``inf`` with fewer than two UAVs).

    ``distances_m``, the :func:`pair_distances_m` of the same positions when the caller has them, saves
    computing them again.

    Examples:
        >>> float(closest_distances_m(np.array([[0.0, 0.0], [3.0, 4.0], [20.0, 0.0]])))
        5.0
    """
    p = np.asarray(positions_m, dtype=np.float64)
    if p.shape[-2] < 2:
        return np.full(p.shape[:-2], np.inf)
    d = pair_distances_m(p, altitudes_m) if distances_m is None else distances_m
    return d.min(axis=(-2, -1))


@dataclass(frozen=True)
class ClosestPair:
    """The closest pair of UAVs of one instant."""

    distance_m: float
    first: int
    second: int


def closest_pair(positions_m: np.ndarray, altitudes_m: np.ndarray | None = None) -> ClosestPair:
    """The closest pair of a (K, 2) fleet, ``first < second`` (distance ``inf``, pair (-1, -1) if K < 2)."""
    p = np.asarray(positions_m, dtype=np.float64)
    if p.shape[0] < 2:
        return ClosestPair(math.inf, -1, -1)
    d = pair_distances_m(p, altitudes_m)
    i, j = np.unravel_index(int(np.argmin(d)), d.shape)
    return ClosestPair(float(d[i, j]), int(min(i, j)), int(max(i, j)))


def separation_penalty(positions_m: np.ndarray, min_separation_m: float,
                       altitudes_m: np.ndarray | None = None, *, distances_m: np.ndarray | None = None
                       ) -> np.ndarray:
    """(...) total intrusion of pairs closer than ``min_separation_m``: ``sum(1 - d / d_min)`` over them.

    Each pair at distance ``d < min_separation_m`` adds ``1 - d / min_separation_m`` (1 when they
    coincide); 0 disables the penalty. The result lies in ``[0, K (K - 1) / 2]``. ``distances_m``, the
    :func:`pair_distances_m` of the same positions when the caller has them, saves computing them again.

    Examples:
        >>> float(separation_penalty(np.array([[0.0, 0.0], [2.5, 0.0]]), 5.0))
        0.5
    """
    p = np.asarray(positions_m, dtype=np.float64)
    if p.shape[-2] < 2 or min_separation_m <= 0:
        return np.zeros(p.shape[:-2])
    d = pair_distances_m(p, altitudes_m) if distances_m is None else distances_m
    intrusion = np.where(d < min_separation_m, 1.0 - d / min_separation_m, 0.0)
    return intrusion.sum(axis=(-2, -1)) / 2.0


def required_distances_m(min_separation_m: float, altitudes_m: np.ndarray | None, n_uavs: int) -> np.ndarray:
    """(K, K) horizontal distance each pair needs: ``sqrt(max(d_min^2 - dz^2, 0))`` (0 on the diagonal)."""
    if altitudes_m is None:
        required = np.full((n_uavs, n_uavs), float(min_separation_m))
    else:
        dz = np.asarray(altitudes_m, dtype=np.float64)
        required = np.sqrt(np.maximum(min_separation_m**2 - (dz[:, None] - dz[None, :]) ** 2, 0.0))
    np.fill_diagonal(required, 0.0)
    return required


def max_spread_m(n_uavs: int, width_m: float, height_m: float) -> float:
    """The largest minimum distance this module can give ``n_uavs`` points in a ``width_m x height_m`` area.

    The best of: the best known spread in a square of the shorter side, and square grids of ``r x c``
    points (a construction, so the figure is always reachable; the true optimum of a long rectangle may be
    a little larger). ``inf`` for fewer than two UAVs.

    Examples:
        >>> round(max_spread_m(10, 200.0, 200.0), 1)  # 10 points in a 200 m square
        84.3
    """
    if n_uavs < 2:
        return math.inf
    best = math.hypot(width_m, height_m) if n_uavs == 2 else 0.0
    if n_uavs <= len(_UNIT_SQUARE_SPREAD) + 1:
        best = max(best, min(width_m, height_m) * _UNIT_SQUARE_SPREAD[n_uavs - 2])
    for cols in range(1, n_uavs + 1):
        rows = -(-n_uavs // cols)
        gap_x = width_m / (cols - 1) if cols > 1 else math.inf
        gap_y = height_m / (rows - 1) if rows > 1 else math.inf
        best = max(best, min(gap_x, gap_y))
    return best


def check_fleet_fits(n_uavs: int, min_separation_m: float, width_m: float, height_m: float, *,
                     field: str = "uav.min_separation_m") -> None:
    """Refuse a minimum separation the fleet cannot keep in its area, naming ``field``.

    Raises:
        ConfigError: ``min_separation_m`` exceeds :func:`max_spread_m` for the fleet and area.

    Examples:
        >>> try:
        ...     check_fleet_fits(10, 90.0, 200.0, 200.0)
        ... except ConfigError as error:
        ...     print(error)
        uav.min_separation_m = 90 m cannot be kept by 10 UAVs in a 200 x 200 m area: allowed 0 <= \
uav.min_separation_m <= 84.2
    """
    spread = max_spread_m(n_uavs, width_m, height_m)
    if min_separation_m > spread:
        raise ConfigError(
            f"{field} = {min_separation_m:g} m cannot be kept by {n_uavs} UAVs in a "
            f"{width_m:g} x {height_m:g} m area: allowed 0 <= {field} <= {math.floor(spread * 10) / 10:g}")


def draw_apart_m(rng: np.random.Generator, n_uavs: int, area_m: np.ndarray, required_m: np.ndarray, *,
                 max_tries: int = 10_000) -> np.ndarray:
    """(K, 2) uniform positions in ``[0, area_m]``, redrawn one UAV at a time until pairs keep ``required_m``.

    The first draw is ``rng.uniform(0, area_m, (K, 2))``; only a UAV closer than ``required_m`` (K, K) to an
    earlier one is drawn again, so a draw that already keeps its distances costs nothing more.

    Raises:
        ValueError: No such positions were found in ``max_tries`` draws (the minimum barely fits).

    Examples:
        >>> p = draw_apart_m(np.random.default_rng(0), 10, np.array([30.0, 30.0]), np.full((10, 10), 5.0))
        >>> bool(closest_distances_m(p) >= 5.0)
        True
    """
    area = np.asarray(area_m, dtype=np.float64)
    positions = rng.uniform(0.0, area, size=(n_uavs, 2))
    tries = 0
    for uav in range(1, n_uavs):
        while np.any(np.linalg.norm(positions[:uav] - positions[uav], axis=1) < required_m[uav, :uav]):
            tries += 1
            if tries > max_tries:
                raise ValueError(f"no start positions {required_m.max():g} m apart for {n_uavs} UAVs "
                                 f"in {max_tries} draws")
            positions[uav] = rng.uniform(0.0, area)
    return positions


class SeparationMonitor:
    """What a run reports about separation: the closest pair, conflicts, time below the minimum, holds.

    Feed it the positions of each sample (:meth:`observe`) and the guard's holds (:meth:`count_holds`).
    A *conflict* is a pair entering below the minimum (closer now, not closer at its previous sample).

    Examples:
        >>> monitor = SeparationMonitor(5.0)
        >>> for t_s, gap_m in [(0.0, 10.0), (1.0, 4.0), (2.0, 3.0), (3.0, 8.0)]:
        ...     _ = monitor.observe(t_s, np.array([[0.0, 0.0], [gap_m, 0.0]]))
        >>> s = monitor.summary()
        >>> s["closest_m"], s["closest_pair"], s["closest_t_s"], s["conflicts"], s["time_below_min_s"]
        (3.0, [0, 1], 2.0, 1, 2.0)
    """

    def __init__(self, min_separation_m: float, altitudes_m: np.ndarray | None = None) -> None:
        self.min_separation_m = float(min_separation_m)
        self._altitudes_m = altitudes_m
        self._closest = ClosestPair(math.inf, -1, -1)
        self._closest_t_s = math.nan
        self._below: np.ndarray | None = None
        self._last_t_s: float | None = None
        self.conflicts = 0
        self.time_below_min_s = 0.0
        self.holds = 0
        self.samples = 0

    def observe(self, t_s: float, positions_m: np.ndarray, ids: list[int] | None = None) -> float:
        """Record one sample of (K, 2) positions at time ``t_s``; returns its closest distance (m).

        ``ids`` names the UAVs of the rows (default 0 ... K-1): a fleet whose membership changes (a lost
        vehicle) keeps its pairs apart by id.
        """
        p = np.asarray(positions_m, dtype=np.float64)
        names = list(range(p.shape[0])) if ids is None else list(ids)
        altitudes = None if self._altitudes_m is None else np.asarray(self._altitudes_m)[names]
        pair = closest_pair(p, altitudes)
        if pair.distance_m < self._closest.distance_m:
            self._closest = ClosestPair(pair.distance_m, names[pair.first], names[pair.second])
            self._closest_t_s = float(t_s)
        size = max(names, default=-1) + 1
        below = np.zeros((size, size), dtype=bool)
        if p.shape[0] >= 2:
            close = pair_distances_m(p, altitudes) < self.min_separation_m
            below[np.ix_(names, names)] = close
        previous = self._below
        if previous is not None:
            overlap = min(previous.shape[0], size)
            entering = below.copy()
            entering[:overlap, :overlap] &= ~previous[:overlap, :overlap]
        else:
            entering = below
        self.conflicts += int(np.count_nonzero(np.triu(entering)))
        if self._last_t_s is not None and below.any():
            self.time_below_min_s += float(t_s) - self._last_t_s
        self._below, self._last_t_s = below, float(t_s)
        self.samples += 1
        return pair.distance_m

    def count_holds(self, n: int) -> None:
        """Add ``n`` commands the guard held back (a UAV turned or braked for another)."""
        self.holds += int(n)

    def summary(self) -> dict[str, Any]:
        """The run's figures, JSON-ready.

        Keys: ``min_separation_m``, ``closest_m``, ``closest_pair``, ``closest_t_s``, ``conflicts``,
        ``time_below_min_s``, ``holds``, ``samples`` (the closest pair is None before two UAVs flew).
        """
        finite = math.isfinite(self._closest.distance_m)
        return {
            "min_separation_m": self.min_separation_m,
            "closest_m": round(self._closest.distance_m, 3) if finite else None,
            "closest_pair": [self._closest.first, self._closest.second] if finite else None,
            "closest_t_s": self._closest_t_s if finite else None,
            "conflicts": self.conflicts,
            "time_below_min_s": round(self.time_below_min_s, 3),
            "holds": self.holds,
            "samples": self.samples,
        }
