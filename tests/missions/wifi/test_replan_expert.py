"""The expert in flight: replans warm-started from the last placement, a fresh solve only when worth it."""

import numpy as np
import pytest

from typed_config import ConfigError
from uav_swarm.missions.wifi.replan_expert import ReplanExpert, ReplanExpertConfig, travel_m
from uav_swarm.missions.wifi.rules import assign_users, is_valid_placement
from uav_swarm.missions.wifi.task import WifiConfig, WifiTask
from uav_swarm.missions.wifi.warm_start import replan_expert, served_users
from uav_swarm.world.comms import RadioConfig
from uav_swarm.world.crowd import CrowdSim
from uav_swarm.world.scenario import ScenarioConfig, random_scenario

SMALL = ScenarioConfig(width_m=100.0, height_m=100.0, n_groups_min=3, n_groups_max=4, n_obstacles=2)


class _Recorder:
    """Fake solves that say which ran: the fresh one jumps far away and serves ``fresh_served`` users."""

    def __init__(self, fresh_served: int) -> None:
        self.calls: list[str] = []
        self.fresh_served = fresh_served

    def fresh(self, users_m, velocities_m_s):
        self.calls.append("fresh")
        return np.array([[90.0, 90.0], [10.0, 90.0]]) + 0.01 * len(self.calls)

    def warm(self, users_m, last_m):
        self.calls.append("warm")
        return last_m + 0.5

    def served(self, users_m, uavs_m):
        return self.fresh_served if uavs_m[0, 0] > 80.0 or uavs_m[0, 1] > 80.0 else 100


def test_travel_pairs_by_least_total_distance_and_charges_the_unpaired():
    a = np.array([[0.0, 0.0], [10.0, 0.0]])
    assert travel_m(a, a[::-1] + (0.0, 1.0), 30.0) == pytest.approx(2.0)
    assert travel_m(a, a[:1], 30.0) == pytest.approx(30.0)
    assert travel_m(np.zeros((0, 2)), np.zeros((0, 2)), 30.0) == 0.0


def test_the_first_replan_solves_then_the_warm_start_runs_and_a_fresh_solve_wins_only_by_its_move_cost():
    config = ReplanExpertConfig(fresh_every=3, move_cost_users_per_100m=10.0)
    users = np.zeros((5, 2))
    cheap = _Recorder(fresh_served=101)  # one more user than the warm placement: not worth ~170 m
    expert = ReplanExpert(config, cheap.fresh, cheap.warm, cheap.served)
    first = expert.place(users)
    expert.last_m = np.array([[10.0, 10.0], [20.0, 10.0]])
    placements = [expert.place(users) for _ in range(4)]
    assert cheap.calls == ["fresh", "warm", "warm", "warm", "fresh", "warm"]
    assert first[0, 0] > 80.0 and all(p[0, 0] < 30.0 for p in placements)
    assert np.allclose(placements[-1], [[12.0, 12.0], [22.0, 12.0]])
    worth = _Recorder(fresh_served=150)  # 50 more users pay for the travel
    expert = ReplanExpert(config, worth.fresh, worth.warm, worth.served)
    expert.place(users)
    expert.last_m = np.array([[10.0, 10.0], [20.0, 10.0]])
    taken = [expert.place(users) for _ in range(3)]
    assert taken[-1][1, 1] > 80.0 and expert.fresh_taken == 2


def test_without_warm_start_every_replan_is_a_fresh_solve():
    recorder = _Recorder(fresh_served=0)
    config = ReplanExpertConfig(warm_start=False)
    expert = ReplanExpert(config, recorder.fresh, recorder.warm, recorder.served)
    for _ in range(3):
        expert.place(np.zeros((5, 2)))
    assert recorder.calls == ["fresh"] * 3


def _walking(task: WifiTask, seed: int, seconds: int) -> list[tuple[np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(seed)
    crowd = CrowdSim(random_scenario(rng, task.config.scenario), task.config.crowd, rng)
    crowd.step(int(20.0 / task.config.crowd.dt_s))
    frames = []
    for _ in range(seconds):
        frames.append((np.array(crowd.positions_m), np.array(crowd.velocities_m_s)))
        crowd.step(int(1.0 / task.config.crowd.dt_s))
    return frames


@pytest.mark.parametrize("seed", [3, 4])
def test_on_the_paper_radio_a_walking_crowd_gets_valid_placements_that_travel_no_more_than_fresh_solves(seed):
    config = WifiConfig(strategy=2, scenario=SMALL, expert=WifiConfig().expert.replace(method="search"))
    frames = _walking(WifiTask(config), seed, 6)
    travelled = {}
    for warm in (False, True):
        replan = config.expert.replan.replace(warm_start=warm, fresh_every=0)
        task = WifiTask(config.replace(expert=config.expert.replace(replan=replan)))
        expert, last, travelled[warm] = replan_expert(task), None, 0.0
        for users, velocities in frames:
            placement = expert.place(users, velocities)
            assert is_valid_placement(assign_users(users, placement, task.rules.radius_m), task.rules)
            if last is not None:
                travelled[warm] += travel_m(last, placement, 50.0)
            last = placement
        assert expert.fresh_taken == (1 if warm else len(frames))
    assert travelled[True] <= travelled[False]


def test_under_the_80211_radio_the_warm_start_serves_users_and_the_same_sequence_gives_the_same_placements():
    radio = RadioConfig(propagation="802.11", altitude_m=10.0)
    config = WifiConfig(strategy=2, scenario=SMALL, radio=radio)
    frames = _walking(WifiTask(config), 5, 3)
    runs = []
    for _ in range(2):
        task = WifiTask(config)
        expert = replan_expert(task)
        runs.append([expert.place(users, velocities) for users, velocities in frames])
        assert served_users(task, frames[-1][0], runs[-1][-1]) > 0
    for a, b in zip(*runs, strict=True):
        np.testing.assert_array_equal(a, b)


def test_bad_replan_settings_are_refused():
    with pytest.raises(ConfigError, match="fresh_every"):
        ReplanExpertConfig(fresh_every=-1)
    with pytest.raises(ConfigError, match="move_cost"):
        ReplanExpertConfig(move_cost_users_per_100m=-1.0)
