import numpy as np
import pytest

from typed_config import ConfigError
from uav_swarm.missions.registry import build_refiner, build_task
from uav_swarm.missions.wifi.expert import CandidatePairs, PlacementSearch
from uav_swarm.missions.wifi.refine import WifiRefineConfig, refine_placement
from uav_swarm.missions.wifi.relocation import (
    adopt_by_relocation,
    placement_violation,
    relocate,
    relocation_scores,
)
from uav_swarm.missions.wifi.rules import CoverageRules, assign_users, candidate_grid, is_valid_placement

S1 = CoverageRules(radius_m=30.0, min_users=31, max_users=None, max_uavs=10, exclusive=True)
S2 = CoverageRules(radius_m=30.0, min_users=31, max_users=40, max_uavs=10, exclusive=False)
RELOCATION = WifiRefineConfig(grid_step_m=5.0, fine_radius_m=5.0, max_moves=0, relocation=True,
                              polish_radius_m=4.0, polish_step_m=1.0)


def _crowd(rng: np.random.Generator, groups: int = 6) -> np.ndarray:
    centres = rng.uniform(20.0, 180.0, size=(groups, 2))
    return np.concatenate([rng.normal(c, 6.0, size=(int(rng.integers(15, 75)), 2)) for c in centres])


def _key(users: np.ndarray, uavs: np.ndarray, rules: CoverageRules) -> tuple[int, int]:
    state = assign_users(users, uavs, rules.radius_m)
    return int(placement_violation(state.counts, rules).sum()), state.n_served


def test_scores_equal_every_relocation_applied_and_reassociated():
    rng = np.random.default_rng(1)
    candidates, _ = candidate_grid(200.0, 200.0, 10.0)
    for k in (1, 2, 5):
        users = _crowd(rng)
        uavs = rng.uniform(0.0, 200.0, size=(k, 2))
        uavs[0] = users[0]  # at least one UAV serves someone; others may be unjustified or overloaded
        pairs = CandidatePairs(users, candidates, S2)
        violation, served = relocation_scores(pairs, users, uavs, S2)
        assert violation.shape == served.shape == (k, len(pairs.candidates_m))
        for j in range(k):
            for c in range(0, len(pairs.candidates_m), 3):
                moved = np.vstack([np.delete(uavs, j, axis=0), pairs.candidates_m[c]])
                assert (violation[j, c], served[j, c]) == _key(users, moved, S2)


def test_relocation_only_improves_and_repairs_broken_proposals():
    rng = np.random.default_rng(2)
    candidates, _ = candidate_grid(200.0, 200.0, 5.0)
    for _ in range(4):
        users = _crowd(rng)
        search = PlacementSearch(users, S2, CandidatePairs(users, candidates, S2))
        proposals = rng.uniform(0.0, 200.0, size=(8, 2))
        before = _key(users, proposals, S2)
        state = adopt_by_relocation(search, proposals, max_moves=50)
        assert is_valid_placement(state, S2) and len(search.uavs_m) <= 8
        after = _key(users, search.uavs_m, S2)
        assert after[0] == 0 and (after[0], -after[1]) <= (before[0], -before[1])
        served = search.state.n_served
        assert relocate(search, max_moves=50) == 0  # adoption ends where no relocation helps
        assert search.state.n_served == served


def test_an_empty_proposal_jumps_to_the_group_it_missed():
    rng = np.random.default_rng(3)
    users = np.concatenate([rng.normal([40.0, 40.0], 3.0, size=(35, 2)),
                            rng.normal([160.0, 150.0], 3.0, size=(38, 2))])
    search = PlacementSearch(users, S2, CandidatePairs(users, candidate_grid(200.0, 200.0, 5.0)[0], S2))
    state = adopt_by_relocation(search, np.array([[40.0, 40.0], [100.0, 190.0]]), max_moves=10)
    assert len(search.uavs_m) == 2 and state.n_served == 73


def test_refinement_with_relocation_obeys_strategy_2_and_is_deterministic():
    rng = np.random.default_rng(4)
    for _ in range(3):
        users = _crowd(rng, groups=8)
        for proposals in (np.zeros((0, 2)), rng.uniform(0.0, 200.0, size=(10, 2)), users[:12]):
            placed = refine_placement(users, proposals, S2, 200.0, 200.0, RELOCATION)
            assert len(placed) <= 10 and is_valid_placement(assign_users(users, placed, 30.0), S2)
            again = refine_placement(users, proposals, S2, 200.0, 200.0, RELOCATION)
            np.testing.assert_array_equal(placed, again)


def test_relocation_serves_at_least_the_ruin_and_recreate_refinement_on_packed_crowds():
    rng = np.random.default_rng(5)
    gains = []
    for _ in range(4):
        users = _crowd(rng, groups=12)
        proposals = users[rng.choice(len(users), size=10, replace=False)]
        ruin = refine_placement(users, proposals, S2, 200.0, 200.0, WifiRefineConfig(grid_step_m=5.0))
        relocated = refine_placement(users, proposals, S2, 200.0, 200.0, RELOCATION)
        gains.append(_key(users, relocated, S2)[1] - _key(users, ruin, S2)[1])
    assert sum(gains) > 0


def test_relocation_refuses_strategy_1():
    users = _crowd(np.random.default_rng(6))
    pairs = CandidatePairs(users, candidate_grid(200.0, 200.0, 10.0)[0], S1)
    with pytest.raises(ValueError, match="strategy 2"):
        relocation_scores(pairs, users, users[:2], S1)
    with pytest.raises(ValueError, match="relocation"):
        refine_placement(users, users[:2], S1, 200.0, 200.0, RELOCATION)
    with pytest.raises(ConfigError, match=r"\[refine\] relocation"):
        build_refiner(build_task("wifi-s1"), {"relocation": True})
    assert build_refiner(build_task("wifi-s2"), {"relocation": True}).config.relocation
