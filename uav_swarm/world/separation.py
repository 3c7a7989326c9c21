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

import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from typed_config import ConfigError

__all__ = [
    "ClosestPair", "SeparationMonitor", "check_fleet_fits", "closest_distances_m", "closest_pair",
    "draw_apart_m", "fleet_slots_m", "max_spread_m", "pair_distances_m", "required_distances_m",
    "separation_penalty",
]

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


def _layouts(width_m: float, height_m: float, rows: np.ndarray, cols: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    """``(gap (L,), capacity (L,))`` of the layouts ``(kind, rows, cols)`` (kind 0: grid, 1: staggered).

    A *grid* puts ``cols`` points evenly from ``0`` to ``width_m`` (one column: the middle) on ``rows``
    lines evenly from ``0`` to ``height_m``; a *staggered* layout alternates lines of ``cols`` points and
    lines of ``cols - 1`` points set in the middle of the gaps (a hexagonal packing stretched to the area).
    """
    r, c = rows.astype(np.float64), cols.astype(np.float64)
    with np.errstate(divide="ignore"):
        dx = np.where(c > 1, width_m / np.maximum(c - 1, 1), np.inf)
        dy = np.where(r > 1, height_m / np.maximum(r - 1, 1), np.inf)
    grid = np.minimum(dx, dy)
    staggered = np.minimum(np.minimum(dx, np.hypot(dx / 2, dy)), np.where(r > 2, 2 * dy, np.inf))
    staggered = np.where((r > 1) & (c > 1), staggered, 0.0)
    capacity = (rows + 1) // 2 * cols + rows // 2 * (cols - 1)
    return np.concatenate([grid, staggered]), np.concatenate([rows * cols, capacity])


def _candidates(width_m: float, height_m: float, max_rows: int, max_cols: int
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every layout of up to ``max_rows x max_cols``, both ways round: ``(spec (L, 4), gap, capacity)``.

    ``spec`` rows are ``(kind, rows, cols, transposed)``.
    """
    rows, cols = (a.ravel() for a in np.meshgrid(np.arange(1, max_rows + 1), np.arange(1, max_cols + 1)))
    specs, gaps, caps = [], [], []
    for transposed, (w, h) in enumerate([(width_m, height_m), (height_m, width_m)]):
        gap, cap = _layouts(w, h, rows, cols)
        kind = np.repeat([0, 1], len(rows))
        specs.append(np.stack([kind, np.tile(rows, 2), np.tile(cols, 2), np.full(2 * len(rows), transposed)],
                              axis=1))
        gaps.append(gap)
        caps.append(cap)
    return np.concatenate(specs), np.concatenate(gaps), np.concatenate(caps)


def _points(spec: np.ndarray, width_m: float, height_m: float) -> np.ndarray:
    """``(capacity, 2)`` the points of one layout ``(kind, rows, cols, transposed)``."""
    kind, rows, cols, transposed = (int(x) for x in spec)
    w, h = (height_m, width_m) if transposed else (width_m, height_m)
    ys = np.linspace(0.0, h, rows) if rows > 1 else np.array([h / 2])
    points = []
    for line, y in enumerate(ys):
        if kind == 1 and line % 2:
            dx = w / (cols - 1)
            xs = dx / 2 + dx * np.arange(cols - 1)
        else:
            xs = np.linspace(0.0, w, cols) if cols > 1 else np.array([w / 2])
        points.append(np.stack([xs, np.full(len(xs), y)], axis=1))
    out = np.concatenate(points)
    return out[:, ::-1].copy() if transposed else out


@functools.lru_cache(maxsize=256)  # a pure function of three numbers, asked at every separation of targets
def max_spread_m(n_uavs: int, width_m: float, height_m: float) -> float:
    """The largest minimum distance of ``n_uavs`` points this module lays out in ``width_m x height_m``.

    The best of grids and staggered (hexagonal) layouts stretched to the area, both ways round, and for two
    UAVs the diagonal: a construction, so every fleet it accepts can be started
    (:func:`draw_apart_m`) and every set of targets separated
    (:func:`uav_swarm.planning.spacing.separate_targets`). ``inf`` for fewer than two UAVs.

    Examples:
        >>> round(max_spread_m(10, 200.0, 200.0), 1)  # 10 points in a 200 m square: 3-2-3-2 staggered
        83.3
        >>> max_spread_m(10, 12.0, 12.0)  # 10 UAVs 5 m apart fit in a 12 m square
        5.0
    """
    if n_uavs < 2:
        return math.inf
    _, gaps, caps = _candidates(width_m, height_m, n_uavs, n_uavs)
    best = float(gaps[caps >= n_uavs].max())
    return max(best, math.hypot(width_m, height_m)) if n_uavs == 2 else best


def fleet_slots_m(min_separation_m: float, width_m: float, height_m: float) -> np.ndarray:
    """``(S, 2)`` the most points of one layout of :func:`max_spread_m` at least ``min_separation_m`` apart.

    A fleet of ``n`` UAVs fits (:func:`check_fleet_fits`) exactly when ``S >= n``.

    Examples:
        >>> len(fleet_slots_m(5.0, 12.0, 12.0))  # 3-2-3-2 points, 5 m apart
        10
    """
    if min_separation_m <= 0:
        raise ValueError(f"min_separation_m = {min_separation_m:g}: allowed > 0")
    max_rows = max(2, int(2.0 * max(width_m, height_m) / min_separation_m) + 1)
    specs, gaps, caps = _candidates(width_m, height_m, max_rows, max_rows)
    caps = np.where(gaps >= min_separation_m, caps, 0)
    best = int(np.argmax(caps))
    if caps[best] < 2 and math.hypot(width_m, height_m) >= min_separation_m:  # two UAVs: the diagonal
        return np.array([[0.0, 0.0], [width_m, height_m]])
    return _points(specs[best], width_m, height_m) if caps[best] else np.zeros((0, 2))


def check_fleet_fits(n_uavs: int, min_separation_m: float, width_m: float, height_m: float, *,
                     field: str = "uav.min_separation_m") -> None:
    """Refuse a minimum separation the fleet cannot keep in its area, naming ``field``.

    The one rule of the fleet check, the env's start positions (:func:`draw_apart_m`) and the separation
    of targets (:func:`uav_swarm.planning.spacing.separate_targets`): :func:`max_spread_m`.

    Raises:
        ConfigError: ``min_separation_m`` exceeds :func:`max_spread_m` for the fleet and area.

    Examples:
        >>> try:
        ...     check_fleet_fits(10, 90.0, 200.0, 200.0)
        ... except ConfigError as error:
        ...     print(error)
        uav.min_separation_m = 90 m cannot be kept by 10 UAVs in a 200 x 200 m area: allowed 0 <= \
uav.min_separation_m <= 83.3
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
    earlier one is drawn again, so a draw that already keeps its distances costs nothing more. When
    ``max_tries`` draws do not find them (the fleet barely fits), the UAVs take ``K`` points of
    :func:`fleet_slots_m` drawn at random.

    Raises:
        ConfigError: The fleet does not fit (:func:`check_fleet_fits` at the largest required distance).

    Examples:
        >>> p = draw_apart_m(np.random.default_rng(0), 10, np.array([30.0, 30.0]), np.full((10, 10), 5.0))
        >>> bool(closest_distances_m(p) >= 5.0)
        True
    """
    area = np.asarray(area_m, dtype=np.float64)
    need = float(np.max(required_m, initial=0.0))
    check_fleet_fits(n_uavs, need, float(area[0]), float(area[1]))
    positions = rng.uniform(0.0, area, size=(n_uavs, 2))
    tries = 0
    for uav in range(1, n_uavs):
        while np.any(np.linalg.norm(positions[:uav] - positions[uav], axis=1) < required_m[uav, :uav]):
            tries += 1
            if tries > max_tries:
                slots = fleet_slots_m(need, float(area[0]), float(area[1]))
                return slots[rng.choice(len(slots), n_uavs, replace=False)]
            positions[uav] = rng.uniform(0.0, area)
    return positions


class SeparationMonitor:
    """What a run reports about separation: the closest pair, conflicts, time below the minimum, holds.

    Feed it the positions of each sample (:meth:`observe`) and the guard's holds (:meth:`count_holds`).
    A *conflict* is a pair entering below the minimum (closer now, not closer at its previous sample).
    The closest pair *in flight* counts only pairs whose UAVs are both airborne (each sample says which;
    all of them unless told): on the ground, armed before take-off, two UAVs stand at their launch spacing.

    Examples:
        >>> monitor = SeparationMonitor(5.0)
        >>> for t_s, gap_m in [(0.0, 10.0), (1.0, 4.0), (2.0, 3.0), (3.0, 8.0)]:
        ...     _ = monitor.observe(t_s, np.array([[0.0, 0.0], [gap_m, 0.0]]), airborne=[True, t_s < 2.0])
        >>> s = monitor.summary()
        >>> s["closest_m"], s["closest_pair"], s["closest_t_s"], s["conflicts"], s["time_below_min_s"]
        (3.0, [0, 1], 2.0, 1, 2.0)
        >>> s["closest_in_flight_m"], s["closest_in_flight_t_s"]
        (4.0, 1.0)
    """

    def __init__(self, min_separation_m: float, altitudes_m: np.ndarray | None = None) -> None:
        self.min_separation_m = float(min_separation_m)
        self._altitudes_m = altitudes_m
        self._closest = ClosestPair(math.inf, -1, -1)
        self._closest_t_s = math.nan
        self.closest_in_flight = ClosestPair(math.inf, -1, -1)
        """The closest pair of UAVs both airborne so far (distance ``inf`` before two flew at once)."""
        self._closest_in_flight_t_s = math.nan
        self._told_airborne = False
        self._below: np.ndarray | None = None
        self._last_t_s: float | None = None
        self.conflicts = 0
        self.time_below_min_s = 0.0
        self.holds = 0
        self.samples = 0

    def observe(self, t_s: float, positions_m: np.ndarray, ids: list[int] | None = None,
                airborne: list[bool] | np.ndarray | None = None) -> float:
        """Record one sample of (K, 2) positions at time ``t_s``; returns its closest distance (m).

        ``ids`` names the UAVs of the rows (default 0 ... K-1): a fleet whose membership changes (a lost
        vehicle) keeps its pairs apart by id. ``airborne`` (K,) says which are in flight (default: all).
        """
        p = np.asarray(positions_m, dtype=np.float64)
        names = list(range(p.shape[0])) if ids is None else list(ids)
        altitudes = None if self._altitudes_m is None else np.asarray(self._altitudes_m)[names]
        pair = closest_pair(p, altitudes)
        if pair.distance_m < self._closest.distance_m:
            self._closest = ClosestPair(pair.distance_m, names[pair.first], names[pair.second])
            self._closest_t_s = float(t_s)
        self._told_airborne |= airborne is not None
        flying = np.ones(p.shape[0], dtype=bool) if airborne is None else np.asarray(airborne, dtype=bool)
        rows = np.flatnonzero(flying)
        in_flight = pair if airborne is None else closest_pair(
            p[rows], None if altitudes is None else altitudes[rows])
        if in_flight.distance_m < self.closest_in_flight.distance_m:
            first, second = (names[rows[in_flight.first]], names[rows[in_flight.second]])
            self.closest_in_flight = ClosestPair(in_flight.distance_m, first, second)
            self._closest_in_flight_t_s = float(t_s)
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
        ``time_below_min_s``, ``holds``, ``samples`` (a closest pair is None before two UAVs were observed
        at once); when samples said which UAVs were airborne, the same of the closest pair in flight
        (``closest_in_flight_m``, ``closest_in_flight_pair``, ``closest_in_flight_t_s``).
        """
        finite = math.isfinite(self._closest.distance_m)
        flown = math.isfinite(self.closest_in_flight.distance_m)
        in_flight = self.closest_in_flight
        in_flight_keys = {
            "closest_in_flight_m": round(in_flight.distance_m, 3) if flown else None,
            "closest_in_flight_pair": [in_flight.first, in_flight.second] if flown else None,
            "closest_in_flight_t_s": self._closest_in_flight_t_s if flown else None,
        } if self._told_airborne else {}
        return {
            "min_separation_m": self.min_separation_m,
            "closest_m": round(self._closest.distance_m, 3) if finite else None,
            "closest_pair": [self._closest.first, self._closest.second] if finite else None,
            "closest_t_s": self._closest_t_s if finite else None,
            **in_flight_keys,
            "conflicts": self.conflicts,
            "time_below_min_s": round(self.time_below_min_s, 3),
            "holds": self.holds,
            "samples": self.samples,
        }
