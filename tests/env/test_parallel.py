"""The uav_swarm_v0 environment: PettingZoo's conformance suite over a grid, and our own checks."""

import copy
import functools
import itertools
import types

import numpy as np
import pytest
from pettingzoo.test import (
    api_test,
    max_cycles_test,
    parallel_api_test,
    parallel_seed_test,
    render_test,
    seed_test,
    state_test,
)
from pettingzoo.utils.conversions import parallel_to_aec

from typed_config import ConfigError
from uav_swarm.env.parallel import EnvConfig, env, parallel_env
from uav_swarm.world.comms import evaluate_coverage

SMALL_WORLD = {
    "scenario": {"n_groups_min": 2, "n_groups_max": 2, "group_size_min": 6, "group_size_max": 6,
                 "n_obstacles": 4},
    "density_shape": (16, 16),
    "patch_px": 5,
}

GRID = [
    pytest.param({"n_uavs": n, "action_mode": mode, "strategy": strategy}, id=f"n{n}-{mode}-s{strategy}")
    for n, mode, strategy in itertools.product((1, 4, 10), ("velocity", "waypoint"), (1, 2))
]


def small(**kwargs):
    return {**SMALL_WORLD, "max_cycles": 15, **kwargs}


@pytest.fixture(autouse=True)
def _headless(monkeypatch):
    monkeypatch.setenv("MPLBACKEND", "Agg")


@pytest.mark.parametrize("settings", GRID)
def test_parallel_api(settings):
    parallel_api_test(parallel_env(**small(**settings)), num_cycles=20)


@pytest.mark.parametrize("settings", GRID)
def test_aec_api(settings):
    api_test(parallel_to_aec(parallel_env(**small(**settings))), num_cycles=10)


@pytest.mark.parametrize("settings", GRID)
def test_seeds(settings):
    parallel_seed_test(functools.partial(parallel_env, **small(**settings)), num_cycles=10)
    seed_test(functools.partial(env, **small(**settings)), num_cycles=10)


@pytest.mark.parametrize("settings", GRID)
def test_max_cycles(settings):
    kwargs = {k: v for k, v in small(**settings).items() if k != "max_cycles"}
    module = types.SimpleNamespace(parallel_env=functools.partial(parallel_env, **kwargs),
                                   env=functools.partial(env, **kwargs))
    max_cycles_test(module)


@pytest.mark.parametrize("settings", GRID)
def test_state(settings):
    state_test(env(**small(**settings)), parallel_env(**small(**settings)), num_cycles=5)


@pytest.mark.parametrize("settings", [GRID[0], GRID[-1]])
def test_render(settings):
    render_test(functools.partial(env, **small(**settings)))


def _random_actions(par_env, rng):
    return {agent: par_env.action_space(agent).low
            + rng.random(2) * (par_env.action_space(agent).high - par_env.action_space(agent).low)
            for agent in par_env.agents}


@pytest.mark.parametrize("mode", ["velocity", "waypoint"])
def test_same_seed_same_actions_same_episode_for_200_steps(mode):
    kwargs = {"n_uavs": 4, "action_mode": mode, "max_cycles": 200, "strategy": 1,
              "scenario": {"n_groups_min": 3, "n_groups_max": 3, "group_size_min": 30, "group_size_max": 30}}
    env_a, env_b = parallel_env(**kwargs), parallel_env(**kwargs)
    obs_a, info_a = env_a.reset(seed=123)
    obs_b, info_b = env_b.reset(seed=123)
    rng = np.random.default_rng(5)
    steps = 0
    start_peds, start_uavs = env_a.pedestrian_positions_m.copy(), env_a.uav_positions_m.copy()
    while env_a.agents:
        assert info_a == info_b
        assert all(np.array_equal(obs_a[a], obs_b[a]) for a in env_a.possible_agents)
        actions = _random_actions(env_a, rng)
        obs_a, rew_a, term_a, trunc_a, info_a = env_a.step(actions)
        obs_b, rew_b, term_b, trunc_b, info_b = env_b.step(actions)
        assert rew_a == rew_b and term_a == term_b and trunc_a == trunc_b
        assert np.array_equal(env_a.pedestrian_positions_m, env_b.pedestrian_positions_m)
        steps += 1
    assert steps == 200
    # The episode is not trivially constant: the crowd walked and the UAVs flew.
    assert np.abs(env_a.pedestrian_positions_m - start_peds).max() > 5.0
    assert np.abs(env_a.uav_positions_m - start_uavs).max() > 5.0
    env_c = parallel_env(**kwargs)
    env_c.reset(seed=124)
    assert not np.array_equal(env_c.pedestrian_positions_m[:5], env_a.pedestrian_positions_m[:5])


