"""The 802.11 expert: deterministic, separated, every UAV earns its place, it beats the paper's placement."""

from __future__ import annotations

import numpy as np
import pytest

from typed_config import ConfigError
from uav_swarm.missions.registry import build_task
from uav_swarm.missions.wifi.ieee80211_expert import (
    Ieee80211ExpertConfig,
    place_uavs_80211,
    placement_scores,
    refine_80211,
)
from uav_swarm.world.comms import evaluate_coverage
from uav_swarm.world.radio_config import RadioConfig
from uav_swarm.world.wifi.channels import plan_channels

RADIO = RadioConfig(propagation="802.11", altitude_m=10.0)
CONFIG = Ieee80211ExpertConfig(grid_step_m=20.0, polish_radius_m=5.0, polish_step_m=5.0, max_moves=5)


def _crowd(seed: int) -> np.ndarray:
    """Four dense groups of 25-40 users in a 200 m square (more than one AP can serve at 5 Mbps each)."""
    rng = np.random.default_rng(seed)
    centres = rng.uniform(30.0, 170.0, (4, 2))
    return np.vstack([rng.normal(c, 4.0, (int(rng.integers(25, 41)), 2)) for c in centres])


def _place(users: np.ndarray, strategy: int = 2, radio: RadioConfig = RADIO) -> np.ndarray:
    return place_uavs_80211(users, radio, 200.0, 200.0, strategy=strategy, max_uavs=6, min_separation_m=5.0,
                            config=CONFIG)


@pytest.mark.parametrize("seed", [3, 11])
def test_placement_is_deterministic_separated_and_inside(seed):
    users = _crowd(seed)
    first, second = _place(users), _place(users.copy())
    assert np.array_equal(first, second)
    assert 1 <= len(first) <= 6
    assert np.all((first >= 0.0) & (first <= 200.0))
    gaps = np.linalg.norm(first[:, None] - first[None], axis=2) + np.eye(len(first)) * 1e9
    assert gaps.min() >= 5.0


@pytest.mark.parametrize("seed", [3, 11])
def test_every_uav_earns_its_place(seed):
    users = _crowd(seed)
    placement = _place(users)
    heights = np.full(len(placement), 10.0)
    served, _ = placement_scores(users, placement[None], RADIO, heights, 2)
    without = np.stack([np.delete(placement, j, axis=0) for j in range(len(placement))])
    served_without, _ = placement_scores(users, without, RADIO, heights[:-1], 2)
    assert np.all(served[0] - served_without >= CONFIG.min_gain_users)


def test_scores_are_the_models_qos_with_the_channel_plan():
    users = _crowd(5)
    placement = _place(users)
    served, throughput = placement_scores(users, placement[None], RADIO, np.full(len(placement), 10.0), 2)
    coverage = evaluate_coverage(users, placement, RADIO, channels=plan_channels(placement, RADIO))
    assert served[0] == round(coverage.qos_s2 * len(users))
    assert throughput[0] == pytest.approx(coverage.mean_throughput_mbps * len(users))


@pytest.mark.parametrize("seed", [3, 11])
def test_beats_the_papers_placement_under_the_80211_radio(seed):
    users = _crowd(seed)
    paper_task = build_task("wifi-s2", {"radio": {"station_limit": "auto"}})
    paper = paper_task.expert_placement_m(users)
    heights = np.full(len(paper), 10.0)
    paper_served, _ = placement_scores(users, paper[None], RADIO, heights, 2)
    ours = _place(users)
    ours_served, _ = placement_scores(users, ours[None], RADIO, np.full(len(ours), 10.0), 2)
    assert ours_served[0] >= paper_served[0]


def test_a_channel_plan_serves_more_than_one_channel():
    users = _crowd(7)
    one_channel = RadioConfig.from_dict({"propagation": "802.11", "altitude_m": 10.0,
                                         "ieee80211": {"channels": [36]}})
    planned = _place(users)
    single = _place(users, radio=one_channel)
    served_planned, _ = placement_scores(users, planned[None], RADIO, np.full(len(planned), 10.0), 2)
    served_single, _ = placement_scores(users, single[None], one_channel, np.full(len(single), 10.0), 2)
    assert served_planned[0] > served_single[0]


def test_strategy_one_counts_a_usable_rate():
    users = _crowd(3)
    radio = RadioConfig.from_dict({"propagation": "802.11", "altitude_m": 10.0,
                                   "ieee80211": {"rate_admission": False}})
    placement = _place(users, strategy=1, radio=radio)
    coverage = evaluate_coverage(users, placement, radio, channels=plan_channels(placement, radio))
    assert coverage.qos_s1 == 1.0  # four groups within 200 m: the MCS 0 range (~80 m) reaches everyone
    assert len(placement) <= 4


def test_task_config_refuses_what_the_80211_expert_cannot_honour():
    with pytest.raises(ConfigError, match="expert.method"):
        build_task("wifi-s2", {"radio": {"propagation": "802.11", "altitude_m": 10.0},
                               "expert": {"method": "search"}})
    with pytest.raises(ConfigError, match="altitude_m"):
        build_task("wifi-s2", {"radio": {"propagation": "802.11"}})
    with pytest.raises(ValueError, match="propagation"):
        place_uavs_80211(_crowd(1), RadioConfig(), 200.0, 200.0, strategy=2, max_uavs=2, min_separation_m=5.0,
                         config=CONFIG)


def test_refinement_from_nothing_is_the_expert_and_never_loses_what_it_was_given():
    users = _crowd(3)
    expert = _place(users)
    from_nothing = refine_80211(users, np.zeros((0, 2)), RADIO, 200.0, 200.0, strategy=2, max_uavs=6,
                                min_separation_m=5.0, config=CONFIG)
    assert np.array_equal(from_nothing, expert)
    rng = np.random.default_rng(0)
    proposals = expert[:-1] + rng.normal(0.0, 8.0, expert[:-1].shape)  # one missing, the others off
    heights = np.full(len(proposals), 10.0)
    given, _ = placement_scores(users, np.clip(proposals, 0.0, 200.0)[None], RADIO, heights, 2)
    refined = refine_80211(users, proposals, RADIO, 200.0, 200.0, strategy=2, max_uavs=6,
                           min_separation_m=5.0, config=CONFIG)
    served, _ = placement_scores(users, refined[None], RADIO, np.full(len(refined), 10.0), 2)
    assert served[0] >= given[0] - CONFIG.min_gain_users  # the prune may drop a UAV worth less than that
    best, _ = placement_scores(users, expert[None], RADIO, np.full(len(expert), 10.0), 2)
    assert served[0] >= 0.9 * best[0]
