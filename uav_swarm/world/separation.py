"""Separation between UAVs: distances, the fleet's feasibility, a step guard and a run's record (pure numpy).

``[uav] min_separation_m`` is the distance no two UAVs may come closer than; ``[uav] layer_step_m`` puts
UAV ``k`` at ``alt_m + k * layer_step_m``, and distances are then 3-D: a pair whose altitudes differ by
``dz`` needs only ``sqrt(d_min^2 - dz^2)`` horizontally (nothing when ``dz >= d_min``).

**The step guard** (:func:`guard_commands`) keeps every pair apart under the kinematics of
:func:`uav_swarm.world.uav.fly_step`. Its invariant: the *braking paths* of any two UAVs (the polyline a UAV
would fly if it braked at ``max_accel_m_s2`` from now on: a ray of its stopping distance, clamped to the
area) are at least the minimum apart. A UAV's command is accepted only if the path it implies (this step's
segment, then braking from the new state) keeps the minimum to every other UAV's path: the new path of a
UAV already decided this step, the current braking path of one not yet decided (which contains whatever
that UAV does next if it brakes). A refused UAV tries its command turned by 45 and 90 degrees either way
(it routes around), then brakes, whose path lies inside its current one. By induction no two UAVs
ever come closer than the minimum, whatever the commands, provided they start apart at rest.

Examples:
    >>> import numpy as np
    >>> from uav_swarm.world.uav import UAVConfig, fly_step, waypoint_velocity
    >>> config, area = UAVConfig(min_separation_m=5.0), np.array([100.0, 100.0])
    >>> p, v = np.array([[20.0, 50.0], [80.0, 50.0]]), np.zeros((2, 2))
    >>> targets = p[::-1].copy()  # a head-on swap
    >>> closest = np.inf
    >>> for _ in range(400):
    ...     command, held = guard_commands(p, v, waypoint_velocity(p, targets, 0.1, config), 0.1, config,
    ...                                    upper_m=area)
    ...     p, v = fly_step(p, v, command, 0.1, config, area)
    ...     closest = min(closest, float(closest_distances_m(p)))
    >>> closest >= 5.0, bool(np.allclose(p, targets, atol=0.1))
    (True, True)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from typed_config import ConfigError
from uav_swarm.world.uav import UAVConfig, fly_step

__all__ = [
    "ClosestPair", "SeparationMonitor", "braking_paths", "check_fleet_fits", "closest_distances_m",
    "closest_pair", "draw_apart_m", "guard_commands", "max_spread_m", "pair_distances_m", "path_distances_m",
    "required_distances_m", "separation_penalty", "stopping_distance_m",
]

# Best known largest minimum distance of n points in a unit square (n = 2 ... 10; Schaer, Croft et al.).
_UNIT_SQUARE_SPREAD = (math.sqrt(2.0), 1.035276180, 1.0, 0.707106781, 0.600925213, 0.535898384,
                       0.517638090, 0.5, 0.421279543)
_TURNS_RAD = (0.0, math.pi / 4, -math.pi / 4, math.pi / 2, -math.pi / 2)  # the command, then around


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


def stopping_distance_m(speed_m_s: np.ndarray, max_accel_m_s2: float, dt_s: float) -> np.ndarray:
    """Distance flown while braking at ``max_accel_m_s2`` in steps of ``dt_s`` (the kinematics of fly_step).

    After step ``j`` the speed is ``s - j a dt`` (while positive) and the UAV moves that times ``dt``.

    Examples:
        >>> float(stopping_distance_m(np.array(10.0), 5.0, 0.1))  # about v^2 / 2a = 10 m
        9.5
    """
    step = max_accel_m_s2 * dt_s
    steps = np.floor(np.asarray(speed_m_s, dtype=np.float64) / step)
    return dt_s * (steps * speed_m_s - step * steps * (steps + 1.0) / 2.0)


def braking_paths(positions_m: np.ndarray, velocities_m_s: np.ndarray, dt_s: float, config: UAVConfig,
                  upper_m: np.ndarray | None = None) -> np.ndarray:
    """(..., K, 3, 2) polyline each UAV flies if it brakes from now on: start, wall hit (or end), end.

    The ray of the stopping distance, clamped to the area ``[0, upper_m]`` as fly_step clamps (a UAV that
    meets a wall slides along it, never beyond the clamped end).
    """
    p = np.asarray(positions_m, dtype=np.float64)
    v = np.asarray(velocities_m_s, dtype=np.float64)
    speed = np.hypot(v[..., 0], v[..., 1])
    reach = stopping_distance_m(speed, config.max_accel_m_s2, dt_s)
    with np.errstate(invalid="ignore", divide="ignore"):
        unit = np.where(speed[..., None] > 1e-12, v / speed[..., None], 0.0)
    end = p + unit * reach[..., None]
    if upper_m is None:
        return np.stack([p, end, end], axis=-2)
    upper = np.asarray(upper_m, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        to_wall = np.where(unit > 0, (upper - p) / unit, np.where(unit < 0, -p / unit, np.inf))
    hit = np.minimum(to_wall.min(axis=-1), reach)
    wall = p + unit * hit[..., None]
    return np.stack([p, wall, np.clip(end, 0.0, upper)], axis=-2)


def path_distances_m(paths_a: np.ndarray, paths_b: np.ndarray) -> np.ndarray:
    """(..., A, B) least distance between polylines ``paths_a`` (..., A, P, 2) and ``paths_b`` (..., B, Q, 2).

    Examples:
        >>> a = np.array([[[0.0, 0.0], [10.0, 0.0]]])
        >>> b = np.array([[[5.0, 3.0], [5.0, 9.0]], [[5.0, -1.0], [5.0, 1.0]]])
        >>> path_distances_m(a, b).tolist()
        [[3.0, 0.0]]
    """
    a0, a1 = paths_a[..., :, None, :-1, None, :], paths_a[..., :, None, 1:, None, :]
    b0, b1 = paths_b[..., None, :, None, :-1, :], paths_b[..., None, :, None, 1:, :]
    return _segment_distances(a0, a1, b0, b1).min(axis=(-2, -1))


def _segment_distances(a0: np.ndarray, a1: np.ndarray, b0: np.ndarray, b1: np.ndarray) -> np.ndarray:
    """Least distance between segments [a0, a1] and [b0, b1] (broadcast, last axis x/y)."""
    d = np.minimum(np.minimum(_point_segment(a0, b0, b1), _point_segment(a1, b0, b1)),
                   np.minimum(_point_segment(b0, a0, a1), _point_segment(b1, a0, a1)))
    crossing = ((_orientation(a0, a1, b0) * _orientation(a0, a1, b1) < 0)
                & (_orientation(b0, b1, a0) * _orientation(b0, b1, a1) < 0))
    return np.where(crossing, 0.0, d)


def _point_segment(point: np.ndarray, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    along = end - start
    length2 = np.einsum("...c,...c->...", along, along)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(length2 > 0, np.einsum("...c,...c->...", point - start, along) / length2, 0.0)
    nearest = start + np.clip(t, 0.0, 1.0)[..., None] * along
    gap = point - nearest
    return np.sqrt(np.einsum("...c,...c->...", gap, gap))


def _orientation(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    ab, ac = b - a, c - a
    return ab[..., 0] * ac[..., 1] - ab[..., 1] * ac[..., 0]


def guard_commands(positions_m: np.ndarray, velocities_m_s: np.ndarray, command_m_s: np.ndarray, dt_s: float,
                   config: UAVConfig, altitudes_m: np.ndarray | None = None, *,
                   upper_m: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Commands that keep every pair of UAVs at least ``config.min_separation_m`` apart (module docstring).

    Args:
        positions_m: (..., K, 2) positions in metres.
        velocities_m_s: (..., K, 2) velocities in m/s.
        command_m_s: (..., K, 2) the velocity commands wanted (from the waypoint controller or a policy).
        dt_s: The step the commands will be flown for (s).
        config: Flight limits and the minimum separation (0: every command passes).
        altitudes_m: (K,) the UAVs' altitudes (layers), or None for one altitude.
        upper_m: (2,) the area's upper corner, as given to fly_step (None: no border).

    Returns:
        The safe commands (..., K, 2) and ``held`` (..., K) bool: True where a UAV did not get its command
        (it was turned around a neighbour or braked). UAV ``k`` has priority over UAV ``k + 1``.
    """
    p = np.asarray(positions_m, dtype=np.float64)
    v = np.asarray(velocities_m_s, dtype=np.float64)
    wanted = np.asarray(command_m_s, dtype=np.float64)
    k = p.shape[-2]
    held: np.ndarray = np.zeros(p.shape[:-1], dtype=bool)
    if k < 2 or config.min_separation_m <= 0:
        return wanted.copy(), held
    batch = p.shape[:-2]
    p, v, wanted = (a.reshape(-1, k, 2) for a in (p, v, wanted))
    held = held.reshape(-1, k)
    area = np.full(2, np.inf) if upper_m is None else np.asarray(upper_m, dtype=np.float64)
    pairs = required_distances_m(config.min_separation_m, altitudes_m, k)
    required = np.broadcast_to(pairs, (p.shape[0], k, k))
    p_next, v_next = fly_step(p, v, wanted, dt_s, config, area)
    current = _paths(p, p, v, dt_s, config, area)  # (B, K, 4, 2): braking from now
    proposed = _paths(p, p_next, v_next, dt_s, config, area)
    # Every path lies within its reach of the UAV's position: pairs whose discs keep the gap need no geometry.
    centre = pair_distances_m(p)
    accel = config.max_accel_m_s2
    reach_now = stopping_distance_m(np.linalg.norm(v, axis=-1), accel, dt_s)
    reach_next = (np.linalg.norm(p_next - p, axis=-1)
                  + stopping_distance_m(np.linalg.norm(v_next, axis=-1), accel, dt_s))
    # A pair already closer than the minimum (a start inside it) may only keep or widen its gap.
    threshold = required.copy()
    near = centre - reach_now[..., :, None] - reach_now[..., None, :] < required
    if near.any():
        b, i, j = np.nonzero(near)
        threshold[b, i, j] = np.minimum(required[b, i, j], _pair_gaps(current, current, b, i, j) - 1e-9)
    clear = np.ones_like(near)
    for others, reach in ((proposed, reach_next), (current, reach_now)):
        near = centre - reach_next[..., :, None] - reach[..., None, :] < threshold
        if near.any():
            b, i, j = np.nonzero(near)
            clear[b, i, j] &= _pair_gaps(proposed, others, b, i, j) >= threshold[b, i, j]
    tight = ~clear.all(axis=(-2, -1))
    safe = wanted.copy()
    if tight.any():
        safe[tight], held[tight] = _sequential(p[tight], v[tight], wanted[tight], current[tight],
                                               threshold[tight], dt_s, config, area)
    return safe.reshape(*batch, k, 2), held.reshape(*batch, k)


