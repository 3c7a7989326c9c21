import numpy as np
import pytest

from typed_config import ConfigError
from uav_swarm.missions.wifi.refine import WifiRefineConfig, refine_placement
from uav_swarm.missions.wifi.rules import CoverageRules, assign_users, is_valid_placement

S1 = CoverageRules(radius_m=30.0, min_users=31, max_users=None, max_uavs=10, exclusive=True)
S2 = CoverageRules(radius_m=30.0, min_users=31, max_users=40, max_uavs=10, exclusive=False)
FINE_AND_COARSE = [WifiRefineConfig(), WifiRefineConfig(grid_step_m=5.0, fine_radius_m=15.0)]


def _crowd(seed: int) -> np.ndarray:
    """Groups of 35-90 people spread over 200 m x 200 m."""
    rng = np.random.default_rng(seed)
    centres = rng.uniform(30.0, 170.0, size=(5, 2))
    return np.concatenate([rng.normal(c, 6.0, size=(int(rng.integers(35, 90)), 2)) for c in centres])


@pytest.mark.parametrize("rules", [S1, S2], ids=["s1", "s2"])
@pytest.mark.parametrize("config", FINE_AND_COARSE,
                         ids=["coarse", "fine"])
def test_refined_placements_obey_the_strategy_whatever_the_proposals(rules, config):
    rng = np.random.default_rng(0)
    for seed in range(4):
        users = _crowd(seed)
        for proposals in (np.zeros((0, 2)), rng.uniform(0, 200, size=(10, 2)), users[:3], users[:1] + 500.0):
            placed = refine_placement(users, proposals, rules, 200.0, 200.0, config)
            assert placed.shape[1] == 2 and len(placed) <= rules.max_uavs
            state = assign_users(users, placed, rules.radius_m)
            assert is_valid_placement(state, rules)
            assert np.all((placed >= 0.0) & (placed <= 200.0))


def test_refinement_repairs_an_overloaded_uav_by_splitting_it():
    rng = np.random.default_rng(3)
    users = rng.normal(100.0, 4.0, size=(75, 2))  # one group of 75: at most 40 per UAV under strategy 2
    proposal = np.array([[100.0, 100.0]])
    assert not is_valid_placement(assign_users(users, proposal, 30.0), S2)
    placed = refine_placement(users, proposal, S2, 200.0, 200.0)
    state = assign_users(users, placed, 30.0)
    assert len(placed) == 2 and is_valid_placement(state, S2) and state.n_served >= 62


def test_refinement_drops_unjustified_uavs_and_covers_a_missed_group():
    rng = np.random.default_rng(4)
    users = np.concatenate([rng.normal([50.0, 50.0], 4.0, size=(50, 2)),
                            rng.normal([150.0, 150.0], 4.0, size=(50, 2))])
    proposals = np.array([[50.0, 50.0], [52.0, 50.0], [100.0, 190.0]])  # a duplicate and an empty spot
    placed = refine_placement(users, proposals, S1, 200.0, 200.0)
    state = assign_users(users, placed, 30.0)
    assert len(placed) == 2 and state.n_served == 100


def test_refinement_is_deterministic_and_validates_input():
    users = _crowd(7)
    proposals = np.random.default_rng(1).uniform(0, 200, size=(6, 2))
    first = refine_placement(users, proposals, S2, 200.0, 200.0)
    np.testing.assert_array_equal(first, refine_placement(users, proposals, S2, 200.0, 200.0))
    with pytest.raises(ValueError, match="proposals_m"):
        refine_placement(users, np.array([[np.nan, 0.0]]), S1, 200.0, 200.0)
    with pytest.raises(ValueError, match="users_m"):
        refine_placement(np.zeros((3, 3)), proposals, S1, 200.0, 200.0)
    with pytest.raises(ConfigError, match="grid_step_m"):
        WifiRefineConfig(grid_step_m=0.0)
    assert refine_placement(users[:10], proposals, S1, 200.0, 200.0).shape == (0, 2)  # too few to justify one
