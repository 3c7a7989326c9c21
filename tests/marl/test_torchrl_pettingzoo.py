"""TorchRL's PettingZooWrapper over uav_swarm_v0: specs, and rollouts equal to the raw env's, step by step."""

import subprocess
import sys

import numpy as np
import pytest
import torch  # noqa: E402
from marl_world import SMALL_WORLD, random_actions, raw_trajectory  # noqa: E402
from tensordict import TensorDict  # noqa: E402
from torchrl.envs.utils import MarlGroupMapType, check_env_specs  # noqa: E402

from uav_swarm.env.parallel import parallel_env  # noqa: E402
from uav_swarm.marl import torchrl_env  # noqa: E402

N_UAVS, MAX_CYCLES, N_STEPS = 3, 25, 100  # four episodes per rollout
MODES = ("velocity", "waypoint")


def _kwargs(mode):
    return {"n_uavs": N_UAVS, "max_cycles": MAX_CYCLES, "action_mode": mode, **SMALL_WORLD}


def _per_agent(td, env, key):
    """(..., n_agents, ...) values of ``key`` gathered over the groups, in agent order."""
    return torch.cat([td.get((group, *key)) for group in env.group_map], dim=td.batch_dims)


@pytest.mark.parametrize("mode", MODES)
def test_specs_match_the_env_spaces(mode):
    env = torchrl_env(seed=0, return_state=True, **_kwargs(mode))
    raw = parallel_env(**_kwargs(mode))
    obs_space, act_space = raw.observation_space("uav_0"), raw.action_space("uav_0")
    assert env.group_map == {"agents": ["uav_0", "uav_1", "uav_2"]}
    obs_spec = env.observation_spec["agents", "observation"]
    assert obs_spec.shape == (N_UAVS, obs_space.shape[0]) and obs_spec.dtype == torch.float32
    np.testing.assert_array_equal(obs_spec.space.low.numpy(), np.tile(obs_space.low, (N_UAVS, 1)))
    np.testing.assert_array_equal(obs_spec.space.high.numpy(), np.tile(obs_space.high, (N_UAVS, 1)))
    act_spec = env.full_action_spec["agents", "action"]
    assert act_spec.shape == (N_UAVS, 2) and act_spec.dtype == torch.float32
    np.testing.assert_array_equal(act_spec.space.low.numpy(), np.tile(act_space.low, (N_UAVS, 1)))
    np.testing.assert_array_equal(act_spec.space.high.numpy(), np.tile(act_space.high, (N_UAVS, 1)))
    assert env.full_reward_spec["agents", "reward"].shape == (N_UAVS, 1)
    for key in ("done", "terminated", "truncated"):
        assert env.full_done_spec[key].shape == (1,)
        assert env.full_done_spec["agents", key].shape == (N_UAVS, 1)
    assert env.observation_spec["state"].shape == raw.state_space.shape
    assert set(env.observation_spec["agents", "info"].keys()) >= {"qos_s1", "qos_s2", "users_served"}
    check_env_specs(env, seed=1)


@pytest.mark.parametrize("group_map", ["agents", "per_agent"])
@pytest.mark.parametrize("mode", MODES)
def test_rollout_equals_the_raw_env(mode, group_map):
    """Rewards, observations, state, infos and done flags over four episodes, with automatic resets."""
    env = torchrl_env(group_map=group_map, return_state=True, **_kwargs(mode))
    actions = random_actions(parallel_env(**_kwargs(mode)), N_STEPS, seed=3)
    expected = raw_trajectory(_kwargs(mode), actions, seed=11)
    steps = iter(torch.from_numpy(actions))

    def policy(td):
        step_actions = next(steps)
        for group, agents in env.group_map.items():
            index = [int(agent.split("_")[1]) for agent in agents]
            td.set((group, "action"), step_actions[index])
        return td

    td = env.rollout(N_STEPS, policy, auto_reset=False, tensordict=env.reset(seed=11),
                     break_when_any_done=False)
    assert td.batch_size == (N_STEPS,)
    np.testing.assert_array_equal(_per_agent(td, env, ("action",)).numpy(), actions)
    np.testing.assert_allclose(_per_agent(td, env, ("observation",)).numpy(), expected["obs"][:-1])
    nxt = td["next"]
    np.testing.assert_allclose(_per_agent(nxt, env, ("observation",)).numpy(), expected["final_obs"])
    reward = _per_agent(nxt, env, ("reward",)).squeeze(-1).numpy()
    np.testing.assert_allclose(reward, np.repeat(expected["reward"][:, None], N_UAVS, 1), rtol=1e-6)
    assert expected["reward"].std() > 0  # the comparison is not between zeros
    qos = _per_agent(nxt, env, ("info", "qos_s1")).numpy()
    np.testing.assert_allclose(qos, np.repeat(expected["qos_s1"][:, None], N_UAVS, 1), rtol=1e-6)
    np.testing.assert_allclose(nxt["state"].numpy(), expected["state"], rtol=1e-6)

    at_end = (np.arange(1, N_STEPS + 1) % MAX_CYCLES) == 0
    np.testing.assert_array_equal(expected["truncated"], at_end)
    for key, flags in (("done", at_end), ("truncated", at_end), ("terminated", np.zeros(N_STEPS, bool))):
        np.testing.assert_array_equal(nxt[key].squeeze(-1).numpy(), flags)
        np.testing.assert_array_equal(
            _per_agent(nxt, env, (key,)).squeeze(-1).numpy(), np.repeat(flags[:, None], N_UAVS, 1))
    # After each episode end, the next root observation is a fresh reset, not the final one.
    ends = np.flatnonzero(at_end)[:-1]
    assert not np.allclose(expected["final_obs"][ends], expected["obs"][ends + 1])


def test_per_agent_groups_have_one_agent_each():
    env = torchrl_env(group_map="per_agent", seed=0, **_kwargs("velocity"))
    assert env.group_map == {f"uav_{i}": [f"uav_{i}"] for i in range(N_UAVS)}
    for group in env.group_map:
        assert env.full_action_spec[group, "action"].shape == (1, 2)
        assert env.full_reward_spec[group, "reward"].shape == (1, 1)
    check_env_specs(env, seed=2)


def test_group_map_passes_through_and_rejects_unknown_names():
    env = torchrl_env(group_map=MarlGroupMapType.ALL_IN_ONE_GROUP, seed=0, **_kwargs("velocity"))
    assert list(env.group_map) == ["agents"]
    env = torchrl_env(group_map={"left": ("uav_0",), "right": ("uav_1", "uav_2")}, seed=0,
                      **_kwargs("velocity"))
    assert env.full_action_spec["right", "action"].shape == (2, 2)
    td = env.rand_step(env.reset())
    assert isinstance(td, TensorDict)
    with pytest.raises(ValueError, match="group_map = 'everyone'"):
        torchrl_env(group_map="everyone", **_kwargs("velocity"))


def test_missing_torchrl_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "torchrl.envs.libs.pettingzoo", None)
    with pytest.raises(ImportError, match=r"pip install 'uav-swarm\[marl\]'"):
        torchrl_env(**_kwargs("velocity"))


def test_importing_the_package_imports_no_optional_library():
    code = ("import sys, uav_swarm.marl; "
            "print(sorted({'torch', 'torchrl', 'tensordict', 'supersuit'} & set(sys.modules)))")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "[]"