@pytest.mark.parametrize("mode", ["velocity", "waypoint"])
def test_observations_and_state_stay_in_their_spaces(mode):
    par_env = parallel_env(**small(n_uavs=10, action_mode=mode, max_cycles=60))
    obs, _ = par_env.reset(seed=1)
    rng = np.random.default_rng(0)
    while par_env.agents:
        for agent, o in obs.items():
            assert o.dtype == np.float32 and par_env.observation_space(agent).contains(o), agent
        assert par_env.state_space.contains(par_env.state())
        # Extreme actions (corners, full speed) push the UAVs against the bounds.
        actions = {a: par_env.action_space(a).high if rng.random() < 0.5 else par_env.action_space(a).low
                   for a in par_env.agents}
        obs, rewards, terms, truncs, infos = par_env.step(actions)
        assert all(type(r) is float for r in rewards.values())
        assert all(type(t) is bool for t in (*terms.values(), *truncs.values()))
    assert all(truncs.values())


def test_observation_layout():
    par_env = parallel_env(**small(n_uavs=3))
    obs, _ = par_env.reset(seed=2)
    pos = par_env.uav_positions_m / np.array([par_env.width_m, par_env.height_m])
    o = obs["uav_1"]
    assert np.allclose(o[0:2], pos[1])
    assert np.allclose(o[4:8], np.concatenate([pos[0] - pos[1], pos[2] - pos[1]]), atol=1e-6)
    assert np.all(o[8:22] == 0)
    assert o[22:31].tolist() == [1, 1] + [0] * 7
    patch = o[31:31 + 25].reshape(5, 5)
    assert patch.sum() <= 1.0 + 1e-6
    col, row = (par_env.uav_positions_m[1] * 16 / 200).astype(int)  # the UAV's density-map pixel
    assert patch[2, 2] == pytest.approx(par_env.density[row, col] / 12)
    for dr, dc in ((0, 0), (1, 2), (4, 4), (3, 0)):
        r, c = row + dr - 2, col + dc - 2
        inside = 0 <= r < 16 and 0 <= c < 16
        assert patch[dr, dc] == pytest.approx(par_env.density[r, c] / 12 if inside else 0.0)
    assert o[-2] == pytest.approx(par_env.coverage.qos_s1)


def test_reward_infos_and_accessors_agree_with_the_world():
    paper = {"propagation": "paper"}  # compared with the paper's snapshot model below
    par_env = parallel_env(**small(n_uavs=4, strategy=1, separation_weight=0.0, radio=paper))
    par_env.reset(seed=3)
    _, rewards, _, _, infos = par_env.step({a: np.zeros(2) for a in par_env.agents})
    cov = evaluate_coverage(par_env.pedestrian_positions_m, par_env.uav_positions_m, par_env.radio)
    assert rewards["uav_0"] == pytest.approx(cov.qos_s1)
    assert len(set(rewards.values())) == 1
    info = infos["uav_2"]
    assert info["n_pedestrians"] == par_env.scenario.n_pedestrians == 12
    assert info["covered_users"] == int(cov.covered.sum())
    assert info["users_served"] == int(cov.users_per_uav[2])
    assert info["mean_throughput_mbps"] == pytest.approx(cov.mean_throughput_mbps)
    assert par_env.density.sum() == 12
    with pytest.raises(ValueError):
        par_env.uav_positions_m[0, 0] = 1.0  # read-only


