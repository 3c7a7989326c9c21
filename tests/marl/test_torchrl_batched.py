"""UAVSwarmTorchRLEnv: TorchRL's specs, equality with the raw env, partial resets, auto-reset in a rollout."""

import numpy as np
import pytest
import torch
from marl_world import SMALL_WORLD, raw_trajectory  # noqa: E402
from torchrl.envs.utils import check_env_specs  # noqa: E402

from uav_swarm.marl.torchrl_batched import UAVSwarmTorchRLEnv  # noqa: E402

N_UAVS, MAX_CYCLES = 3, 6


def make(num_envs: int = 3, seed: int = 5, **extra) -> UAVSwarmTorchRLEnv:
    return UAVSwarmTorchRLEnv(num_envs, seed=seed, n_uavs=N_UAVS, max_cycles=MAX_CYCLES, **SMALL_WORLD,
                              **extra)


def test_specs_follow_the_env_and_torchrl_accepts_them() -> None:
    env = make()
    check_env_specs(env)
    action = env.full_action_spec["agents", "action"]
    assert action.shape == (3, N_UAVS, 2)
    space = env.world.single_action_space
    np.testing.assert_array_equal(action.space.low[0, 0].numpy(), space.low)
    np.testing.assert_array_equal(action.space.high[0, 0].numpy(), space.high)
    assert env.full_observation_spec["agents", "observation"].shape == (3, N_UAVS, env.world.obs_dim)
    assert env.full_reward_spec["agents", "reward"].shape == (3, N_UAVS, 1)


@pytest.mark.parametrize("action_mode", ["velocity", "waypoint"])
def test_rollout_equals_separate_raw_envs_and_auto_resets(action_mode: str) -> None:
    """Copy k seeded s + k is the raw env seeded s + k, through two episode ends (collector-style resets)."""
    steps, seed = 2 * MAX_CYCLES + 3, 5
    env = make(seed=seed, action_mode=action_mode)
    rng = np.random.default_rng(1)
    space = env.world.single_action_space
    actions = rng.uniform(space.low, space.high, size=(3, steps, N_UAVS, 2)).astype(np.float32)
    td = env.reset()
    rewards, dones, observations = [], [], [td["agents", "observation"].numpy().copy()]
    for t in range(steps):
        td["agents", "action"] = torch.from_numpy(actions[:, t])
        out, td = env.step_and_maybe_reset(td)
        rewards.append(out["next", "agents", "reward"].numpy()[..., 0])
        dones.append(out["next", "done"].numpy()[:, 0])
        observations.append(td["agents", "observation"].numpy().copy())
    rewards, dones = np.stack(rewards, axis=1), np.stack(dones, axis=1)  # (3, T, n), (3, T)
    kwargs = {"n_uavs": N_UAVS, "max_cycles": MAX_CYCLES, "action_mode": action_mode, **SMALL_WORLD}
    for k in range(3):
        raw = raw_trajectory(kwargs, actions[k], seed + k)
        assert (rewards[k] == rewards[k][:, :1]).all()  # the team reward, copied to every agent
        np.testing.assert_allclose(rewards[k][:, 0], raw["reward"], rtol=1e-5, atol=1e-6)
        np.testing.assert_array_equal(dones[k], raw["truncated"])
        np.testing.assert_allclose(np.stack(observations, axis=1)[k], raw["obs"], rtol=1e-5, atol=1e-6)
    assert dones[:, MAX_CYCLES - 1].all() and dones.sum() == 3 * 2


def test_reset_mask_resets_only_those_copies() -> None:
    env = make(seed=9)
    td = env.reset()
    for _ in range(2):
        td["agents", "action"] = env.full_action_spec["agents", "action"].rand()
        td = env.step(td)["next"]
    before = td["agents", "observation"].clone()
    mask = torch.tensor([[False], [True], [False]])
    # as TorchRL's collectors do: the current tensordict with the copies to reset marked
    after = env.reset(td.clone().set("_reset", mask))["agents", "observation"]
    torch.testing.assert_close(after[0], before[0])
    torch.testing.assert_close(after[2], before[2])
    assert not torch.equal(after[1], before[1])


def test_same_seed_same_rollout() -> None:
    rollouts = []
    for _ in range(2):
        torch.manual_seed(0)  # the rollout's random actions
        rollouts.append(make(seed=3).rollout(2 * MAX_CYCLES, break_when_any_done=False))
    torch.testing.assert_close(rollouts[0], rollouts[1])
