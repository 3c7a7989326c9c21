"""Guards judged, repaired and solved on the user's outline in metres (Art Gallery and Fortress).

The network proposes guards on its raster; this module makes them true on the building the user gave
(:mod:`uav_swarm.missions.monitoring.outline`: witnesses, candidate lattices, visibility with a margin):

* :func:`judge`: which witnesses each guard sees, the coverage a command reports.
* :func:`repair_on_outline`: **move**: the proposals' neighbourhoods (lattice points of ``move_spacing_m``
  within ``move_radius_m`` of a proposal, and the lattice point nearest each proposal) covered as a set
  cover; **complete**: the witnesses still unseen covered from the ``lattice_m`` lattice within
  ``complete_radius_m`` of them (and, for witnesses no lattice point sees, from positions aimed at
  them); **prune** redundant guards; when guards were added, **re-solve** the cover over the guards and
  the ``move_spacing_m`` lattice within ``move_radius_m`` of them (never more guards: the guards are in
  that pool). The result sees every witness by construction, or :class:`InfeasibleCoverError` names
  the points nothing sees.
* :func:`reference_guards`: the exact reference the repair is judged against: the fewest points of a
  dense lattice (``reference_spacing_m``) seeing every witness.

Every set cover here is solved on witnesses added lazily: the cover of a subset of the witnesses is
checked against all of them and the unseen ones join the subset until none is left. The last cover is
optimal for its subset and sees every witness, so it is optimal for all of them (a subset's optimum never
exceeds the whole instance's); only the visibility of the chosen guards is ever computed against every
witness. Covers are exact (:func:`uav_swarm.missions.monitoring.setcover.small_cover`: the greedy cover
when a packing proves it minimal, else HiGHS).

Guards fly: every cover keeps them ``min_separation_m`` apart (a cover with two candidates closer than
that is re-solved with exclusion rows, :func:`uav_swarm.missions.monitoring.setcover.separated_cover`),
candidates closer than that to a guard already placed (``fixed_m``: an earlier stage's, or another
building's) are not used, and a building whose witnesses no such guards see is refused, naming the
minimum.

Examples:
    >>> from uav_swarm.missions.monitoring.outline import Outline
    >>> ell = Outline.from_rings(np.array([[0, 0], [30, 0], [30, 10], [10, 10], [10, 30], [0, 30.0]]))
    >>> len(reference_guards(ell, "interior", SightConfig(witness_spacing_m=1.0)).guards_m)
    1
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from typed_config import Config, ConfigError, param
from uav_swarm.missions.monitoring.outline import (
    Outline,
    Region,
    Witnesses,
    candidates,
    visibility,
    witnesses,
)
from uav_swarm.missions.monitoring.setcover import InfeasibleCoverError, prune_cover, small_cover

__all__ = ["SightConfig", "Placement", "judge", "repair_on_outline", "reference_guards"]

_FIRST_WITNESSES = 300
"""Witnesses, an even spread, a lazy cover starts from."""

_ADDED_WITNESSES = 300
"""Most unseen witnesses (an even spread of them) one round of a lazy cover adds."""

_AIMED_DIRECTIONS = 32
"""Directions of the rays along which positions are aimed at a witness a lattice misses."""


@dataclass(frozen=True)
class SightConfig(Config):
    """What a guard must see on the real outline, and where guards are looked for (metres)."""

    witness_spacing_m: float = param(0.5, gt=0.0, le=10.0, doc="spacing of the witnesses (grid or wall), m")
    min_clearance_m: float = param(
        0.5, ge=0.0, le=10.0, doc="a sight line keeps this far from every wall but the witness's own, m")
    standoff_m: float = param(1.0, ge=0.0, le=50.0, doc="guards keep this far from every wall, m")
    reach_m: float = param(15.0, gt=0.0, le=1000.0,
                           doc="Fortress guards stand at most this far outside the building's box, m")
    move_radius_m: float = param(10.0, ge=0.0, le=1000.0, doc="a proposal may move this far, m")
    move_spacing_m: float = param(2.0, gt=0.0, le=50.0, doc="lattice the proposals move on, m")
    lattice_m: float = param(2.0, gt=0.0, le=50.0, doc="lattice that covers what the moved proposals miss, m")
    complete_radius_m: float = param(
        20.0, gt=0.0, le=1000.0, doc="witnesses the moved proposals miss are covered from this near, m")
    reference_spacing_m: float = param(1.0, gt=0.0, le=50.0, doc="the exact reference's candidate lattice, m")
    min_separation_m: float = param(
        5.0, ge=0.0, le=1000.0, doc="guards (UAVs) keep at least this distance between them, m (0: none)")

    def check(self) -> None:
        """A guard must be able to see past the wall it stands by."""
        if self.standoff_m < self.min_clearance_m:
            raise ConfigError(f"SightConfig.standoff_m = {self.standoff_m} must be >= min_clearance_m = "
                              f"{self.min_clearance_m} (a guard nearer a wall than the margin sees nothing)")
        if self.standoff_m == 0.0:
            raise ConfigError("SightConfig.standoff_m = 0.0: allowed > 0 (a guard on a wall sees along it)")


@dataclass(frozen=True)
class Placement:
    """Guards on the real outline and what they see.

    Attributes:
        guards_m: ``(k, 2)`` guard positions, metres.
        witnesses: The witnesses judged.
        seen_by: ``(k, W)`` bool, guard ``g`` sees witness ``w``.
        n_proposals: Proposals given (0 for the reference).
        n_added: Guards added where the moved proposals left witnesses unseen.
        n_pruned: Redundant guards dropped.
    """

    guards_m: np.ndarray
    witnesses: Witnesses
    seen_by: np.ndarray
    n_proposals: int = 0
    n_added: int = 0
    n_pruned: int = 0

    @property
    def seen_fraction(self) -> float:
        """Share of the witnesses some guard sees."""
        return float(np.mean(np.any(self.seen_by, axis=0))) if len(self.witnesses) else 1.0


def _witnesses(outline: Outline, region: Region, config: SightConfig) -> Witnesses:
    """The witnesses of ``config``'s spacing, prepared for its margin."""
    points = witnesses(outline, region, config.witness_spacing_m)
    return points.prepared(outline, config.min_clearance_m, region)


