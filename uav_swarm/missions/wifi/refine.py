"""Refining learned Wi-Fi placements on the real crowd (strategies 1 and 2).

The network sees a density raster and proposes UAV positions; it knows neither where each
pedestrian stands nor the missions' rules, so its placements may leave users out, break the
"more than 30 users per UAV" rule or, under strategy 2, load a UAV with more than 40 users.
:func:`refine_placement` starts from the proposals and runs the expert's own moves
(:class:`uav_swarm.missions.wifi.expert.PlacementSearch`), bounded, on the real positions:

1. **Adopt** the proposals, made valid: unjustified UAVs are **dropped** (the least justified
   first) and overloaded ones relieved by adding a UAV beside them (a **split**).
2. **Add** UAVs greedily while one newly covers users and the placement stays valid.
3. **Ruin and recreate**, at most ``max_moves`` improving moves: remove one UAV or two
   interacting ones and refill nearby (a **merge** when one UAV does the work of two, a **split**
   when two do better than one, a **move** otherwise).
4. **Centre** each UAV on the users it serves when that loses nobody (a **move**).

With ``relocation`` (strategy 2, ``configs/tasks/wifi-s2.toml``) the search moves single UAVs, each
move the best of every UAV moved to every candidate (:mod:`uav_swarm.missions.wifi.relocation`):

1. **Adopt** the proposals, repaired by relocation (an unjustified UAV jumps to users nobody serves, an
   overloaded one shifts until it serves at most 40); a UAV is dropped only when no relocation repairs.
2. **Add** UAVs greedily, relocating after each round; when none can be added at once, **insert** one
   where most users are uncovered and let relocations of its neighbours make room (``insertion_tries``
   places), kept only when the placement ends valid and serves more users.
3. **Polish**: relocations on a grid of ``polish_step_m`` within ``polish_radius_m`` of each UAV.

Ruin and recreate (``max_moves``; none in the shipped S2 settings) runs between 2 and 3, the centring
after 3.

Candidates for additions come from a grid of ``grid_step_m`` (10 m by default, four times the
expert's step, which is what makes the refinement cheap), plus, within ``fine_radius_m`` of each
proposal, a grid of ``fine_step_m`` (strategy 2 splits groups between UAVs and needs the finer
positions: ``configs/tasks/wifi-s2.toml``); the centring makes the final positions continuous.
Greedy fills try ``branching`` separated first candidates, as the expert does.
Every step keeps the UAVs ``rules.min_separation_m`` apart (a proposal closer than that to a better
one is dropped on adoption; additions, relocations and centring moves that come that close are not
feasible). Everything is deterministic, and the result always obeys the strategy's rules.

Examples:
    >>> from uav_swarm.missions.wifi.rules import CoverageRules
    >>> rules = CoverageRules(radius_m=30.0, min_users=31, max_users=None, max_uavs=10, exclusive=True)
    >>> users = np.random.default_rng(0).normal(100.0, 5.0, size=(60, 2))
    >>> refine_placement(users, np.array([[20.0, 20.0]]), rules, 200.0, 200.0).shape
    (1, 2)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from typed_config import Config, ConfigError, param
from uav_swarm.missions.wifi.capacitated import complete_capacitated
from uav_swarm.missions.wifi.expert import CandidatePairs, PlacementSearch
from uav_swarm.missions.wifi.relocation import adopt_by_relocation, insert_by_relocation, relocate
from uav_swarm.missions.wifi.rules import CoverageRules, candidate_grid

__all__ = ["WifiRefineConfig", "refine_placement", "strategy_refinement"]

_ADD_RELOCATE_ROUNDS = 4  # rounds of (greedy additions, relocations) before polishing


@dataclass(frozen=True)
class WifiRefineConfig(Config):
    """Settings of the Wi-Fi refinement."""

    grid_step_m: float = param(
        10.0, gt=0.0, le=50.0, doc="spacing of the grid UAVs may be added from, metres")
    fine_step_m: float = param(
        2.5, gt=0.0, le=50.0, doc="spacing of the finer grid around each proposal, metres")
    fine_radius_m: float = param(
        0.0, ge=0.0, le=100.0, doc="the finer grid covers this radius around each proposal (0: none), metres")
    max_moves: int = param(2, ge=0, le=100, doc="improving ruin-and-recreate moves allowed (0: none)")
    branching: int = param(
        3, ge=1, le=50, doc="greedy fills try this many separated first candidates and keep the best")
    centre_passes: int = param(3, ge=0, le=100, doc="passes centring each UAV on the users it serves")
    relocation: bool = param(
        False, doc="strategy 2 only: adopt, repair and improve by relocating single UAVs (wifi_relocation)")
    max_relocations: int = param(
        50, ge=0, le=1000, doc="relocations allowed per pass (each the best of all UAVs x candidates)")
    insertion_tries: int = param(
        0, ge=0, le=50, doc="strategy 2 with relocation: places tried for one more UAV whose neighbours "
        "then make room by relocation (0: none)")
    polish_radius_m: float = param(
        0.0, ge=0.0, le=30.0, doc="strategy 2 with relocation: a last relocation pass on a finer grid within "
        "this radius of each UAV (0: none), metres")
    polish_step_m: float = param(1.0, gt=0.0, le=10.0, doc="spacing of the polishing grid, metres")

    def check_rules(self, rules: CoverageRules, where: str) -> None:
        """Refuse ``relocation`` under strategy 1's rules; ``where`` names the table in the message.

        Raises:
            ConfigError: ``relocation`` with exclusive coverage (strategy 1).
        """
        if self.relocation and rules.exclusive:
            raise ConfigError(f"{where} relocation = true is for strategy 2 (users a UAV serves); strategy 1 "
                              "counts the users a UAV alone covers: allowed relocation = false")


def strategy_refinement(strategy: int) -> WifiRefineConfig:
    """The refinement settings that come with a strategy when none are given.

    Strategy 1: ``WifiRefineConfig()``. Strategy 2: relocation on a 5 m grid plus 2.5 m within 5 m
    of each proposal, two insertion places and a 1 m polish within 3 m (the settings chosen on
    120 tuning crowds, README "refinement"; also ``configs/tasks/wifi-s2.toml``'s ``[refine]``):
    strategy 1's search keeps 73.6 % of the strategy-2 expert's QoS, these 100.3 %.
    """
    if strategy == 2:
        return WifiRefineConfig(grid_step_m=5.0, fine_step_m=2.5, fine_radius_m=5.0, max_moves=0, branching=1,
                                centre_passes=3, relocation=True, max_relocations=50, insertion_tries=2,
                                polish_radius_m=3.0, polish_step_m=1.0)
    return WifiRefineConfig()


def refine_placement(
    users_m: np.ndarray,
    proposals_m: np.ndarray,
    rules: CoverageRules,
    width_m: float,
    height_m: float,
    config: WifiRefineConfig | None = None,
) -> np.ndarray:
    """Refine proposed UAV positions on the real crowd (see the module docstring).

    Args:
        users_m: ``(N, 2)`` user positions, metres.
        proposals_m: ``(k, 2)`` proposed UAV positions, metres (may be empty).
        rules: The strategy's constraints.
        width_m: Area width (x extent), metres.
        height_m: Area height (y extent), metres.
        config: Search effort; defaults to ``WifiRefineConfig()``.

    Returns:
        ``(k', 2)`` float64 UAV positions in metres, ``0 <= k' <= rules.max_uavs``, sorted by
        ``(y, x)``, obeying ``rules`` (every pair at least ``rules.min_separation_m`` apart).

    Raises:
        ValueError: ``users_m`` or ``proposals_m`` is not a finite ``(n, 2)`` array.
        ConfigError: ``config.relocation`` with strategy 1's rules (a ``ValueError`` too).
    """
    config = config or WifiRefineConfig()
    config.check_rules(rules, "WifiRefineConfig:")
    arrays = []
    for name, value in (("users_m", users_m), ("proposals_m", proposals_m)):
        array = np.asarray(value, dtype=np.float64)
        if array.size == 0:
            array = array.reshape(0, 2)
        if array.ndim != 2 or array.shape[1] != 2 or not np.all(np.isfinite(array)):
            raise ValueError(f"{name} must be a finite (n, 2) array, got shape {array.shape}")
        arrays.append(array)
    users, proposals = arrays
    if len(users) < rules.min_users or rules.max_uavs == 0:
        return np.zeros((0, 2))
    proposals = np.clip(proposals, 0.0, [width_m, height_m])
    candidates, _ = candidate_grid(width_m, height_m, config.grid_step_m)
    if config.fine_radius_m > 0 and len(proposals):
        fine, _ = candidate_grid(width_m, height_m, config.fine_step_m)
        distance2 = ((fine[:, None, :] - proposals[None, :, :]) ** 2).sum(axis=2).min(axis=1)
        candidates = np.concatenate([candidates, fine[distance2 <= config.fine_radius_m ** 2]])
    search = PlacementSearch(users, rules, CandidatePairs(users, candidates, rules))
    search.branching = config.branching
    if config.relocation:
        _relocation_search(search, proposals, config, width_m, height_m)
    else:
        search.adopt(proposals)
        search.greedy()
        search.ruin_and_recreate(config.max_moves)
    search.refine(config.centre_passes)
    uavs = search.uavs_m
    if rules.admission_control:  # judged by the radio's admission: complete and centre as the expert does
        return complete_capacitated(users, uavs, rules, width_m, height_m)
    return uavs[np.lexsort((uavs[:, 0], uavs[:, 1]))] if len(uavs) else np.zeros((0, 2))


def _relocation_search(
    search: PlacementSearch, proposals: np.ndarray, config: WifiRefineConfig, width_m: float, height_m: float,
) -> None:
    """Strategy 2: adopt by relocation, add UAVs (relocating after each round), ruin and recreate, polish."""
    adopt_by_relocation(search, proposals, config.max_relocations)  # ends where no relocation helps
    for _ in range(_ADD_RELOCATE_ROUNDS):
        before = len(search.uavs_m)
        search.greedy()
        if len(search.uavs_m) != before:
            relocate(search, config.max_relocations)
        elif not insert_by_relocation(search, config.max_relocations, config.insertion_tries):
            break
    search.ruin_and_recreate(config.max_moves)
    if config.polish_radius_m > 0 and len(search.uavs_m):
        reach = np.arange(-config.polish_radius_m, config.polish_radius_m + 1e-9, config.polish_step_m)
        offsets = np.stack(np.meshgrid(reach, reach), axis=-1).reshape(-1, 2)
        offsets = offsets[(offsets ** 2).sum(axis=1) <= config.polish_radius_m ** 2 + 1e-9]
        upper = np.nextafter(np.array([width_m, height_m]), 0.0)
        local = np.clip((search.uavs_m[:, None, :] + offsets[None]).reshape(-1, 2), 0.0, upper)
        search.pairs = CandidatePairs(search.users_m, local, search.rules)
        relocate(search, config.max_relocations)
