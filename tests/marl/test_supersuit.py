"""SuperSuit's wrappers on the parallel uav_swarm_v0, and its vector env, checked against the raw env."""

import sys

import numpy as np
import pytest
import supersuit as ss  # noqa: E402  (the marl extra; CI installs it)
from marl_world import SMALL_WORLD, random_actions, raw_trajectory  # noqa: E402
from pettingzoo.test import parallel_api_test  # noqa: E402

from uav_swarm.env.parallel import parallel_env  # noqa: E402
from uav_swarm.marl import supersuit_vec_env  # noqa: E402

N_UAVS, MAX_CYCLES = 3, 20


def _kwargs(mode="velocity", n_uavs=N_UAVS):
    return {"n_uavs": n_uavs, "max_cycles": MAX_CYCLES, "action_mode": mode, **SMALL_WORLD}


WRAPPERS = {
    "clip_actions": ss.clip_actions_v0,
    "normalize_obs": lambda env: ss.normalize_obs_v0(env, env_min=0.0, env_max=1.0),
    "dtype": lambda env: ss.dtype_v0(env, np.float64),
    "frame_stack": lambda env: ss.frame_stack_v1(env, 3),
    "clip_reward": lambda env: ss.clip_reward_v0(env, lower_bound=0.0, upper_bound=0.5),
}


def _wrapped_trajectory(wrapper, mode, actions, seed):
    env = WRAPPERS[wrapper](parallel_env(**_kwargs(mode)))
    obs, _ = env.reset(seed=seed)
    out = {"obs": [np.stack(list(obs.values()))], "reward": [], "truncated": []}
    for step_actions in actions:
        obs, rewards, _, truncs, _ = env.step(dict(zip(env.agents, step_actions, strict=True)))
        out["obs"].append(np.stack(list(obs.values())))
        out["reward"].append(next(iter(rewards.values())))
        out["truncated"].append(all(truncs.values()))
        if not env.agents:
            env.reset()
    return env, {key: np.asarray(value) for key, value in out.items()}


@pytest.mark.parametrize("mode", ["velocity", "waypoint"])
@pytest.mark.parametrize("wrapper", list(WRAPPERS))
def test_parallel_api_after_wrapping(wrapper, mode):
    parallel_api_test(WRAPPERS[wrapper](parallel_env(**_kwargs(mode))), num_cycles=3 * MAX_CYCLES)


@pytest.mark.parametrize("mode", ["velocity", "waypoint"])
def test_clip_actions_hands_the_env_clipped_actions(mode):
    raw = parallel_env(**_kwargs(mode))
    received = []
    step = raw.step
    raw.step = lambda actions: received.append(dict(actions)) or step(actions)  # the caller reuses its dict
    env = ss.clip_actions_v0(raw)
    space = raw.action_space("uav_0")
    actions = random_actions(raw, MAX_CYCLES, seed=5, spread=3.0)  # mostly out of the box
    assert np.mean((actions < space.low) | (actions > space.high)) > 0.5
    env.reset(seed=2)
    rewards = []
    for step_actions in actions:
        rewards.append(env.step(dict(zip(env.agents, step_actions, strict=True)))[1]["uav_0"])
    clipped = np.clip(actions, space.low, space.high)
    np.testing.assert_array_equal(np.stack([np.stack(list(a.values())) for a in received]), clipped)
    np.testing.assert_allclose(rewards, raw_trajectory(_kwargs(mode), clipped, seed=2)["reward"])