def judge(outline: Outline, region: Region, guards_m: np.ndarray, config: SightConfig) -> Placement:
    """What guards at ``guards_m`` see of the real outline (witnesses at ``config.witness_spacing_m``).

    A guard outside the mission's region, or nearer a wall than ``standoff_m``, sees nothing.
    """
    guards = np.asarray(guards_m, dtype=np.float64).reshape(-1, 2)
    targets = _witnesses(outline, region, config)
    allowed = (outline.inside(guards) == (region == "interior")) & (
        outline.wall_distances(guards) >= config.standoff_m)
    seen = np.zeros((len(guards), len(targets)), dtype=bool)
    seen[allowed] = visibility(outline, guards[allowed], targets, config.min_clearance_m, region)
    return Placement(guards, targets, seen)


def _spread(index: np.ndarray, limit: int) -> np.ndarray:
    """At most ``limit`` entries of ``index``, evenly spaced."""
    if len(index) <= limit:
        return index
    return index[np.unique(np.linspace(0, len(index) - 1, limit).round().astype(np.int64))]


def _far(points_m: np.ndarray, fixed_m: np.ndarray, min_separation_m: float) -> np.ndarray:
    """``(P,)`` True where a point stands at least ``min_separation_m`` from every fixed guard."""
    if min_separation_m <= 0.0 or len(fixed_m) == 0 or len(points_m) == 0:
        return np.ones(len(points_m), dtype=bool)
    return _nearest(points_m, fixed_m)[0] >= min_separation_m


