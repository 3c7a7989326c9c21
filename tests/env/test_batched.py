"""BatchedUAVSwarm: B copies stepped together equal B separate raw_envs (seeds s, s+1, ...)."""

from __future__ import annotations

import numpy as np
import pytest

from uav_swarm.env.batched import BatchedUAVSwarm
from uav_swarm.env.parallel import raw_env

WORLD = {
    "scenario": {"n_groups_min": 2, "n_groups_max": 3, "group_size_min": 10, "group_size_max": 30},
    "density_shape": (16, 16),
    "patch_px": 5,
}
SETTINGS = [
    pytest.param({"n_uavs": 4, "action_mode": "velocity"}, id="velocity-s1"),
    pytest.param({"n_uavs": 10, "action_mode": "waypoint", "strategy": 2, "use_3d_distance": True,
                  "density_shape": (32, 24), "patch_px": 7}, id="waypoint-s2-3d"),
    pytest.param({"n_uavs": 1, "action_mode": "velocity", "strategy": 2}, id="single-uav"),
]
TEAM_KEYS = ("qos_s1", "qos_s2", "mean_throughput_mbps", "covered_users", "n_pedestrians",
             "separation_penalty")
TOL = {"rtol": 1e-6, "atol": 1e-6}


def _random_actions(rng, envs, n_steps):
    """Actions beyond the box on purpose (clipping), (steps, B, n, 2)."""
    low, high = envs.single_action_space.low, envs.single_action_space.high
    span = high - low
    return rng.uniform(low - 0.2 * span, high + 0.2 * span, size=(n_steps, envs.num_envs, envs.n_agents, 2))


def _as_dict(action, agents):
    return dict(zip(agents, action, strict=True))


def _assert_copy_equals(k, batch_out, single_out, agents):
    obs, reward, terminated, truncated, info = batch_out
    s_obs, s_rew, s_term, s_trunc, s_info = single_out
    np.testing.assert_allclose(obs[k], np.stack([s_obs[a] for a in agents]), **TOL)
    assert reward[k] == pytest.approx(s_rew[agents[0]], abs=1e-6)
    assert terminated[k] == s_term[agents[0]]
    assert truncated[k] == s_trunc[agents[0]]
    _assert_infos(k, info, s_info, agents)


def _assert_infos(k, info, s_info, agents):
    for key in TEAM_KEYS:
        assert info[key][k] == pytest.approx(s_info[agents[0]][key], abs=1e-9), key
    np.testing.assert_array_equal(info["users_served"][k], [s_info[a]["users_served"] for a in agents])
    np.testing.assert_allclose(info["throughput_per_user_mbps"][k],
                               [s_info[a]["throughput_per_user_mbps"] for a in agents], rtol=1e-12)


@pytest.mark.parametrize("settings", SETTINGS)
def test_copies_equal_separate_envs(settings):
    cfg = {**WORLD, "max_cycles": 60, **settings}
    envs = BatchedUAVSwarm(3, **cfg)
    singles = [raw_env(**cfg) for _ in range(3)]
    obs, info = envs.reset(seed=11)
    agents = singles[0].possible_agents
    for k, single in enumerate(singles):
        s_obs, s_info = single.reset(seed=11 + k)
        np.testing.assert_allclose(obs[k], np.stack([s_obs[a] for a in agents]), **TOL)
        _assert_infos(k, info, s_info, agents)
    actions = _random_actions(np.random.default_rng(0), envs, 60)
    for step, action in enumerate(actions):
        out = envs.step(action)
        for k, single in enumerate(singles):
            single_out = single.step({a: action[k, i] for i, a in enumerate(agents)})
            _assert_copy_equals(k, out, single_out, agents)
            np.testing.assert_allclose(envs.state()[k], single.state(), **TOL)
        assert out[3].all() == (step == 59)
        assert out[0].dtype == np.float32 and out[1].dtype == np.float32
    assert envs.finished.all()
    with pytest.raises(RuntimeError, match=r"copies \[0, 1, 2\] are finished"):
        envs.step(actions[0])


def test_partial_reset_and_masked_step():
    cfg = {**WORLD, "max_cycles": 100, "n_uavs": 3}
    envs = BatchedUAVSwarm(3, **cfg)
    singles = [raw_env(**cfg) for _ in range(3)]
    envs.reset(seed=[5, None, 7])
    singles[0].reset(seed=5)
    singles[2].reset(seed=7)
    singles[1] = None  # copy 1 drew from entropy: reseeded below
    agents = envs.possible_agents
    actions = _random_actions(np.random.default_rng(1), envs, 20)
    for action in actions[:10]:
        envs.step(action)
        for k in (0, 2):
            singles[k].step({a: action[k, i] for i, a in enumerate(agents)})
    before = envs.state()
    mask = np.array([False, True, False])
    obs, info = envs.reset(seed=[None, 42, None], mask=mask)
    singles[1] = raw_env(**cfg)
    s_obs, _ = singles[1].reset(seed=42)
    np.testing.assert_allclose(obs[1], np.stack([s_obs[a] for a in agents]), **TOL)
    np.testing.assert_array_equal(envs.state()[[0, 2]], before[[0, 2]])  # the others untouched
    # A masked step moves only copy 0 and 2; copy 1 stays at its reset state.
    out = envs.step(actions[10], mask=np.array([True, False, True]))
    np.testing.assert_allclose(out[0][1], obs[1])
    for k in (0, 2):
        _assert_copy_equals(k, out, singles[k].step(_as_dict(actions[10][k], agents)), agents)
    for action in actions[11:]:
        out = envs.step(action)
        for k in range(3):
            _assert_copy_equals(k, out, singles[k].step(_as_dict(action[k], agents)), agents)


