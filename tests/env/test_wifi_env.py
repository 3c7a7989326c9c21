"""The environment under the 802.11 radio: it runs, each UAV's altitude reaches the radio, batch = singles."""

import numpy as np
import pytest

from uav_swarm.env import parallel_env
from uav_swarm.env.batched import BatchedUAVSwarm

WIFI = {"propagation": "802.11"}


def hold(env, steps, uav=None):
    env.reset(seed=3)
    spots = {a: np.array([60.0 + 30 * i, 100.0]) for i, a in enumerate(env.possible_agents)}
    for _ in range(steps):
        _, rewards, _, _, infos = env.step(spots)
    return rewards, infos


def test_the_env_reports_the_802_11_coverage():
    env = parallel_env(n_uavs=3, strategy=2, radio=WIFI)
    rewards, infos = hold(env, 5)
    coverage = env.coverage
    assert coverage.model.startswith("802.11")
    # 30 m apart the three hear each other: the environment's own plan puts them on three channels
    assert coverage.sinr_db is not None and coverage.channel.tolist() == [36, 40, 44]
    assert 0.0 <= infos["uav_0"]["qos_s2"] <= infos["uav_0"]["qos_s1"] <= 1.0
    assert np.all(coverage.throughput_mbps[~coverage.covered] == 0.0)
    served = sum(infos[a]["users_served"] for a in env.possible_agents)
    assert served == np.count_nonzero(coverage.association >= 0)


def test_altitude_layers_reach_the_radio():
    flat = parallel_env(n_uavs=3, strategy=1, radio=WIFI)
    layered = parallel_env(n_uavs=3, strategy=1, radio=WIFI, uav={"layer_step_m": 15.0})
    hold(flat, 2)
    hold(layered, 2)
    np.testing.assert_array_equal(flat.pedestrian_positions_m, layered.pedestrian_positions_m)
    assert not np.allclose(flat.coverage.sinr_db, layered.coverage.sinr_db)


def test_the_batched_view_matches_single_environments_under_802_11():
    batched = BatchedUAVSwarm(2, n_uavs=3, strategy=2, radio=WIFI)
    batched.reset(seed=[5, 6])
    singles = [parallel_env(n_uavs=3, strategy=2, radio=WIFI) for _ in range(2)]
    for seed, env in zip([5, 6], singles, strict=True):
        env.reset(seed=seed)
    actions = np.array([[[50.0, 50.0], [100.0, 100.0], [150.0, 150.0]]] * 2)
    for _ in range(5):
        _, reward, *_ = batched.step(actions)
        for copy, env in enumerate(singles):
            _, rewards, *_ = env.step(dict(zip(env.possible_agents, actions[copy], strict=True)))
            assert reward[copy] == rewards["uav_0"]


def test_a_channel_plan_reaches_the_radio_and_a_wrong_one_is_refused():
    env = parallel_env(n_uavs=3, strategy=2, radio=WIFI)
    hold(env, 1)
    env.set_channel_plan(np.array([40, 44, 48]))
    hold_still = {a: np.zeros(2) for a in env.possible_agents}
    env.step(hold_still)
    assert env.coverage.channel.tolist() == [40, 44, 48]
    with pytest.raises(ValueError, match="channels \\[52\\] are not usable"):
        env.set_channel_plan(np.array([52, 40, 44]))
    paper = parallel_env(n_uavs=3, radio={"propagation": "paper"})
    with pytest.raises(ValueError, match="applies only with RadioConfig.propagation = '802.11'"):
        paper.set_channel_plan(np.array([36, 40, 44]))


def test_the_environment_flies_the_802_11_radio_and_plans_channels_unless_told():
    env = parallel_env(n_uavs=3)
    assert env.radio.propagation == "802.11"
    assert env.radio.ieee80211.rate_admission is False  # strategy 1: nobody refused on rate
    assert parallel_env(n_uavs=3, strategy=2).radio.ieee80211.rate_admission is True
    hold(env, 2)
    assert sorted(env.coverage.channel.tolist()) == [36, 40, 44]  # three APs that hear each other
    env.set_channel_plan(np.array([36, 36, 36]))  # a plan given stays
    env.step({a: np.zeros(2) for a in env.possible_agents})
    assert env.coverage.channel.tolist() == [36, 36, 36]
    env.set_channel_plan(None)  # planned again from the next step
    env.step({a: np.zeros(2) for a in env.possible_agents})
    assert sorted(env.coverage.channel.tolist()) == [36, 40, 44]
    assert parallel_env(n_uavs=3, radio={"propagation": "paper"}).radio.propagation == "paper"
