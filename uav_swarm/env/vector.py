"""``uav_swarm_v0`` as a Gymnasium vector environment: :class:`UAVSwarmVectorEnv`, over BatchedUAVSwarm.

Each sub-environment is the joint team view of one copy: observation ``(n_agents, obs_dim)`` float32
(the agents' observations stacked in agent order), action ``(n_agents, 2)``, one shared team reward.
Auto-reset follows Gymnasium's modes:

- ``NEXT_STEP`` (default, as :class:`gymnasium.vector.SyncVectorEnv`): the step after a copy's episode
  ended resets that copy (its generator continued) instead of stepping it, and returns its reset
  observation with reward 0 and ``terminated = truncated = False``; its action is ignored (but validated).
- ``DISABLED`` (what TorchRL's ``GymWrapper`` prefers): nothing resets by itself; reset the finished copies
  with ``reset(options={"reset_mask": mask})`` before stepping them again.

Infos are a dict of arrays over the copies (no ``_key`` masks: every key is set for every copy); see
:meth:`BatchedUAVSwarm.step`.

Examples:
    >>> import numpy as np
    >>> envs = UAVSwarmVectorEnv(4, n_uavs=2, max_cycles=2)
    >>> obs, info = envs.reset(seed=0)
    >>> obs.shape, envs.action_space.shape
    ((4, 2, 260), (4, 2, 2))
    >>> for _ in range(3):
    ...     obs, reward, terminated, truncated, info = envs.step(envs.action_space.sample())
    >>> truncated.tolist(), reward.tolist()  # step 3 auto-reset every copy
    ([False, False, False, False], [0.0, 0.0, 0.0, 0.0])
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from uav_swarm.env.batched import BatchedUAVSwarm
from uav_swarm.env.config import EnvConfig
from uav_swarm.world.scenario import Scenario

__all__ = ["UAVSwarmVectorEnv"]


class UAVSwarmVectorEnv(VectorEnv):
    """``num_envs`` copies of ``uav_swarm_v0`` (team view) behind Gymnasium's vector API.

    Args:
        num_envs: Number of copies.
        config: The environment configuration (defaults otherwise).
        scene: Fixes the scene of every copy and episode.
        autoreset_mode: ``AutoresetMode.NEXT_STEP`` (default) or ``AutoresetMode.DISABLED`` (or their
            values, "NextStep" or "Disabled").
        **overrides: :class:`EnvConfig` fields, as for :class:`uav_swarm.env.parallel.raw_env`.

    Attributes:
        env: The :class:`BatchedUAVSwarm` core.
        autoreset_mode: The auto-reset mode (also ``metadata["autoreset_mode"]``).
    """

    metadata: dict[str, Any] = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    def __init__(
        self,
        num_envs: int,
        config: EnvConfig | None = None,
        scene: Scenario | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        **overrides: Any,
    ) -> None:
        mode = AutoresetMode(autoreset_mode)
        if mode not in (AutoresetMode.NEXT_STEP, AutoresetMode.DISABLED):
            raise ValueError(f"autoreset_mode = {mode}: choose NEXT_STEP or DISABLED")
        self.env = BatchedUAVSwarm(num_envs, config=config, scene=scene, **overrides)
        self.autoreset_mode = mode
        self.metadata = {**self.metadata, "autoreset_mode": mode}
        self.num_envs = self.env.num_envs
        n = self.env.n_agents
        obs, act = self.env.single_observation_space, self.env.single_action_space
        self.single_observation_space = spaces.Box(
            np.tile(obs.low, (n, 1)), np.tile(obs.high, (n, 1)), dtype=np.float32)
        self.single_action_space = spaces.Box(
            np.tile(act.low, (n, 1)), np.tile(act.high, (n, 1)), dtype=np.float32)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._autoreset = np.zeros(self.num_envs, dtype=bool)

    def reset(
        self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Reset all copies, or those of ``options["reset_mask"]`` (a ``(num_envs,)`` bool array).

        Args:
            seed: ``s``: copy ``k`` restarts from ``default_rng(s + k)``; a list: one seed (or None) per
                copy; None: each copy continues its generator.
            options: ``{"reset_mask": mask}`` resets only the copies in ``mask``; nothing else is read.
        """
        mask = None if options is None else options.get("reset_mask")
        obs, info = self.env.reset(seed=seed, mask=mask)
        self._autoreset[np.ones(self.num_envs, dtype=bool) if mask is None else np.asarray(mask)] = False
        return obs, info

    def step(
        self, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        """Step every copy (auto-resetting, in ``NEXT_STEP`` mode, those whose episode ended last step).

        Args:
            actions: ``(num_envs, n_agents, 2)`` actions.

        Returns:
            Observations ``(num_envs, n_agents, obs_dim)`` float32, team rewards ``(num_envs,)`` float64,
            terminated and truncated ``(num_envs,)`` bool, and the info arrays.
        """
        resetting = self._autoreset.copy()
        if resetting.any():
            self.env.reset(mask=resetting)
            obs, reward, terminated, truncated, info = self.env.step(actions, mask=~resetting)
            reward = np.where(resetting, 0.0, reward)
            terminated &= ~resetting
            truncated &= ~resetting
        else:
            obs, reward, terminated, truncated, info = self.env.step(actions)
        if self.autoreset_mode == AutoresetMode.NEXT_STEP:
            self._autoreset = terminated | truncated
        return obs, reward.astype(np.float64), terminated, truncated, info

    def state(self) -> np.ndarray:
        """``(num_envs, state_dim)`` float32 global states (raw_env's ``state()`` per copy)."""
        return self.env.state()
