"""Repairing learned guard proposals into a placement that sees every witness (AGP and FP).

The network proposes guard positions in milliseconds but guarantees nothing; the exact expert
(:mod:`uav_swarm.missions.monitoring.guards`) guarantees full coverage with the fewest guards but builds the
whole candidate-by-witness visibility matrix and solves a set cover on it. The repair keeps the
guarantee and most of the speed by looking only where the proposals point:

1. **Snap.** Each proposal goes to the nearest candidate (a pixel centre of the mission's region:
   inside the building for the Art Gallery, strictly outside for the Fortress).
2. **Move.** The candidates within ``move_radius_px`` of a proposal (every ``move_stride_px``-th
   pixel, plus the snapped ones) are judged against a spread subset of at most
   ``move_witnesses`` witnesses; a set cover on that small instance picks the fewest of them
   seeing the subset, preferring candidates near the proposals (a greedy cover when a packing of
   witnesses proves it minimal, else the exact one). Proposals therefore move
   within the match radius, merge when one candidate does the work of two, and disappear when
   they add nothing.
3. **Complete.** The chosen guards are checked against every witness. The witnesses still unseen
   are covered by the fewest candidates that see them: candidates of the move stage's lattice first,
   every pixel centre only for witnesses no lattice point sees (the only visibility computed against
   the whole candidate set is against those few witnesses).
4. **Prune.** Guards whose witnesses are all seen by the others are dropped, the guard seeing
   the fewest first, re-checking after each drop.

The result sees every witness by construction (step 3 covers what the rest leaves, and step 4
drops only guards that leave nothing unseen); :class:`RepairResult` says what each step did.
An instance whose witnesses some pixel centre cannot see at all (possible for the Fortress,
see :func:`uav_swarm.missions.monitoring.guards.solve_guards`) raises
:class:`uav_swarm.missions.monitoring.setcover.InfeasibleCoverError`, as the expert does.

Examples:
    >>> from uav_swarm.missions.monitoring.polygons import Polygon, locate_points
    >>> from uav_swarm.missions.monitoring.guards import interior_pixels
    >>> square = Polygon(np.array([[10, 10], [30, 10], [30, 30], [10, 30]]), size_px=40)
    >>> witnesses = interior_pixels(square)
    >>> repair_guards(square, "interior", witnesses, np.array([[40.0, 40.0]])).guards_px.shape
    (1, 2)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from typed_config import Config, param
from uav_swarm.missions.monitoring.polygons import Polygon, locate_points
from uav_swarm.missions.monitoring.setcover import InfeasibleCoverError, prune_cover, small_cover
from uav_swarm.missions.monitoring.visibility import Region, visibility_matrix

__all__ = ["RepairConfig", "RepairResult", "repair_guards"]

_FAR_COST = 1000.0
"""Tie-break cost of a candidate when there are no proposals (costs are pixels to the nearest proposal)."""


@dataclass(frozen=True)
class RepairConfig(Config):
    """Settings of the guard repair (lengths in raster pixels)."""

    move_radius_px: float = param(
        6.4, ge=0.0, le=64.0, doc="a proposal may move this far (the metrics' match radius by default)")
    move_stride_px: int = param(2, ge=1, le=16, doc="the move stage tries every this-many-th pixel centre")
    move_witnesses: int = param(
        300, ge=1, le=100_000, doc="witnesses (an even spread) the move stage judges candidates against")


@dataclass(frozen=True)
class RepairResult:
    """A repaired placement and what each step did.

    Attributes:
        guards_px: ``(k, 2)`` float64 guard positions ``(x, y)`` on pixel centres, sorted by row then column.
        n_proposals: Proposals given.
        n_moved: Guards of the move stage (step 2) that are not where a proposal snapped.
        n_added: Guards added to cover the witnesses left unseen (step 3).
        n_pruned: Redundant guards dropped (step 4).
    """

    guards_px: np.ndarray
    n_proposals: int
    n_moved: int
    n_added: int
    n_pruned: int


def _candidates(polygon: Polygon, region: Region) -> tuple[np.ndarray, np.ndarray]:
    """``(G, 2)`` pixel centres ``(x, y)`` allowed to hold a guard (row-major), and their location codes."""
    codes = polygon.pixel_locations()
    rows, cols = np.nonzero(codes >= 0 if region == "interior" else codes < 0)
    return np.stack([cols, rows], axis=1).astype(np.float64), codes[rows, cols]


def _spread(count: int, limit: int) -> np.ndarray:
    """At most ``limit`` evenly spaced indices into ``range(count)``."""
    if count <= limit:
        return np.arange(count)
    return np.unique(np.linspace(0, count - 1, limit).round().astype(np.int64))


def repair_guards(
    polygon: Polygon,
    region: Region,
    witnesses_px: np.ndarray,
    proposals_px: np.ndarray,
    config: RepairConfig | None = None,
) -> RepairResult:
    """Turn proposals into guards that see every witness (see the module docstring).

    Args:
        polygon: The building.
        region: ``"interior"`` (Art Gallery: guards inside) or ``"exterior"`` (Fortress: outside).
        witnesses_px: ``(W, 2)`` the points that must be seen, in the closed region.
        proposals_px: ``(k, 2)`` proposed positions ``(x, y)`` (any finite floats; may be empty).
        config: Radii and effort; defaults to ``RepairConfig()``.

    Returns:
        The repaired placement.

    Raises:
        ValueError: ``proposals_px`` is not a finite ``(k, 2)`` array, or the region has no pixel centre.
        uav_swarm.missions.monitoring.setcover.InfeasibleCoverError: A witness no candidate sees.
    """
    config = config or RepairConfig()
    proposals = np.asarray(proposals_px, dtype=np.float64)
    if proposals.size == 0:
        proposals = proposals.reshape(0, 2)
    if proposals.ndim != 2 or proposals.shape[1] != 2 or not np.all(np.isfinite(proposals)):
        raise ValueError(f"proposals_px must be a finite (k, 2) array, got shape {proposals.shape}")
    witnesses = np.asarray(witnesses_px, dtype=np.float64).reshape(-1, 2)
    candidates, candidate_codes = _candidates(polygon, region)
    if len(candidates) == 0:
        raise ValueError(f"the building leaves no pixel centre in the {region} region for a guard")
    witness_codes = locate_points(witnesses, polygon.vertices_px)
    if np.any(witness_codes == (-1 if region == "interior" else 1)):
        raise ValueError(f"witnesses_px must lie in the closed {region} region of the polygon")

    def sees(rows: np.ndarray, columns: np.ndarray | slice = slice(None)) -> np.ndarray:
        """Visibility of candidates ``rows`` to witnesses ``columns`` (locations known: not re-checked)."""
        return visibility_matrix(polygon, candidates[rows], witnesses[columns], region,
                                 guard_codes=candidate_codes[rows], witness_codes=witness_codes[columns])

    # 1. snap; 2. move within the radius against a spread of witnesses.
    to_proposals = np.full(len(candidates), np.inf)
    snapped = np.zeros(0, dtype=np.int64)
    if len(proposals):
        d2 = ((candidates[:, None, :] - proposals[None, :, :]) ** 2).sum(axis=2)  # (G, k)
        snapped = np.unique(np.argmin(d2, axis=0))
        to_proposals = np.sqrt(d2.min(axis=1))
    on_stride = np.all(candidates % config.move_stride_px == 0, axis=1)
    near = np.flatnonzero((to_proposals <= config.move_radius_px) & on_stride)
    pool = np.union1d(near, snapped)
    chosen = np.zeros(0, dtype=np.int64)
    seen_by = np.zeros((0, len(witnesses)), dtype=bool)
    if len(pool):
        spread = _spread(len(witnesses), config.move_witnesses)
        pool_sees = sees(pool, spread)
        reachable = np.any(pool_sees, axis=0)
        if np.any(reachable):
            picks = small_cover(pool_sees[:, reachable], np.rint(to_proposals[pool]))
            chosen = pool[picks]
            complete = len(spread) == len(witnesses)  # the judged witnesses were all of them
            seen_by = pool_sees[picks] if complete else sees(chosen)
    n_moved = int(np.count_nonzero(~np.isin(chosen, snapped)))

    # 3. complete: cover what is still unseen with the candidates that see it.
    unseen = ~np.any(seen_by, axis=0)
    n_added = 0
    if np.any(unseen):
        missing = np.flatnonzero(unseen)
        lattice = np.flatnonzero(on_stride)  # the lattice first; every candidate only where it sees nothing
        sees_unseen = np.zeros((len(candidates), len(missing)), dtype=bool)
        sees_unseen[lattice] = sees(lattice, missing)
        blind = ~np.any(sees_unseen, axis=0)
        if np.any(blind):
            others = np.flatnonzero(~on_stride)
            sees_unseen[np.ix_(others, np.flatnonzero(blind))] = sees(others, missing[blind])
            blind = ~np.any(sees_unseen, axis=0)
        if np.any(blind):
            raise InfeasibleCoverError(
                f"{np.count_nonzero(blind)} witness(es) seen by no pixel centre of the {region} region "
                f"(first: {tuple(witnesses[missing[np.argmax(blind)]])})")
        useful = np.flatnonzero(np.any(sees_unseen, axis=1))
        cost = np.rint(to_proposals[useful]).clip(max=_FAR_COST)
        added = useful[small_cover(sees_unseen[useful], cost)]
        n_added = len(added)
        chosen = np.concatenate([chosen, added])
        seen_by = np.concatenate([seen_by, sees(added)])

    # 4. prune.
    keep = prune_cover(seen_by)
    guards = candidates[chosen[keep]]
    guards = guards[np.lexsort((guards[:, 0], guards[:, 1]))]
    return RepairResult(guards, len(proposals), n_moved, n_added, len(chosen) - len(keep))