def _pair_gaps(paths_a: np.ndarray, paths_b: np.ndarray, world: np.ndarray, first: np.ndarray,
               second: np.ndarray) -> np.ndarray:
    """(M,) least distance between ``paths_a[world, first]`` and ``paths_b[world, second]`` (polylines)."""
    a, b = paths_a[world, first], paths_b[world, second]  # (M, P, 2)
    gaps = _segment_distances(a[:, :-1, None], a[:, 1:, None], b[:, None, :-1], b[:, None, 1:])
    return gaps.min(axis=(-2, -1))


def _paths(p: np.ndarray, p_next: np.ndarray, v_next: np.ndarray, dt_s: float, config: UAVConfig,
           area: np.ndarray) -> np.ndarray:
    """(..., K, 4, 2): the segment from ``p`` to ``p_next``, then braking from ``(p_next, v_next)``."""
    return np.concatenate([p[..., None, :], braking_paths(p_next, v_next, dt_s, config, area)], axis=-2)


def _sequential(p: np.ndarray, v: np.ndarray, wanted: np.ndarray, current: np.ndarray, threshold: np.ndarray,
                dt_s: float, config: UAVConfig, area: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Decide UAV by UAV (priority = index) for the worlds where some command conflicts."""
    n_worlds, k = p.shape[:2]
    turns = np.array([[[math.cos(t), -math.sin(t)], [math.sin(t), math.cos(t)]] for t in _TURNS_RAD])
    options = np.einsum("tij,bkj->bkti", turns, wanted)  # (B, K, T, 2): the command and its turns
    options = np.concatenate([options, np.zeros((n_worlds, k, 1, 2))], axis=2)  # braking, always last
    decided = current.copy()  # (B, K, 4, 2): decided paths, current braking paths for the undecided
    safe = np.zeros_like(wanted)
    held = np.zeros((n_worlds, k), dtype=bool)
    rows = np.arange(n_worlds)
    for uav in range(k):
        here = np.repeat(p[:, uav:uav + 1], options.shape[2], axis=1)
        p_next, v_next = fly_step(here, np.repeat(v[:, uav:uav + 1], options.shape[2], axis=1),
                                  options[:, uav], dt_s, config, area)
        paths = _paths(here, p_next, v_next, dt_s, config, area)  # (B, T + 1, 4, 2)
        gaps = path_distances_m(paths, decided)  # (B, T + 1, K)
        ok = (gaps >= threshold[:, uav][:, None, :]) | (np.arange(k) == uav)
        ok = ok.all(axis=-1)
        ok[:, -1] = True
        choice = np.argmax(ok, axis=1)  # the first option that keeps every gap
        safe[:, uav] = options[rows, uav, choice]
        held[:, uav] = choice > 0
        decided[:, uav] = paths[rows, choice]
    return safe, held


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