def test_waypoint_mode_reaches_targets_and_the_guard_keeps_the_separation():
    par_env = parallel_env(**small(n_uavs=3, action_mode="waypoint", max_cycles=600, separation_weight=0.5))
    par_env.reset(seed=4)
    targets = {"uav_0": np.array([20.0, 30.0]), "uav_1": np.array([180.0, 150.0]),
               "uav_2": np.array([100, 100])}
    for _ in range(300):
        _, rewards, _, _, infos = par_env.step(targets)
    assert np.allclose(par_env.uav_positions_m, np.stack(list(targets.values())), atol=0.05)
    assert np.allclose(par_env.uav_velocities_m_s, 0.0, atol=0.05)
    assert infos["uav_0"]["separation_penalty"] == 0.0
    # Same target for all: the guard holds the later UAVs back, no pair comes within the minimum.
    together = {a: np.array([100.0, 100.0]) for a in par_env.agents}
    held = np.zeros(3)
    for _ in range(250):
        _, rewards, _, _, infos = par_env.step(together)
        held += [infos[a]["separation_held"] for a in par_env.agents]
        assert infos["uav_0"]["closest_separation_m"] >= 5.0 - 1e-9
    assert infos["uav_0"]["separation_penalty"] == 0.0
    assert held.sum() > 0
    assert np.linalg.norm(par_env.uav_positions_m - 100.0, axis=1).min() < 5.0  # one of them got there


def test_velocity_mode_is_not_guarded_and_separation_is_penalised():
    par_env = parallel_env(**small(n_uavs=3, max_cycles=600, separation_weight=0.5))
    par_env.reset(seed=4)
    for _ in range(300):  # every UAV flies towards the centre, at most at 1 m/s once within 10 m
        offset = (np.array([100.0, 100.0]) - par_env.uav_positions_m) / 10.0
        action = np.clip(offset / np.maximum(1.0, np.abs(offset).max(axis=1, keepdims=True)), -1, 1)
        _, rewards, _, _, infos = par_env.step(dict(zip(par_env.agents, action, strict=True)))
    info = infos["uav_0"]
    assert info["closest_separation_m"] < 1.0 and info["separation_penalty"] > 2.0
    assert {infos[a]["separation_held"] for a in par_env.agents} == {0}
    assert rewards["uav_0"] == pytest.approx(info["qos_s1"] - 0.5 * info["separation_penalty"], abs=1e-12)


def test_missing_agent_keeps_its_target_or_stops():
    par_env = parallel_env(**small(n_uavs=2, action_mode="waypoint", max_cycles=400))
    par_env.reset(seed=5)
    par_env.step({"uav_0": np.array([50.0, 50.0]), "uav_1": np.array([150.0, 150.0])})
    for _ in range(300):
        par_env.step({"uav_0": np.array([50.0, 50.0])})
    assert np.allclose(par_env.uav_positions_m[1], [150.0, 150.0], atol=0.05)


@pytest.mark.parametrize("dtype", [np.float16, np.float32, np.float64, np.int8, np.int32, np.int64, np.uint8])
def test_any_numeric_dtype_is_accepted(dtype):
    par_env = parallel_env(**small(n_uavs=2, action_mode="waypoint"))
    par_env.reset(seed=6)
    par_env.step({a: np.array([10, 20], dtype=dtype) for a in par_env.agents})
    par_env.step({a: [np.int64(10), np.float32(20.0)] for a in par_env.agents})


@pytest.mark.parametrize(
    ("actions", "match"),
    [({"uav_0": np.zeros(2), "uav_9": np.zeros(2)}, "unknown agent 'uav_9'"),
     ({"uav_0": np.zeros(3)}, r"'uav_0' must have shape \(2,\), got \(3,\)"),
     ({"uav_1": np.zeros((1, 2))}, r"'uav_1' must have shape"),
     ({"uav_0": np.zeros(2), "uav_1": np.array([0.0, np.nan])}, "'uav_1' contains NaN or inf"),
     ({"uav_0": np.array([np.inf, 0.0])}, "'uav_0' contains NaN or inf"),
     ({"uav_0": np.array(["a", "b"])}, "'uav_0' must be a float or int"),
     ({"uav_0": np.array([True, False])}, "'uav_0' must be a float or int")],
)
def test_bad_actions_are_value_errors_naming_the_agent(actions, match):
    par_env = parallel_env(**small(n_uavs=2))
    par_env.reset(seed=0)
    with pytest.raises(ValueError, match=match):
        par_env.step(actions)


