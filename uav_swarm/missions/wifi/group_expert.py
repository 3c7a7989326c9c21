"""The strategy-2 expert by groups: a placement that changes little when the crowd changes little.

The search expert (:mod:`uav_swarm.missions.wifi.expert`) compares whole users served per UAV, so a
pedestrian crossing a coverage boundary flips its choices, and it packs UAVs to the knife-edge of
the rules (exactly 40 users, users at the edge of range), so any motion breaks its placements. This
expert builds the placement from the crowd's walking groups instead:

1. **Groups** (:func:`find_groups`): users closer than ``link_m`` belong to one group (connected
   components); a social-force group walks together, so its members stay together.
2. **Service units** (:func:`service_units`): ways to serve one group or two neighbouring groups,
   each with its UAVs and the users they serve:

   - *whole*: one UAV at the centre of the users' smallest enclosing circle;
   - *split*: ``k >= 2`` UAVs on the users' principal axis, placed so that their bisectors cut the
     users into parts of equal size (a large group, or two groups side by side);
   - *cut*: one UAV slid along the principal axis from either end until it serves as many users as
     the cap allows (a group too large for one UAV and too small for two).

   Every unit keeps **margins**: a UAV's load counts every user within ``radius + range_margin_m``
   (users about to walk in), and must stay within the cap; a unit is kept only when every UAV
   serves at least ``min_users`` users.
3. **Selection**: the units that serve the most users with at most ``max_uavs`` UAVs, no user
   within ``radius + range_margin_m`` of two chosen units (so association is what each unit
   planned), solved exactly as a small integer program (HiGHS). A smooth second term (how deep
   inside range the served users are) breaks ties, so that equal counts do not flip the choice.
   The UAVs keep ``rules.min_separation_m`` apart: within a split by construction, between units by
   exclusion rows of the program (two units with UAVs closer than the minimum are never both chosen).

Every step is a continuous function of the users' positions except where a count changes, and the
units carry margins, so 5 cm of jitter rarely changes the placement, and a placement held fixed
keeps its users while the groups walk. The result obeys the strategy-2 rules exactly
(:func:`uav_swarm.missions.wifi.rules.is_valid_placement`), checked before it is returned.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy.optimize import Bounds, LinearConstraint, milp
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from typed_config import Config, param
from uav_swarm.missions.wifi.rules import CoverageRules, assign_users, is_valid_placement

__all__ = ["GroupExpertConfig", "ServiceUnit", "find_groups", "service_units", "place_uavs_by_groups"]


@dataclass(frozen=True)
class GroupExpertConfig(Config):
    """Settings of the group expert (strategy 2)."""

    link_m: float = param(3.0, gt=0.0, le=50.0, doc="users closer than this belong to one group, metres")
    range_margin_m: float = param(
        1.0, ge=0.0, le=20.0, doc="a UAV's load counts every user within radius + this, metres")
    pair_gap_m: float = param(
        60.0, ge=0.0, le=500.0, doc="two groups form a unit when their centroids are at most this apart")
    cut_step_m: float = param(0.25, gt=0.0, le=5.0, doc="resolution of the cut UAV's slide, metres")
    horizon_s: float = param(
        1.0, ge=0.0, le=30.0, doc="loads and service are checked on the crowd predicted this far ahead, s")
    horizon_steps: int = param(2, ge=1, le=30, doc="instants checked in the horizon (besides now)")
    fallback_weight: float = param(
        0.8, ge=0.0, le=1.0, doc="value of a user served by a unit that holds now only (0: none such)")
    axes: Literal["both", "walk", "shape"] = param(
        "both", doc="directions to split and cut along: the group's walk, its shape, or both")
    soft_edge_m: float = param(
        1.0, gt=0.0, le=10.0, doc="a unit's value counts users within radius +- this on a linear ramp, m")
    fallback_horizon_s: float = param(
        0.5, ge=0.0, le=30.0, doc="the horizon of the fallback units (those valued fallback_weight), s")
    fallback_margin_m: float = param(0.5, ge=0.0, le=20.0, doc="the range margin of the fallback units, m")
    tie_weight: float = param(
        0.01, ge=0.0, le=0.5, doc="weight of the smooth tie-break (served users' depth in range)")



@dataclass(frozen=True)
class ServiceUnit:
    """One way to serve some users.

    Attributes:
        kind: ``"whole"``, ``"split"`` or ``"cut"``.
        uavs_m: ``(k, 2)`` UAV positions, metres.
        served: ``(S,)`` indices of the users it serves now.
        touched: ``(T,)`` indices of every user within ``radius + range_margin_m`` of its UAVs at some
            time of the horizon.
        value: Users it serves (counted with soft range edges), averaged over the horizon.
        depth: Mean of ``1 - d / radius`` over the served users (the tie-break).
    """

    kind: str
    uavs_m: np.ndarray
    served: np.ndarray
    touched: np.ndarray
    value: float
    depth: float


def find_groups(users_m: np.ndarray, link_m: float) -> np.ndarray:
    """``(N,)`` group label of every user: connected components of the ``link_m`` neighbour graph."""
    n = len(users_m)
    if n == 0:
        return np.zeros(0, np.int64)
    pairs = cKDTree(users_m).query_pairs(link_m, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    return connected_components(graph, directed=False)[1].astype(np.int64)


def _enclosing_centre(points: np.ndarray, iterations: int = 60) -> np.ndarray:
    """Centre of (nearly) the smallest circle around ``points`` (Badoiu-Clarkson iterations)."""
    centre = points.mean(axis=0)
    for i in range(1, iterations + 1):
        far = points[np.argmax(((points - centre) ** 2).sum(axis=1))]
        centre = centre + (far - centre) / (i + 1)
    return centre


def _principal_axis(points: np.ndarray) -> np.ndarray:
    """Unit vector of the largest spread of ``points`` (x axis when they have no spread)."""
    centred = points - points.mean(axis=0)
    values, vectors = np.linalg.eigh(centred.T @ centred)
    axis = vectors[:, int(np.argmax(values))]
    return axis / max(np.linalg.norm(axis), 1e-12)


def _line_counts(points: np.ndarray, origin: np.ndarray, axis: np.ndarray, ts: np.ndarray,
                 radius_m: float) -> np.ndarray:
    """``(T,)`` number of ``points`` within ``radius_m`` of ``origin + t * axis`` for each ``t`` in ``ts``.

    A point at along-axis offset ``s`` and distance ``h`` from the line is within the radius while
    ``|t - s| <= sqrt(radius^2 - h^2)``: the counts are those of intervals containing ``t``.
    """
    offset = points - origin
    along = offset @ axis
    across2 = (offset ** 2).sum(axis=1) - along ** 2
    near = across2 <= radius_m ** 2
    half = np.sqrt(np.maximum(radius_m ** 2 - across2[near], 0.0))
    starts = np.sort(along[near] - half)
    ends = np.sort(along[near] + half)
    return np.searchsorted(starts, ts, side="right") - np.searchsorted(ends, ts, side="left")


def _mirrored_positions(cuts: np.ndarray, natural: np.ndarray, min_gap: float, reach: float) -> np.ndarray:
    """``k = len(cuts) + 1`` increasing positions whose midpoints are the cuts.

    Each position mirrors the previous one across a cut, so the first position fixes all. It is
    chosen, on a fine grid within ``reach`` before the first cut, so that the gaps between
    neighbours are closest to the ``natural`` ones (the parts' centroid gaps) while none is below
    ``min_gap``; where no choice keeps ``min_gap``, the smallest gap is made largest.
    """
    signs = (-1.0) ** np.arange(len(cuts))
    offsets = 2.0 * np.cumsum(signs * cuts) * signs  # position i+1 = offsets[i] + (-1)^(i+1) * first
    candidates = cuts[0] - np.linspace(0.0, reach, 241)
    positions = np.concatenate([candidates[:, None], offsets[None, :] - signs[None, :] * candidates[:, None]],
                               axis=1)
    gaps = np.diff(positions, axis=1)
    smallest = gaps.min(axis=1)
    if np.max(smallest) < min_gap:
        return positions[int(np.argmax(smallest))]
    deviation = np.where(smallest >= min_gap, ((gaps - natural[None, :]) ** 2).sum(axis=1), np.inf)
    return positions[int(np.argmin(deviation))]


class _UnitBuilder:
    """Builds and checks units against the whole crowd over the planning horizon (margins, rules)."""

    def __init__(self, users_m: np.ndarray, velocities_m_s: np.ndarray, rules: CoverageRules,
                 config: GroupExpertConfig, robust: bool = True) -> None:
        self.users_m = users_m
        self.velocities_m_s = velocities_m_s
        self.rules = rules
        self.config = config
        horizon_s, steps = ((config.horizon_s, config.horizon_steps) if robust
                            else (config.fallback_horizon_s, 1))
        self.times_s = np.linspace(0.0, horizon_s, steps + 1) if horizon_s > 0 else np.zeros(1)
        self.predicted = [users_m + velocities_m_s * t for t in self.times_s]
        self.trees = [cKDTree(p) for p in self.predicted]
        self.reach_m = rules.radius_m + (config.range_margin_m if robust else config.fallback_margin_m)
        self.weight = 1.0 if robust else config.fallback_weight

    def unit(self, kind: str, uavs_m: np.ndarray) -> ServiceUnit | None:
        """The unit of these UAVs, or None when a load or a justification breaks the rules in the horizon."""
        rules = self.rules
        touched_sets, served_mean = [], np.zeros(len(uavs_m))
        served_now, depth_now = np.zeros(0, np.int64), 0.0  # set at step 0
        for step, (tree, users) in enumerate(zip(self.trees, self.predicted, strict=True)):
            near = np.unique(np.concatenate(
                [np.asarray(tree.query_ball_point(p, self.reach_m), np.int64) for p in uavs_m]))
            if len(near) == 0:
                return None
            d2 = ((users[near][:, None, :] - uavs_m[None, :, :]) ** 2).sum(-1)
            owner = np.argmin(d2, axis=1)
            best = d2[np.arange(len(near)), owner]
            if np.any(np.bincount(owner, minlength=len(uavs_m)) > rules.cap):
                return None
            inside = best <= rules.radius_m ** 2
            counts = np.bincount(owner[inside], minlength=len(uavs_m))
            soft = np.clip((rules.radius_m + self.config.soft_edge_m - np.sqrt(best))
                           / (2.0 * self.config.soft_edge_m), 0.0, 1.0)
            if step == 0:
                if np.any(counts < rules.min_users):
                    return None
                served_now = near[inside]
                depth_now = float(np.mean(1.0 - np.sqrt(best[inside]) / rules.radius_m))
            served_mean += np.bincount(owner, weights=soft, minlength=len(uavs_m)) / len(self.times_s)
            touched_sets.append(near)
        return ServiceUnit(kind, uavs_m, served_now, np.unique(np.concatenate(touched_sets)),
                           self.weight * float(served_mean.sum()), depth_now)

    def whole(self, members: np.ndarray) -> ServiceUnit | None:
        """One UAV at the centre of the members' enclosing circle, halfway through the horizon."""
        middle = self.predicted[len(self.predicted) // 2]
        return self.unit("whole", _enclosing_centre(middle[members])[None])

    def axes(self, members: np.ndarray) -> list[np.ndarray]:
        """Directions to split or cut along: the principal axis, the mean walk, and their normals."""
        walk = self.velocities_m_s[members].mean(axis=0)
        if self.config.axes == "walk" and np.linalg.norm(walk) > 0.2:
            axis = walk / np.linalg.norm(walk)
            return [axis, np.array([-axis[1], axis[0]])]
        axis = _principal_axis(self.users_m[members])
        found = [axis, np.array([-axis[1], axis[0]])]
        if self.config.axes == "both" and np.linalg.norm(walk) > 0.2:
            walk = walk / np.linalg.norm(walk)
            found += [walk, np.array([-walk[1], walk[0]])]
        return found

    def split(self, members: np.ndarray, k: int, axis: np.ndarray) -> ServiceUnit | None:
        """``k`` UAVs along ``axis`` whose bisectors cut the members into equal parts."""
        points = self.users_m[members]
        centre = points.mean(axis=0)
        t = np.sort((points - centre) @ axis)
        bounds = np.linspace(0, len(t), k + 1)
        edges = bounds.astype(np.int64)
        cuts = np.array([(t[e - 1] + t[e]) / 2.0 for e in edges[1:-1]])
        centroids = np.array([t[a:b].mean() for a, b in zip(edges[:-1], edges[1:], strict=True)])
        positions = _mirrored_positions(cuts, np.diff(centroids), self.rules.min_separation_m,
                                        self.rules.radius_m)
        if np.any(np.diff(positions) < self.rules.min_separation_m):
            return None
        return self.unit("split", centre[None, :] + positions[:, None] * axis[None, :])

    def cuts(self, members: np.ndarray, axis: np.ndarray) -> list[ServiceUnit]:
        """One UAV slid along ``axis`` from each end, serving the most users the cap allows in the horizon."""
        points = self.users_m[members]
        centre = points.mean(axis=0)
        t = (points - centre) @ axis
        radius = self.rules.radius_m
        found = []
        for sign in (1.0, -1.0):
            start = sign * (float(np.max(sign * t)) + radius)
            steps = np.arange(0.0, 2.0 * radius + float(np.ptp(t)), self.config.cut_step_m)
            slide = start - sign * steps
            positions = centre[None, :] + slide[:, None] * axis[None, :]
            reach = np.max([_line_counts(users, centre, axis, slide, self.reach_m)
                            for users in self.predicted], axis=0)
            served = np.mean([_line_counts(users, centre, axis, slide, radius)
                              for users in self.predicted], axis=0)
            now = _line_counts(self.predicted[0], centre, axis, slide, radius)
            ok = (reach <= self.rules.cap) & (now >= self.rules.min_users)
            if not np.any(ok):
                continue
            best = np.flatnonzero(ok & (served >= np.max(served[ok]) - 0.5))
            gaps = np.flatnonzero(np.diff(best) > 1)
            run = best[: gaps[0] + 1] if len(gaps) else best
            unit = self.unit("cut", positions[int(run[len(run) // 2])][None])
            if unit is not None:
                found.append(unit)
        return found


def service_units(users_m: np.ndarray, rules: CoverageRules, config: GroupExpertConfig,
                  velocities_m_s: np.ndarray | None = None, robust: bool = True) -> list[ServiceUnit]:
    """Every unit (whole, split, cut) of every group and of every pair of neighbouring groups.

    ``robust`` units keep the margins over the horizon; the others hold now only, and their value is
    weighted by ``config.fallback_weight``.
    """
    velocities_m_s = np.zeros_like(users_m) if velocities_m_s is None else velocities_m_s
    labels = find_groups(users_m, config.link_m)
    n_groups = int(labels.max()) + 1 if len(labels) else 0
    members = [np.flatnonzero(labels == g) for g in range(n_groups)]
    centroids = np.array([users_m[m].mean(axis=0) for m in members]).reshape(-1, 2)
    builder = _UnitBuilder(users_m, velocities_m_s, rules, config, robust)
    sets = list(members)
    for a in range(n_groups):
        for b in range(a + 1, n_groups):
            if np.hypot(*(centroids[a] - centroids[b])) <= config.pair_gap_m:
                sets.append(np.concatenate([members[a], members[b]]))
    units: list[ServiceUnit | None] = []
    for group in sets:
        n = len(group)
        if n < rules.min_users:
            continue
        if n <= rules.cap:
            units.append(builder.whole(group))
        for axis in builder.axes(group):
            for k in range(2, min(rules.max_uavs, n // rules.min_users) + 1):
                if n <= k * rules.cap:
                    units.append(builder.split(group, k, axis))
            if n > rules.cap:
                units.extend(builder.cuts(group, axis))
    return [u for u in units if u is not None]


def _clashes(units: list[ServiceUnit], min_separation_m: float) -> np.ndarray:
    """``(P, 2)`` pairs of units with two UAVs closer than ``min_separation_m`` (never both chosen)."""
    if min_separation_m <= 0.0 or len(units) < 2:
        return np.zeros((0, 2), np.int64)
    owner = np.repeat(np.arange(len(units)), [len(u.uavs_m) for u in units])
    near = cKDTree(np.vstack([u.uavs_m for u in units])).query_pairs(
        min_separation_m * (1.0 - 1e-12), output_type="ndarray")
    pairs = np.sort(owner[near], axis=1) if len(near) else np.zeros((0, 2), np.int64)
    pairs = pairs[pairs[:, 0] != pairs[:, 1]]
    return np.unique(pairs, axis=0) if len(pairs) else np.zeros((0, 2), np.int64)


def _select(units: list[ServiceUnit], n_users: int, rules: CoverageRules, tie_weight: float) -> list[int]:
    """The units serving the most users within the UAV budget, no user touched twice (HiGHS)."""
    m = len(units)
    k = np.array([len(u.uavs_m) for u in units], dtype=np.float64)
    value = np.array([u.value + tie_weight * u.depth for u in units]) - k / (rules.max_uavs + 1.0) * 0.5
    rows = np.concatenate([u.touched for u in units])
    cols = np.repeat(np.arange(m), [len(u.touched) for u in units])
    touch = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n_users, m)).tocsr()
    used = np.diff(touch.indptr) > 1  # users that two or more units touch
    constraints = [LinearConstraint(k[None, :], 0, rules.max_uavs)]
    if np.any(used):
        constraints.append(LinearConstraint(touch[used], 0, 1))
    clash = _clashes(units, rules.min_separation_m)
    if len(clash):
        rows = np.repeat(np.arange(len(clash)), 2)
        pairs = coo_matrix((np.ones(len(rows)), (rows, clash.ravel())), shape=(len(clash), m))
        constraints.append(LinearConstraint(pairs.tocsr(), 0, 1))
    result = milp(-value, constraints=constraints, integrality=np.ones(m), bounds=Bounds(0, 1),
                  options={"time_limit": 5.0})
    if result.x is None:
        return []
    return [int(i) for i in np.flatnonzero(result.x > 0.5)]


def place_uavs_by_groups(users_m: np.ndarray, rules: CoverageRules, config: GroupExpertConfig,
                         velocities_m_s: np.ndarray | None = None) -> np.ndarray:
    """The group expert's placement for one crowd (see the module docstring).

    Args:
        users_m: ``(N, 2)`` user positions, metres.
        rules: Strategy-2 constraints (radius, per-UAV load bounds, UAV budget).
        config: The expert's settings.
        velocities_m_s: ``(N, 2)`` user velocities (default: at rest); loads and service are
            checked on the crowd they predict over ``config.horizon_s``.

    Returns:
        ``(k, 2)`` float64 UAV positions in metres, ``0 <= k <= rules.max_uavs``, sorted by ``(y, x)``;
        every UAV serves between ``min_users`` and ``max_users`` users; every pair stands at least
        ``rules.min_separation_m`` apart.

    Raises:
        ValueError: ``users_m`` is not a finite ``(N, 2)`` array, or ``rules`` are strategy 1's.
    """
    users_m = np.asarray(users_m, dtype=np.float64)
    if users_m.ndim != 2 or users_m.shape[1] != 2 or not np.all(np.isfinite(users_m)):
        raise ValueError(f"users_m must be a finite (N, 2) array, got shape {users_m.shape}")
    if rules.exclusive:
        raise ValueError("the group expert solves strategy 2 (rules.exclusive = False)")
    if len(users_m) < rules.min_users or rules.max_uavs == 0:
        return np.zeros((0, 2))
    units = service_units(users_m, rules, config, velocities_m_s)
    if config.fallback_weight > 0.0:
        units += service_units(users_m, rules, config, velocities_m_s, robust=False)
    if not units:
        return np.zeros((0, 2))
    chosen = _select(units, len(users_m), rules, config.tie_weight)
    uavs_m = np.vstack([units[i].uavs_m for i in chosen]) if chosen else np.zeros((0, 2))
    while len(uavs_m) and not is_valid_placement(assign_users(users_m, uavs_m, rules.radius_m), rules):
        state = assign_users(users_m, uavs_m, rules.radius_m)  # margins make this rare: drop the worst UAV
        bad = (state.counts < rules.min_users) | (state.counts > rules.cap)
        uavs_m = np.delete(uavs_m, int(np.flatnonzero(bad)[0]) if np.any(bad) else len(uavs_m) - 1, axis=0)
    return uavs_m[np.lexsort((uavs_m[:, 0], uavs_m[:, 1]))] if len(uavs_m) else np.zeros((0, 2))