def test_observation_wrappers_transform_the_raw_observations():
    actions = random_actions(parallel_env(**_kwargs()), 2 * MAX_CYCLES, seed=4)
    expected = raw_trajectory(_kwargs(), actions, seed=9)
    raw_obs = np.concatenate([expected["obs"][:1], expected["final_obs"]])  # reset, then each step
    space = parallel_env(**_kwargs()).observation_space("uav_0")

    env, got = _wrapped_trajectory("normalize_obs", "velocity", actions, seed=9)
    np.testing.assert_allclose(got["obs"], (raw_obs - space.low) / (space.high - space.low), atol=1e-6)
    box = env.observation_space("uav_0")
    assert box.low.min() == 0.0 and box.high.max() == 1.0

    env, got = _wrapped_trajectory("dtype", "velocity", actions, seed=9)
    assert got["obs"].dtype == np.float64 and env.observation_space("uav_0").dtype == np.float64
    np.testing.assert_array_equal(got["obs"], raw_obs)

    env, got = _wrapped_trajectory("frame_stack", "velocity", actions, seed=9)
    dim = space.shape[0]
    assert env.observation_space("uav_0").shape == (3 * dim,)
    stacks = got["obs"].reshape(len(got["obs"]), N_UAVS, 3, dim)
    np.testing.assert_array_equal(stacks[0, :, :2], 0.0)  # the stack starts empty
    np.testing.assert_array_equal(stacks[:, :, 2], raw_obs)  # newest frame last
    np.testing.assert_array_equal(stacks[1:MAX_CYCLES + 1, :, 1], raw_obs[:MAX_CYCLES])
    np.testing.assert_array_equal(stacks[2:MAX_CYCLES + 1, :, 0], raw_obs[:MAX_CYCLES - 1])


def test_clip_reward_clips_the_team_reward():
    actions = random_actions(parallel_env(**_kwargs()), 2 * MAX_CYCLES, seed=4)
    expected = raw_trajectory(_kwargs(), actions, seed=9)
    assert expected["reward"].max() > 0.5
    _, got = _wrapped_trajectory("clip_reward", "velocity", actions, seed=9)
    np.testing.assert_allclose(got["reward"], np.clip(expected["reward"], 0.0, 0.5))
    np.testing.assert_array_equal(got["truncated"], expected["truncated"])


@pytest.mark.parametrize("num_copies", [2, 4])
def test_vector_env_equals_independent_raw_envs(num_copies):
    """Slots, rewards, done flags, final observations and automatic resets over three episodes."""
    n_uavs, n_steps = 2, 3 * MAX_CYCLES
    venv = supersuit_vec_env(num_copies, **_kwargs(n_uavs=n_uavs))
    raw = parallel_env(**_kwargs(n_uavs=n_uavs))
    num_envs = num_copies * n_uavs
    assert venv.num_envs == num_envs
    assert venv.observation_space == raw.observation_space("uav_0")
    assert venv.action_space == raw.action_space("uav_0")
    obs, infos = venv.reset(seed=20)
    assert obs.shape == (num_envs, raw.observation_space("uav_0").shape[0]) and len(infos) == num_envs
    actions = random_actions(parallel_env(**_kwargs(n_uavs=num_envs)), n_steps, seed=8)
    expected = [raw_trajectory(_kwargs(n_uavs=n_uavs), actions[:, k * n_uavs:(k + 1) * n_uavs], seed=20 + k)
                for k in range(num_copies)]
    at_end = (np.arange(1, n_steps + 1) % MAX_CYCLES) == 0
    for t, step_actions in enumerate(actions):
        for k, exp in enumerate(expected):
            np.testing.assert_allclose(obs[k * n_uavs:(k + 1) * n_uavs], exp["obs"][t])
        obs, rewards, terms, truncs, infos = venv.step(step_actions)
        assert rewards.shape == terms.shape == truncs.shape == (num_envs,)
        np.testing.assert_allclose(rewards, np.repeat([exp["reward"][t] for exp in expected], n_uavs),
                                   rtol=1e-6)
        np.testing.assert_array_equal(truncs, at_end[t])
        np.testing.assert_array_equal(terms, False)
        for k, exp in enumerate(expected):
            for j in range(n_uavs):
                info = infos[k * n_uavs + j]
                assert ("terminal_observation" in info) == at_end[t]
                if at_end[t]:  # the final observation, and the infos of the reset that followed
                    np.testing.assert_allclose(info["terminal_observation"], exp["final_obs"][t, j])
                    assert info["qos_s1"] == pytest.approx(exp["obs"][t + 1, j, -2], abs=1e-6)
                else:
                    assert info["qos_s1"] == pytest.approx(exp["qos_s1"][t])
    assert np.ptp(np.concatenate([exp["reward"] for exp in expected])) > 0