def test_same_seed_same_trajectory_and_none_continues():
    cfg = {**WORLD, "max_cycles": 30, "n_uavs": 2}
    actions = _random_actions(np.random.default_rng(2), BatchedUAVSwarm(2, **cfg), 15)
    runs = []
    for _ in range(2):
        envs = BatchedUAVSwarm(2, **cfg)
        trace = [envs.reset(seed=3)[0]] + [envs.step(a)[0] for a in actions]
        trace.append(envs.reset()[0])  # continues each copy's generator
        runs.append(np.stack(trace))
    np.testing.assert_array_equal(runs[0], runs[1])
    single = raw_env(**cfg)
    single.reset(seed=4)
    s_obs, _ = single.reset()
    np.testing.assert_allclose(runs[0][-1][1], np.stack([s_obs[a] for a in single.possible_agents]), **TOL)


def test_truncation_after_max_cycles_then_reset():
    envs = BatchedUAVSwarm(2, **WORLD, max_cycles=3, n_uavs=2)
    envs.reset(seed=0)
    truncated = [envs.step(np.zeros((2, 2, 2)))[3].tolist() for _ in range(3)]
    assert truncated == [[False, False], [False, False], [True, True]]
    envs.reset(mask=np.array([True, False]))
    with pytest.raises(RuntimeError, match=r"copies \[1\]"):
        envs.step(np.zeros((2, 2, 2)))
    envs.step(np.zeros((2, 2, 2)), mask=np.array([True, False]))  # the finished copy is left alone


@pytest.mark.parametrize(
    ("actions", "message"),
    [
        (np.zeros((2, 2)), r"shape \(num_envs, n_agents, 2\)"),
        (np.zeros((2, 3, 2)), "shape"),
        (np.full((2, 2, 2), np.nan), r"NaN or inf at \(copy, agent\) \[\(0, 0\)"),
        (np.array([[[0, 0], [0, np.inf]], [[0, 0], [0, 0]]]), r"\[\(0, 1\)\]"),
        (np.full((2, 2, 2), "a"), "float or int"),
        ([[[0, 0], [0]], [[0, 0], [0, 0]]], "shape"),
    ],
    ids=["2d", "agents", "nan", "inf", "str", "ragged"],
)
def test_malformed_actions_rejected(actions, message):
    envs = BatchedUAVSwarm(2, **WORLD, n_uavs=2)
    envs.reset(seed=0)
    with pytest.raises(ValueError, match=message):
        envs.step(actions)


def test_bad_arguments():
    with pytest.raises(ValueError, match="num_envs"):
        BatchedUAVSwarm(0)
    envs = BatchedUAVSwarm(2, **WORLD, n_uavs=2)
    with pytest.raises(RuntimeError, match="reset"):
        envs.step(np.zeros((2, 2, 2)))
    with pytest.raises(RuntimeError, match="first reset"):
        envs.reset(mask=np.array([True, False]))
    with pytest.raises(ValueError, match="sequence of num_envs = 2"):
        envs.reset(seed=[1, 2, 3])
    envs.reset(seed=1)
    with pytest.raises(ValueError, match="mask"):
        envs.reset(mask=np.array([False, False]))


def test_fixed_scene():
    from uav_swarm.world.scenario import ScenarioConfig, random_scenario

    scene = random_scenario(np.random.default_rng(9), ScenarioConfig(n_groups_min=2, n_groups_max=2))
    envs = BatchedUAVSwarm(2, scene=scene, n_uavs=2, max_cycles=5)
    single = raw_env(scene=scene, n_uavs=2, max_cycles=5)
    obs, _ = envs.reset(seed=0)
    s_obs, _ = single.reset(seed=1)
    np.testing.assert_allclose(obs[1], np.stack([s_obs[a] for a in single.possible_agents]), **TOL)
    assert all(s is scene for s in envs.crowd.scenarios)


def test_spaces_match_raw_env():
    envs = BatchedUAVSwarm(2, **WORLD, n_uavs=3, action_mode="waypoint")
    single = raw_env(**WORLD, n_uavs=3, action_mode="waypoint")
    assert envs.single_observation_space == single.observation_space("uav_0")
    assert envs.single_action_space == single.action_space("uav_0")
    assert envs.state_dim == single.state_space.shape[0] and envs.obs_dim == 4 + 27 + 25 + 4
    obs, _ = envs.reset(seed=0)
    assert all(envs.single_observation_space.contains(o) for o in obs.reshape(-1, envs.obs_dim))
