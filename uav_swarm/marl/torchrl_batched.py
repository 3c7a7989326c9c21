"""TorchRL view of the batched environment: many copies of ``uav_swarm_v0`` as one ``EnvBase``.

:class:`UAVSwarmTorchRLEnv` wraps :class:`uav_swarm.env.batched.BatchedUAVSwarm` the way TorchRL's
own VMAS wrapper exposes a vectorised multi-agent simulator: ``batch_size = (num_envs,)`` and all
agents in one group, ``"agents"``:

================================  ===================  =========================================
key                               shape                meaning
================================  ===================  =========================================
``("agents", "observation")``     ``(B, n, obs_dim)``  each UAV's observation (as ``uav_swarm_v0``)
``("agents", "action")``          ``(B, n, 2)``        each UAV's action (the env's ``Box``)
``("agents", "reward")``          ``(B, n, 1)``        the shared team reward, per agent
``"state"``                       ``(B, state_dim)``   the global state (density map, positions)
``("agents", "info", key)``       ``(B, n)``           ``qos_s1``, ``qos_s2``, ``mean_throughput_mbps``
``"done"``, ``"terminated"``,     ``(B, 1)``           episode ends (truncation at ``max_cycles``)
``"truncated"``
================================  ===================  =========================================

A reset with a ``"_reset"`` mask (what TorchRL's collectors send for the copies whose episode
ended) draws new worlds for those copies only. ``set_seed(s)`` seeds the next reset: copy ``k``
uses seed ``s + k``, as :class:`BatchedUAVSwarm` documents.

Examples:
    >>> env = UAVSwarmTorchRLEnv(num_envs=4, n_uavs=3, max_cycles=5)
    >>> rollout = env.rollout(5)
    >>> rollout["next", "agents", "reward"].shape
    torch.Size([4, 5, 3, 1])
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from uav_swarm.env.batched import BatchedUAVSwarm
from uav_swarm.env.config import EnvConfig

__all__ = ["UAVSwarmTorchRLEnv", "INFO_KEYS"]

INFO_KEYS = ("qos_s1", "qos_s2", "mean_throughput_mbps")
"""Team measures copied into ``("agents", "info")`` at every step."""


class UAVSwarmTorchRLEnv(EnvBase):
    """``num_envs`` copies of ``uav_swarm_v0`` stepped together, as a TorchRL environment.

    Args:
        num_envs: Number of copies (the batch size).
        config: The environment settings (default ``EnvConfig()``).
        seed: Seed of the first reset (copy ``k`` gets ``seed + k``); None draws fresh entropy.
        **overrides: ``EnvConfig`` fields, as for ``uav_swarm.env.parallel.raw_env``.
    """

    group = "agents"

    def __init__(self, num_envs: int, config: EnvConfig | None = None, seed: int | None = None,
                 **overrides: Any) -> None:
        self.world = BatchedUAVSwarm(num_envs, config, **overrides)
        super().__init__(batch_size=torch.Size([num_envs]), device="cpu")
        self._next_seed = seed
        self._make_specs()

    @property
    def n_agents(self) -> int:
        """Number of UAVs per copy."""
        return self.world.n_agents

    def _make_specs(self) -> None:
        b, n = self.batch_size[0], self.world.n_agents
        obs_space, act_space = self.world.single_observation_space, self.world.single_action_space
        agent_shape = torch.Size([b, n])

        def box(space: Any) -> Bounded:
            low = torch.as_tensor(space.low, dtype=torch.float32).expand(*agent_shape, *space.shape)
            high = torch.as_tensor(space.high, dtype=torch.float32).expand(*agent_shape, *space.shape)
            return Bounded(low=low.clone(), high=high.clone(), shape=(*agent_shape, *space.shape),
                           dtype=torch.float32)

        info = Composite({key: Unbounded(shape=agent_shape, dtype=torch.float32) for key in INFO_KEYS},
                         shape=agent_shape)
        self.observation_spec = Composite(
            {self.group: Composite({"observation": box(obs_space), "info": info}, shape=agent_shape),
             "state": Bounded(low=0.0, high=1.0, shape=(b, self.world.state_dim), dtype=torch.float32)},
            shape=self.batch_size)
        self.action_spec = Composite(
            {self.group: Composite({"action": box(act_space)}, shape=agent_shape)}, shape=self.batch_size)
        self.reward_spec = Composite(
            {self.group: Composite({"reward": Unbounded(shape=(b, n, 1), dtype=torch.float32)},
                                   shape=agent_shape)}, shape=self.batch_size)
        flag = Categorical(n=2, shape=(b, 1), dtype=torch.bool)
        self.done_spec = Composite(
            {"done": flag, "terminated": flag.clone(), "truncated": flag.clone()}, shape=self.batch_size)

    def _observation_td(self, obs: np.ndarray, info: dict[str, np.ndarray]) -> dict[str, Any]:
        b, n = self.batch_size[0], self.world.n_agents
        agents = {"observation": torch.from_numpy(np.ascontiguousarray(obs, dtype=np.float32))}
        values = {key: torch.from_numpy(np.asarray(info[key], np.float32))[:, None].expand(b, n).clone()
                  for key in INFO_KEYS}
        agents["info"] = TensorDict(values, batch_size=[b, n])
        return {self.group: TensorDict(agents, batch_size=[b, n]),
                "state": torch.from_numpy(np.ascontiguousarray(self.world.state(), dtype=np.float32))}

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs: Any) -> TensorDictBase:
        mask = None
        if tensordict is not None and "_reset" in tensordict.keys():
            mask = tensordict.get("_reset").reshape(-1).numpy().astype(bool)
        seed, self._next_seed = self._next_seed, None
        obs, info = self.world.reset(seed=seed, mask=mask)
        b = self.batch_size[0]
        no = torch.zeros(b, 1, dtype=torch.bool)
        source = self._observation_td(obs, info)
        source.update({"done": no, "terminated": no.clone(), "truncated": no.clone()})
        return TensorDict(source, batch_size=self.batch_size)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        actions = tensordict.get((self.group, "action")).detach().numpy()
        obs, reward, terminated, truncated, info = self.world.step(actions)
        b, n = self.batch_size[0], self.world.n_agents
        source = self._observation_td(obs, info)
        team = torch.from_numpy(np.asarray(reward, dtype=np.float32))
        source[self.group]["reward"] = team[:, None, None].expand(b, n, 1).clone()
        term = torch.from_numpy(np.asarray(terminated, dtype=bool))[:, None]
        trunc = torch.from_numpy(np.asarray(truncated, dtype=bool))[:, None]
        source.update({"done": term | trunc, "terminated": term, "truncated": trunc})
        return TensorDict(source, batch_size=self.batch_size)

    def _set_seed(self, seed: int | None) -> None:
        self._next_seed = seed