def test_vector_env_in_worker_processes_matches_in_process():
    kwargs = _kwargs(n_uavs=2)
    actions = random_actions(parallel_env(**_kwargs(n_uavs=4)), MAX_CYCLES + 2, seed=1)
    runs = []
    for num_cpus in (0, 2):
        venv = supersuit_vec_env(2, num_cpus=num_cpus, **kwargs)
        obs, _ = venv.reset(seed=3)
        steps = [venv.step(step_actions)[:4] for step_actions in actions]
        venv.close()
        runs.append((obs, *(np.stack([step[i] for step in steps]) for i in range(4))))
    for in_process, in_workers in zip(*runs, strict=True):
        np.testing.assert_allclose(in_process, in_workers)


def test_vector_env_applies_wrap_before_vectorising():
    venv = supersuit_vec_env(2, wrap=lambda env: ss.frame_stack_v1(env, 4), **_kwargs(n_uavs=2))
    obs, _ = venv.reset(seed=0)
    dim = parallel_env(**_kwargs()).observation_space("uav_0").shape[0]
    assert obs.shape == (4, 4 * dim)
    obs = venv.step(np.zeros((4, 2), np.float32))[0]
    assert np.all(obs[:, :2 * dim] == 0.0) and np.any(obs[:, 2 * dim:3 * dim] != 0.0)


def test_black_death_within_an_episode_and_at_its_truncation():
    """black_death_v3 passes PettingZoo's API test within an episode; SuperSuit 3.11 ends an episode only
    when every agent is terminated *and* truncated, so on this env (which only truncates) the wrapper keeps
    its agents after the truncation and the env refuses the next step, naming the cure."""
    wrapped = ss.black_death_v3(parallel_env(**_kwargs()))
    parallel_api_test(wrapped, num_cycles=MAX_CYCLES - 1)
    wrapped.reset(seed=0)
    zeros = {agent: np.zeros(2, np.float32) for agent in wrapped.possible_agents}
    for _ in range(MAX_CYCLES - 1):
        _, _, _, truncations, _ = wrapped.step(zeros)
        assert not any(truncations.values())
    wrapped.step(zeros)
    assert wrapped.unwrapped.agents == [] and wrapped.agents == wrapped.possible_agents
    with pytest.raises(RuntimeError, match=r"finished episode: call reset\(\)"):
        wrapped.step(zeros)


def test_frame_skip_draws_from_the_env_generator():
    parallel_api_test(ss.frame_skip_v0(parallel_env(**_kwargs()), 2), num_cycles=2 * MAX_CYCLES)
    runs = []
    for _ in range(2):
        skipping = ss.frame_skip_v0(parallel_env(**_kwargs()), (1, 3))  # 1 to 3 env steps per step
        skipping.reset(seed=4)
        steps = 0
        while skipping.agents:
            skipping.step({agent: np.zeros(2, np.float32) for agent in skipping.agents})
            steps += 1
        runs.append((steps, skipping.unwrapped.np_random.integers(1 << 30)))
    assert runs[0] == runs[1]  # the seed fixes the skips: they come from env.np_random
    assert MAX_CYCLES / 3 <= runs[0][0] < MAX_CYCLES


def test_missing_supersuit_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "supersuit", None)
    with pytest.raises(ImportError, match=r"pip install 'uav-swarm\[marl\]'"):
        supersuit_vec_env(2, **_kwargs())