def test_too_many_uavs_and_bad_settings_are_errors():
    with pytest.raises(ConfigError, match=r"n_uavs = 11 is out of range: allowed 1 <= n_uavs <= 10"):
        parallel_env(n_uavs=11)
    with pytest.raises(ConfigError, match="action_mode"):
        parallel_env(action_mode="teleport")
    with pytest.raises(ConfigError, match="unknown key.*'wind_m_s'"):
        parallel_env(wind_m_s=3.0)
    with pytest.raises(ConfigError, match="patch_px"):
        parallel_env(patch_px=4)
    with pytest.raises(ValueError, match="render_mode"):
        parallel_env(render_mode="ansi")


def test_kwargs_and_config_map_onto_env_config():
    par_env = parallel_env(config=EnvConfig(n_uavs=2), uav={"max_speed_m_s": 3.0},
                           radio={"propagation": "paper", "sigma_sq_m2": 450.0})
    assert par_env.config.n_uavs == 2
    assert par_env.config.uav.max_speed_m_s == 3.0 and par_env.config.uav.max_accel_m_s2 == 5.0
    assert par_env.radio.sigma_sq_m2 == 450.0
    assert par_env.metadata["name"] == "uav_swarm_v0"
    assert parallel_env(n_uavs=2).radio.propagation == "802.11"  # the default
    with pytest.raises(ConfigError, match="sigma_sq_m2 belongs to propagation = 'paper': set propagation"):
        parallel_env(config=EnvConfig(n_uavs=2), radio={"sigma_sq_m2": 450.0})  # given: applied or refused


def test_state_before_reset_is_a_clear_error():
    with pytest.raises(RuntimeError, match="reset"):
        parallel_env(**small()).state()


def test_rgb_render_and_no_render():
    par_env = parallel_env(**small(n_uavs=3), render_mode="rgb_array")
    par_env.reset(seed=0)
    frame = par_env.render()
    assert frame.dtype == np.uint8 and frame.shape == (512, 512, 3)
    assert (frame == [220, 30, 30]).all(axis=2).any()  # the UAVs are drawn
    quiet = parallel_env(**small(n_uavs=3))
    quiet.reset(seed=0)
    assert quiet.render() is None


def test_fixed_scene_is_kept_across_resets():
    from uav_swarm.world.scenario import ScenarioConfig, random_scenario

    scene = random_scenario(np.random.default_rng(0), ScenarioConfig(
        width_m=150.0, height_m=100.0, n_groups_min=2, n_groups_max=2, group_size_min=5, group_size_max=5))
    par_env = parallel_env(scene=scene, action_mode="waypoint", n_uavs=2)
    assert par_env.action_space("uav_0").high.tolist() == [150.0, 100.0]
    par_env.reset(seed=1)
    first = par_env.pedestrian_positions_m.copy()
    par_env.reset(seed=2)
    assert par_env.scenario is scene
    assert not np.array_equal(first, par_env.pedestrian_positions_m)  # the crowd is redrawn


def test_3d_distance_uses_the_flight_altitude():
    flat = parallel_env(**small(n_uavs=1))
    high = parallel_env(**small(n_uavs=1), use_3d_distance=True, uav={"alt_m": 18.0})
    assert flat.radio.altitude_m == 0.0 and high.radio.altitude_m == 18.0
    assert flat.coverage_radius_m == pytest.approx(30.0) and high.coverage_radius_m == pytest.approx(24.0)
    with pytest.raises(ConfigError, match="radio.altitude_m"):
        parallel_env(radio={"altitude_m": 10.0})


def test_a_deep_copy_is_an_independent_env():
    original = parallel_env(**small(n_uavs=2, action_mode="waypoint", max_cycles=400))
    original.reset(seed=12)
    twin = copy.deepcopy(original)
    for _ in range(300):  # both UAVs fly to the first pedestrian: their patches see the crowd
        actions = {a: np.array(original.pedestrian_positions_m[0]) for a in original.agents}
        obs, *_ = original.step(actions)
        twin_obs, *_ = twin.step(actions)
        for agent in obs:
            np.testing.assert_array_equal(obs[agent], twin_obs[agent])
    assert np.any(obs["uav_0"][31:-4] > 0) or np.any(obs["uav_1"][31:-4] > 0)  # the patches are seen
    twin.reset(seed=13)
    assert not np.array_equal(twin.state(), original.state())