def _lazy_cover(outline: Outline, region: Region, pool: np.ndarray, targets: Witnesses, clearance: float,
                cost: np.ndarray, min_separation_m: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Fewest pool points seeing every witness the pool can see (see the module docstring).

    Returns:
        The chosen pool indices and their ``(k, W)`` visibility of every witness.
    """
    if len(pool) == 0:
        return np.zeros(0, dtype=np.int64), np.zeros((0, len(targets)), dtype=bool)
    subset = _spread(np.arange(len(targets)), _FIRST_WITNESSES)
    sees = visibility(outline, pool, targets.subset(subset), clearance, region)
    rows: dict[int, np.ndarray] = {}  # pool point -> what it sees of every witness, computed once
    while True:
        reachable = np.any(sees, axis=0)
        picks = (small_cover(sees[:, reachable], cost, pool, min_separation_m) if np.any(reachable)
                 else np.zeros(0, dtype=np.int64))
        new = [int(p) for p in picks if int(p) not in rows]
        if new:
            rows.update(zip(new, visibility(outline, pool[new], targets, clearance, region), strict=True))
        seen_by = np.array([rows[int(p)] for p in picks], dtype=bool).reshape(len(picks), len(targets))
        unseen = ~np.any(seen_by, axis=0)
        unseen[subset] = False  # those are unseen because no pool point sees them
        if not np.any(unseen):
            return picks, seen_by
        added = _spread(np.flatnonzero(unseen), _ADDED_WITNESSES)
        subset = np.concatenate([subset, added])
        more = visibility(outline, pool, targets.subset(added), clearance, region)
        sees = np.concatenate([sees, more], axis=1)


def _infeasible(outline: Outline, targets: Witnesses, blind: np.ndarray, config: SightConfig,
                region: Region) -> InfeasibleCoverError:
    """The error naming the witnesses no candidate sees, in metres."""
    where = []
    for w in np.flatnonzero(blind)[:5]:
        x, y = targets.points_m[w]
        wall = targets.walls[w, 0]
        if wall >= 0:
            ax, ay, bx, by = outline.walls_m[wall]
            where.append(f"({x:.2f}, {y:.2f}) on the wall ({ax:.2f}, {ay:.2f})-({bx:.2f}, {by:.2f})")
        else:
            where.append(f"({x:.2f}, {y:.2f})")
    place = "inside the building" if region == "interior" else "outside the building"
    return InfeasibleCoverError(
        f"{outline.name}: {int(blind.sum())} witness point(s) no guard position {place} sees with "
        f"min_clearance_m = {config.min_clearance_m} and standoff_m = {config.standoff_m} "
        f"(metres, East-North): {'; '.join(where)}{' ...' if blind.sum() > 5 else ''}")


def _nearest(points: np.ndarray, to: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each of ``points``: the distance to and index of the nearest of ``to``."""
    distance, nearest = cKDTree(to).query(points)
    return np.asarray(distance, dtype=np.float64), np.asarray(nearest, dtype=np.int64)


def _aimed(outline: Outline, region: Region, targets: Witnesses, config: SightConfig) -> np.ndarray:
    """Guard positions aimed at witnesses a lattice misses: rays in 32 directions from each, at 1-32 m.

    A witness deep in a corner or a jog of the wall is seen only from a narrow cone, which a lattice
    may not reach; points on rays from the witness itself do.
    """
    angles = np.linspace(0.0, 2 * np.pi, _AIMED_DIRECTIONS, endpoint=False)
    rays = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    reach = config.standoff_m + config.min_clearance_m + np.array([0.0, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0])
    points = targets.points_m[:, None, None, :] + reach[None, :, None, None] * rays[None, None]
    points = points.reshape(-1, 2)
    allowed = (outline.inside(points) == (region == "interior")) & (
        outline.wall_distances(points) >= config.standoff_m)
    return points[allowed]


def _cover_blind(outline: Outline, region: Region, lattice: np.ndarray, targets: Witnesses,
                 config: SightConfig, cost: np.ndarray, fixed_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Fewest positions seeing ``targets``: lattice points, plus aimed ones for what the lattice misses.

    Positions closer than the minimum separation to ``fixed_m`` (guards already placed) are not used.

    Raises:
        InfeasibleCoverError: Witnesses no lattice or aimed point sees.
    """
    minimum = config.min_separation_m
    far = _far(lattice, fixed_m, minimum)
    lattice, cost = lattice[far], cost[far]
    picks, seen_by = _lazy_cover(outline, region, lattice, targets, config.min_clearance_m, cost, minimum)
    chosen = lattice[picks]
    blind = ~np.any(seen_by, axis=0)
    if np.any(blind):
        aimed = _aimed(outline, region, targets.subset(np.flatnonzero(blind)), config)
        aimed = aimed[_far(aimed, np.concatenate([fixed_m, chosen]), minimum)]
        more, _ = _lazy_cover(outline, region, aimed, targets.subset(np.flatnonzero(blind)),
                              config.min_clearance_m, np.zeros(len(aimed)), minimum)
        chosen = np.concatenate([chosen, aimed[more]])
        seen_by = visibility(outline, chosen, targets, config.min_clearance_m, region)
        blind = ~np.any(seen_by, axis=0)
        if np.any(blind):
            kept = np.concatenate([fixed_m, chosen])
            separation = _too_close(outline, region, targets.subset(np.flatnonzero(blind)), config, kept)
            raise separation or _infeasible(outline, targets, blind, config, region)
    return chosen, seen_by


def _too_close(outline: Outline, region: Region, blind: Witnesses, config: SightConfig, kept_m: np.ndarray
               ) -> InfeasibleCoverError | None:
    """The error naming the minimum separation when only positions it excludes see ``blind``, else None."""
    minimum = config.min_separation_m
    if minimum <= 0.0 or len(kept_m) == 0:
        return None
    positions = np.concatenate([candidates(outline, region, config.lattice_m, config.standoff_m,
                                           config.reach_m), _aimed(outline, region, blind, config)])
    excluded = positions[~_far(positions, kept_m, minimum)]
    if len(excluded) == 0 or not np.any(visibility(outline, excluded, blind, config.min_clearance_m, region)):
        return None
    return InfeasibleCoverError(
        f"{outline.name}: min_separation_m = {minimum:g} is the cause: {len(blind)} witness point(s) stay "
        f"unseen, which positions closer than {minimum:g} m to the {len(kept_m)} guard(s) placed already "
        "would see (guards keep the UAVs' minimum separation); lower --min-separation-m")


def repair_on_outline(outline: Outline, region: Region, proposals_m: np.ndarray, config: SightConfig,
                      fixed_m: np.ndarray | None = None) -> Placement:
    """Guards seeing every witness of the real outline, found near the proposals (module docstring).

    Args:
        outline: The building.
        region: ``"interior"`` (Art Gallery) or ``"exterior"`` (Fortress).
        proposals_m: ``(k, 2)`` proposed positions, metres (any finite values; may be empty).
        config: Witnesses, margin, standoff, lattices and the guards' minimum separation.
        fixed_m: ``(f, 2)`` guards placed already (other buildings'): the new ones keep the minimum to them.

    Raises:
        ValueError: ``proposals_m`` is not a finite ``(k, 2)`` array.
        InfeasibleCoverError: Witnesses no lattice point sees (named in metres).
    """
    proposals = np.asarray(proposals_m, dtype=np.float64)
    proposals = proposals.reshape(0, 2) if proposals.size == 0 else proposals
    if proposals.ndim != 2 or proposals.shape[1] != 2 or not np.all(np.isfinite(proposals)):
        raise ValueError(f"proposals_m must be a finite (k, 2) array, got shape {proposals.shape}")
    targets = _witnesses(outline, region, config)
    clearance, minimum = config.min_clearance_m, config.min_separation_m
    fixed = np.zeros((0, 2)) if fixed_m is None else np.asarray(fixed_m, np.float64).reshape(-1, 2)
    lattice = candidates(outline, region, config.lattice_m, config.standoff_m, config.reach_m)
    if len(lattice) == 0:
        raise _infeasible(outline, targets, np.ones(len(targets), dtype=bool), config, region)
    chosen = np.zeros((0, 2))
    seen_by = np.zeros((0, len(targets)), dtype=bool)
    if len(proposals):
        coarse = candidates(outline, region, config.move_spacing_m, config.standoff_m, config.reach_m)
        _, snapped = _nearest(proposals, lattice)
        pool = np.concatenate([coarse, lattice[np.unique(snapped)]])
        distance, _ = _nearest(pool, proposals)
        within = distance <= max(config.move_radius_m, distance.min())
        within &= _far(pool, fixed, minimum)
        pool, distance = pool[within], distance[within]
        picks, seen_by = _lazy_cover(outline, region, pool, targets, clearance, np.rint(distance), minimum)
        chosen = pool[picks]
    unseen = np.flatnonzero(~np.any(seen_by, axis=0))
    n_added = 0
    if len(unseen):
        missing = targets.subset(unseen)
        near = _nearest(lattice, missing.points_m)[0] <= config.complete_radius_m
        cost = np.rint(_nearest(lattice[near], proposals)[0]) if len(proposals) else np.zeros(int(near.sum()))
        added, _ = _cover_blind(outline, region, lattice[near], missing, config, cost,
                                np.concatenate([fixed, chosen]))
        n_added = len(added)
        chosen = np.concatenate([chosen, added])
        seen_by = np.concatenate([seen_by, visibility(outline, added, targets, clearance, region)])
    keep = prune_cover(seen_by)
    chosen, seen_by, n_pruned = chosen[keep], seen_by[keep], len(chosen) - len(keep)
    if n_added:  # re-solve around the guards: the added ones were chosen for what the others left
        coarse = candidates(outline, region, config.move_spacing_m, config.standoff_m, config.reach_m)
        pool = np.concatenate([chosen, coarse[_nearest(coarse, chosen)[0] <= config.move_radius_m]])
        pool = pool[_far(pool, fixed, minimum)]  # the guards found stay: they keep the minimum to fixed
        cost = np.rint(_nearest(pool, proposals)[0]) if len(proposals) else np.zeros(len(pool))
        cost[:len(chosen)] = 0.0  # ties keep the guards found
        picks, again = _lazy_cover(outline, region, pool, targets, clearance, cost, minimum)
        if len(picks) < len(chosen) and np.all(np.any(again, axis=0)):
            n_pruned += len(chosen) - len(picks)
            chosen, seen_by = pool[picks], again
    return Placement(chosen, targets, seen_by, len(proposals), n_added, n_pruned)


def reference_guards(outline: Outline, region: Region, config: SightConfig,
                     fixed_m: np.ndarray | None = None) -> Placement:
    """The exact reference: fewest points of the ``reference_spacing_m`` lattice seeing every witness.

    Witnesses no lattice point sees are covered, after, by the fewest positions aimed at them (rays from
    each witness), so the reference is exact on the lattice and complete on the outline. The guards keep
    ``config.min_separation_m`` between them and to ``fixed_m`` (guards placed already).

    Raises:
        InfeasibleCoverError: Witnesses no lattice point sees (named in metres).
    """
    targets = _witnesses(outline, region, config)
    lattice = candidates(outline, region, config.reference_spacing_m, config.standoff_m, config.reach_m)
    fixed = np.zeros((0, 2)) if fixed_m is None else np.asarray(fixed_m, np.float64).reshape(-1, 2)
    chosen, seen_by = _cover_blind(outline, region, lattice, targets, config, np.zeros(len(lattice)), fixed)
    return Placement(chosen, targets, seen_by)
