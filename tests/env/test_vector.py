"""UAVSwarmVectorEnv behaves as gymnasium's SyncVectorEnv over single team-view raw_envs."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode, SyncVectorEnv

from uav_swarm.env.parallel import raw_env
from uav_swarm.env.vector import UAVSwarmVectorEnv

WORLD = {
    "scenario": {"n_groups_min": 2, "n_groups_max": 2, "group_size_min": 8, "group_size_max": 15},
    "density_shape": (16, 16),
    "patch_px": 5,
    "n_uavs": 3,
}


class TeamEnv(gymnasium.Env):
    """One raw_env as a single-agent gymnasium env: stacked observations, joint action, team reward."""

    def __init__(self, **kwargs):
        self.env = raw_env(**kwargs)
        agents = self.env.possible_agents
        obs, act = self.env.observation_space(agents[0]), self.env.action_space(agents[0])
        n = len(agents)
        self.observation_space = gymnasium.spaces.Box(np.tile(obs.low, (n, 1)), np.tile(obs.high, (n, 1)))
        self.action_space = gymnasium.spaces.Box(np.tile(act.low, (n, 1)), np.tile(act.high, (n, 1)))

    def reset(self, *, seed=None, options=None):
        obs, infos = self.env.reset(seed=seed)
        return np.stack(list(obs.values())), {}

    def step(self, action):
        agents = self.env.agents
        obs, rew, term, trunc, _ = self.env.step(dict(zip(agents, action, strict=True)))
        return np.stack(list(obs.values())), rew[agents[0]], term[agents[0]], trunc[agents[0]], {}


@pytest.mark.parametrize("mode", ["velocity", "waypoint"])
def test_next_step_autoreset_matches_sync_vector_env(mode):
    cfg = {**WORLD, "max_cycles": 4, "action_mode": mode}
    ours = UAVSwarmVectorEnv(3, **cfg)
    reference = SyncVectorEnv([lambda: TeamEnv(**cfg) for _ in range(3)],
                              autoreset_mode=AutoresetMode.NEXT_STEP)
    assert ours.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    assert ours.single_observation_space == reference.single_observation_space
    assert ours.single_action_space == reference.single_action_space
    assert ours.observation_space == reference.observation_space
    assert ours.action_space == reference.action_space
    obs, _ = ours.reset(seed=21)
    ref_obs, _ = reference.reset(seed=21)
    np.testing.assert_allclose(obs, ref_obs, rtol=1e-6, atol=1e-6)
    ours.action_space.seed(0)
    for step in range(11):  # two auto-resets (steps 5 and 10), the new episodes continue the generators
        actions = ours.action_space.sample()
        obs, reward, terminated, truncated, info = ours.step(actions)
        ref_obs, ref_reward, ref_terminated, ref_truncated, _ = reference.step(actions)
        np.testing.assert_allclose(obs, ref_obs, rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(reward, ref_reward, atol=1e-6)
        np.testing.assert_array_equal(terminated, ref_terminated)
        np.testing.assert_array_equal(truncated, ref_truncated)
        assert reward.dtype == np.float64 and ours.observation_space.contains(obs)
        assert truncated.all() == (step in (3, 8)), step
        assert set(info) >= {"qos_s1", "users_served"} and info["users_served"].shape == (3, 3)


def test_partial_reset_mask_and_seed_list():
    cfg = {**WORLD, "max_cycles": 50}
    ours = UAVSwarmVectorEnv(3, **cfg)
    reference = SyncVectorEnv([lambda: TeamEnv(**cfg) for _ in range(3)])
    np.testing.assert_allclose(ours.reset(seed=[1, 2, 3])[0], reference.reset(seed=[1, 2, 3])[0], atol=1e-6)
    actions = ours.action_space.sample()
    ours.step(actions)
    reference.step(actions)
    mask = np.array([False, True, True])
    obs, _ = ours.reset(seed=[None, 9, None], options={"reset_mask": mask})
    ref_obs, _ = reference.reset(seed=[None, 9, None], options={"reset_mask": mask})
    np.testing.assert_allclose(obs, ref_obs, atol=1e-6)
    for _ in range(3):
        actions = ours.action_space.sample()
        np.testing.assert_allclose(ours.step(actions)[0], reference.step(actions)[0], atol=1e-6)


def test_disabled_autoreset_leaves_finished_copies_to_the_caller():
    ours = UAVSwarmVectorEnv(2, **WORLD, max_cycles=2, autoreset_mode="Disabled")
    assert ours.metadata["autoreset_mode"] == AutoresetMode.DISABLED
    ours.reset(seed=0)
    zeros = np.zeros(ours.action_space.shape, dtype=np.float32)
    ours.step(zeros)
    assert ours.step(zeros)[3].all()
    with pytest.raises(RuntimeError, match="finished"):
        ours.step(zeros)
    ours.reset(options={"reset_mask": np.array([True, True])})
    assert not ours.step(zeros)[3].any()


def test_rejects_same_step_mode():
    with pytest.raises(ValueError, match="NEXT_STEP or DISABLED"):
        UAVSwarmVectorEnv(2, **WORLD, autoreset_mode=AutoresetMode.SAME_STEP)


def test_torchrl_gym_wrapper_rolls_out_with_partial_resets():
    import torchrl.envs as torchrl_envs
    venv = UAVSwarmVectorEnv(3, **WORLD, max_cycles=3, autoreset_mode=AutoresetMode.DISABLED)
    env = torchrl_envs.GymWrapper(venv)
    assert tuple(env.batch_size) == (3,)
    rollout = env.rollout(7, break_when_any_done=False)
    assert tuple(rollout["next", "observation"].shape) == (3, 7, 3, venv.env.obs_dim)
    truncated = rollout["next", "truncated"].squeeze(-1).numpy()
    np.testing.assert_array_equal(truncated.any(axis=0), [False, False, True, False, False, True, False])
