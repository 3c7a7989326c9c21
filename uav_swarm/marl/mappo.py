"""MAPPO on ``uav_swarm_v0`` with TorchRL's components (velocity actions, shared team reward).

The algorithm is TorchRL's, not ours: a :class:`torchrl.modules.MultiAgentMLP` actor with parameters
shared by all UAVs (decentralised: each UAV sees its own observation) giving a
:class:`torchrl.modules.TanhNormal` over its velocity command, a centralised critic (a
``MultiAgentMLP`` over all UAVs' observations, MAPPO's centralised value function),
:class:`torchrl.objectives.ClipPPOLoss` with generalised advantage estimation, and TorchRL's
``Collector`` over :class:`uav_swarm.marl.torchrl_batched.UAVSwarmTorchRLEnv` (``num_envs`` worlds
stepped together). Observations are standardised by a fixed per-feature normalisation measured once
on a random-action rollout (saved with the policy).

Outputs of :func:`train_mappo` in ``out``: ``checkpoint.pt`` (resumable: networks, optimiser,
progress; written atomically every ``checkpoint_every`` iterations and at the end), ``policy.pt``
(what :func:`load_policy` reads), ``curve.csv`` and ``curve.png`` (the mean team reward per step
of each collected batch against frames, with the random-action level), ``summary.json``.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import logging
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
import torch
from torch import nn

from typed_config import Config, param
from typed_config.files import write_bytes_atomic, write_json_atomic, write_text_atomic
from uav_swarm.env.config import MAX_UAVS, EnvConfig
from uav_swarm.world.radio_config import RadioConfig

__all__ = ["MappoConfig", "train_mappo", "load_policy", "MappoPolicy", "FeatureNorm"]

logger = logging.getLogger(__name__)

_CHECKPOINT_FORMAT = "uav-swarm-mappo-1"


@dataclass(frozen=True)
class MappoConfig(Config):
    """Settings of a MAPPO training run (``uav-swarm rl-train``)."""

    seed: int = param(0, ge=0, doc="seed of the worlds, the networks and the sampling")
    n_uavs: int = param(MAX_UAVS, ge=1, le=MAX_UAVS, doc="UAVs (agents) per world")
    strategy: int = param(1, ge=1, le=2, doc="the team reward's QoS strategy")
    max_cycles: int = param(600, ge=10, le=100_000, doc="steps of 0.1 s per training episode")
    num_envs: int = param(32, ge=1, le=4096, doc="worlds stepped together")
    frames_per_batch: int = param(6_400, ge=1, le=10_000_000,
                                  doc="world-steps per collected batch (all worlds together)")
    total_frames: int = param(2_000_000, ge=1, le=1_000_000_000, doc="world-steps to train for")
    max_minutes: float = param(55.0, gt=0.0, le=10_000.0,
                               doc="wall-clock budget: stop after the batch that passes it")
    epochs: int = param(4, ge=1, le=100, doc="PPO epochs per batch")
    minibatch_size: int = param(800, ge=1, le=10_000_000, doc="world-steps per PPO minibatch")
    lr: float = param(3e-4, gt=0.0, le=1.0, doc="Adam learning rate")
    gamma: float = param(0.98, gt=0.0, le=1.0, doc="discount")
    lmbda: float = param(0.95, ge=0.0, le=1.0, doc="GAE lambda")
    clip_epsilon: float = param(0.2, gt=0.0, le=1.0, doc="PPO clip")
    entropy_coeff: float = param(1e-3, ge=0.0, le=1.0, doc="entropy bonus weight")
    max_grad_norm: float = param(1.0, gt=0.0, le=1000.0, doc="gradient clipping")
    hidden: int = param(128, ge=8, le=4096, doc="hidden units per layer")
    depth: int = param(2, ge=1, le=8, doc="hidden layers")
    torch_threads: int = param(2, ge=1, le=256, doc="torch CPU threads")
    checkpoint_every: int = param(10, ge=1, le=100_000, doc="iterations between two checkpoints")
    action_mode: Literal["velocity"] = param("velocity",
                                             doc="actions: velocity commands (the issue's setting)")

    def env_config(self) -> EnvConfig:
        """The environment: the Wi-Fi world of ``uav-swarm simulate`` with velocity actions.

        On the paper's radio, which the shipped baseline and its comparison table were trained and measured
        on (the environment's default is the 802.11 radio).
        """
        return EnvConfig(n_uavs=self.n_uavs, action_mode=self.action_mode, strategy=self.strategy,
                         max_cycles=self.max_cycles, radio=RadioConfig())


class FeatureNorm(nn.Module):
    """Fixed standardisation ``(x - mean) / std`` of each observation feature (buffers, saved)."""

    mean: torch.Tensor
    std: torch.Tensor

    def __init__(self, mean: torch.Tensor, std: torch.Tensor) -> None:
        super().__init__()
        self.register_buffer("mean", mean.clone().float())
        self.register_buffer("std", std.clone().float())

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Standardise ``x`` (..., features)."""
        return (x - self.mean) / self.std


def _networks(config: MappoConfig, obs_dim: int, norm: FeatureNorm) -> tuple[nn.Module, nn.Module]:
    """The actor (loc and scale per UAV) and the centralised critic, both behind ``norm``."""
    from tensordict.nn import NormalParamExtractor
    from torchrl.modules import MultiAgentMLP

    common = {"n_agents": config.n_uavs, "share_params": True, "depth": config.depth,
              "num_cells": config.hidden, "activation_class": nn.Tanh}
    actor = nn.Sequential(norm, MultiAgentMLP(obs_dim, 2 * 2, centralized=False, **common),
                          NormalParamExtractor())
    critic = nn.Sequential(norm, MultiAgentMLP(obs_dim, 1, centralized=True, **common))
    return actor, critic


def _actor(env: Any, actor_net: nn.Module) -> Any:
    from tensordict.nn import TensorDictModule
    from torchrl.modules import ProbabilisticActor, TanhNormal

    group = env.group
    spec = env.full_action_spec_unbatched[group, "action"]
    module = TensorDictModule(actor_net, in_keys=[(group, "observation")],
                              out_keys=[(group, "loc"), (group, "scale")])
    return ProbabilisticActor(
        module=module, spec=env.full_action_spec_unbatched, in_keys=[(group, "loc"), (group, "scale")],
        out_keys=[(group, "action")], distribution_class=TanhNormal,
        distribution_kwargs={"low": spec.space.low, "high": spec.space.high}, return_log_prob=True)


def _observation_norm(env: Any, frames: int, seed: int) -> tuple[FeatureNorm, float]:
    """Per-feature mean and std of a random-action rollout of ``frames`` world-steps, and its mean reward."""
    torch.manual_seed(seed)
    steps = max(1, frames // env.batch_size[0])
    rollout = env.rollout(steps, break_when_any_done=False)
    obs = rollout["next", env.group, "observation"]
    obs = obs.reshape(-1, obs.shape[-1])
    reward = rollout["next", env.group, "reward"].mean().item()
    std = obs.std(dim=0)
    return FeatureNorm(obs.mean(dim=0), torch.where(std > 1e-6, std, torch.ones_like(std))), reward


def train_mappo(config: MappoConfig, out: str | Path, *, resume: bool = False, progress: bool = True
                ) -> dict[str, Any]:
    """Train MAPPO and write the outputs (module docstring) into ``out``.

    Args:
        config: The run's settings.
        out: Output folder (created).
        resume: Continue from ``out/checkpoint.pt`` with ``config`` (which may raise ``total_frames`` or
            ``max_minutes``; the networks and the task must be the checkpoint's); the worlds restart.
        progress: Show a progress bar (on a terminal only: none in a log or a pipe).

    Returns:
        The summary written to ``summary.json``.

    Raises:
        FileNotFoundError: ``resume`` without ``out/checkpoint.pt``.
        ValueError: ``resume`` with other networks or another task than the checkpoint's.
    """
    from tensordict.nn import TensorDictModule
    from torchrl.collectors import Collector
    from torchrl.data.replay_buffers import ReplayBuffer
    from torchrl.data.replay_buffers.samplers import SamplerWithoutReplacement
    from torchrl.data.replay_buffers.storages import LazyTensorStorage
    from torchrl.objectives import ClipPPOLoss, ValueEstimators
    from tqdm import tqdm

    from uav_swarm.marl.torchrl_batched import UAVSwarmTorchRLEnv

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    state = torch.load(out / "checkpoint.pt", weights_only=False) if resume else None
    if state is not None:
        _check_resumable(MappoConfig.from_dict(state["config"]), config)
    torch.set_num_threads(config.torch_threads)
    torch.manual_seed(config.seed)
    iteration = 0 if state is None else state["iteration"]
    env = UAVSwarmTorchRLEnv(config.num_envs, config.env_config(), seed=config.seed + 1_000_003 * iteration)
    group, obs_dim = env.group, env.world.obs_dim
    if state is None:
        norm, random_reward = _observation_norm(env, config.frames_per_batch, config.seed)
    else:
        norm = FeatureNorm(state["norm"]["mean"], state["norm"]["std"])
        random_reward = state["random_reward"]
    actor_net, critic_net = _networks(config, obs_dim, norm)
    policy = _actor(env, actor_net)
    critic = TensorDictModule(critic_net, in_keys=[(group, "observation")], out_keys=[(group, "state_value")])
    loss = ClipPPOLoss(actor_network=policy, critic_network=critic, clip_epsilon=config.clip_epsilon,
                       entropy_coeff=config.entropy_coeff, normalize_advantage=True,
                       normalize_advantage_exclude_dims=(-2,))  # per agent
    loss.set_keys(reward=(group, "reward"), action=(group, "action"), value=(group, "state_value"),
                  done=(group, "done"), terminated=(group, "terminated"))
    loss.make_value_estimator(ValueEstimators.GAE, gamma=config.gamma, lmbda=config.lmbda)
    optimiser = torch.optim.Adam(loss.parameters(), lr=config.lr)
    history: list[dict[str, float]] = []
    frames_done = 0
    if state is not None:
        actor_net.load_state_dict(state["actor"])
        critic_net.load_state_dict(state["critic"])
        optimiser.load_state_dict(state["optimiser"])
        history, frames_done = state["history"], state["frames"]

    remaining = max(0, config.total_frames - frames_done)
    frames_per_batch = config.frames_per_batch - config.frames_per_batch % config.num_envs or config.num_envs
    collector = Collector(env, policy, frames_per_batch=frames_per_batch,
                          total_frames=max(remaining, frames_per_batch),
                          auto_register_policy_transforms=False)
    buffer = ReplayBuffer(storage=LazyTensorStorage(frames_per_batch), sampler=SamplerWithoutReplacement(),
                          batch_size=config.minibatch_size)
    start = time.perf_counter() - (history[-1]["elapsed_s"] if history else 0.0)
    bar = tqdm(total=config.total_frames, initial=frames_done, unit="frame",
               disable=None if progress else True)
    for batch in collector:
        if frames_done >= config.total_frames:
            break
        shape = batch.get(("next", group, "reward")).shape
        for key in ("done", "terminated"):
            batch.set(("next", group, key), batch.get(("next", key)).unsqueeze(-1).expand(shape))
        with torch.no_grad():
            loss.value_estimator(batch, params=loss.critic_network_params,
                                 target_params=loss.target_critic_network_params)
        buffer.extend(batch.reshape(-1))
        totals = {"loss_objective": 0.0, "loss_critic": 0.0, "loss_entropy": 0.0}
        n_updates = 0
        for _ in range(config.epochs):
            for _ in range(max(1, frames_per_batch // config.minibatch_size)):
                values = loss(buffer.sample())
                total = values["loss_objective"] + values["loss_critic"] + values["loss_entropy"]
                optimiser.zero_grad()
                total.backward()
                nn.utils.clip_grad_norm_(loss.parameters(), config.max_grad_norm)
                optimiser.step()
                for key in totals:
                    totals[key] += float(values[key].detach())
                n_updates += 1
        collector.update_policy_weights_()
        iteration += 1
        frames_done += batch.numel()
        info = batch.get(("next", group, "info"))
        row = {"iteration": iteration, "frames": frames_done, "elapsed_s": time.perf_counter() - start,
               "mean_reward": float(batch.get(("next", group, "reward")).mean()),
               "mean_qos_s1": float(info["qos_s1"].mean()), "mean_qos_s2": float(info["qos_s2"].mean()),
               **{key: value / n_updates for key, value in totals.items()}}
        history.append(row)
        bar.update(batch.numel())
        bar.set_postfix(reward=f"{row['mean_reward']:.3f}", qos_s1=f"{row['mean_qos_s1']:.3f}")
        over_time = row["elapsed_s"] > 60.0 * config.max_minutes
        if iteration % config.checkpoint_every == 0:  # the last one is saved after the loop
            _save(out, config, actor_net, critic_net, norm, optimiser, iteration, frames_done, history,
                  random_reward)
        if over_time:
            logger.info("stopping after %.1f min (max_minutes = %s)", row["elapsed_s"] / 60,
                        config.max_minutes)
            break
    bar.close()
    collector.shutdown()
    _save(out, config, actor_net, critic_net, norm, optimiser, iteration, frames_done, history, random_reward)
    return _write_outputs(out, config, history, random_reward)


def _check_resumable(saved: MappoConfig, config: MappoConfig) -> None:
    """Refuse to resume with other networks or another task than the checkpoint's."""
    fixed = ("n_uavs", "strategy", "action_mode", "hidden", "depth", "max_cycles")
    changed = [f"{name} ({getattr(saved, name)} -> {getattr(config, name)})" for name in fixed
               if getattr(saved, name) != getattr(config, name)]
    if changed:
        raise ValueError("cannot resume: the checkpoint was trained with other settings: "
                         + ", ".join(changed))


def _save(out: Path, config: MappoConfig, actor_net: nn.Module, critic_net: nn.Module, norm: FeatureNorm,
          optimiser: torch.optim.Optimizer, iteration: int, frames: int, history: list[dict[str, float]],
          random_reward: float) -> None:
    """Write ``checkpoint.pt`` (resumable) and ``policy.pt`` (the actor), atomically."""
    common = {"format": _CHECKPOINT_FORMAT, "config": config.to_dict(), "obs_dim": int(norm.mean.numel()),
              "norm": {"mean": norm.mean, "std": norm.std}, "actor": actor_net.state_dict(),
              "iteration": iteration, "frames": frames, "random_reward": random_reward}
    for name, payload in (("checkpoint.pt", {**common, "critic": critic_net.state_dict(),
                                             "optimiser": optimiser.state_dict(), "history": history}),
                          ("policy.pt", common)):
        buffer = io.BytesIO()
        torch.save(payload, buffer)
        write_bytes_atomic(out / name, buffer.getvalue())


def _write_outputs(out: Path, config: MappoConfig, history: list[dict[str, float]], random_reward: float
                   ) -> dict[str, Any]:
    """``curve.csv``, ``curve.png`` and ``summary.json``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if history:
        text = io.StringIO()
        writer = csv.DictWriter(text, fieldnames=list(history[0]))
        writer.writeheader()
        writer.writerows(history)
        write_text_atomic(out / "curve.csv", text.getvalue())
        figure, axis = plt.subplots(figsize=(7, 4))
        frames = [row["frames"] for row in history]
        reward = np.array([row["mean_reward"] for row in history])
        axis.plot(frames, reward, color="tab:blue", alpha=0.35, label="MAPPO, each training batch")
        # A batch holds one part of the worlds' episodes (they start together): average over an episode.
        window = min(len(reward), max(1, -(-config.max_cycles * config.num_envs // config.frames_per_batch)))
        smooth = np.convolve(reward, np.ones(window) / window, mode="valid")
        axis.plot(frames[window - 1:], smooth, color="tab:blue", label=f"MAPPO, mean of {window} batches")
        axis.axhline(random_reward, color="grey", linestyle="--", label="random actions")
        axis.set(xlabel="world-steps (all worlds)", ylabel="mean team reward per step",
                 title=f"MAPPO on uav_swarm_v0: {config.n_uavs} UAVs, strategy {config.strategy}")
        axis.legend(loc="lower right")
        figure.tight_layout()
        buffer = io.BytesIO()
        figure.savefig(buffer, format="png", dpi=100)
        plt.close(figure)
        write_bytes_atomic(out / "curve.png", buffer.getvalue())
    last = history[-10:]
    summary = {
        "config": config.to_dict(), "iterations": len(history),
        "frames": history[-1]["frames"] if history else 0,
        "elapsed_s": history[-1]["elapsed_s"] if history else 0.0,
        "random_reward": random_reward,
        "final_mean_reward": float(np.mean([row["mean_reward"] for row in last])) if last else None,
        "final_mean_qos_s1": float(np.mean([row["mean_qos_s1"] for row in last])) if last else None,
    }
    write_json_atomic(out / "summary.json", summary)
    return summary


@dataclasses.dataclass
class MappoPolicy:
    """A trained MAPPO actor, deterministic (the mean action), for numpy observations.

    Attributes:
        config: The training run's settings (its environment is the one to act in).
        actor: ``(n, obs_dim)`` -> loc/scale network.
    """

    config: MappoConfig
    actor: nn.Module

    @torch.inference_mode()
    def act(self, observations: np.ndarray) -> np.ndarray:
        """``(n_uavs, 2)`` velocity commands in [-1, 1] for ``(n_uavs, obs_dim)`` observations."""
        loc, _ = self.actor(torch.as_tensor(np.asarray(observations, np.float32))[None])
        return torch.tanh(loc[0]).numpy()


def load_policy(path: str | Path) -> MappoPolicy:
    """Load ``policy.pt`` (or ``checkpoint.pt``) written by :func:`train_mappo`.

    Raises:
        ValueError: Not a MAPPO checkpoint of this format.
    """
    state = torch.load(Path(path), map_location="cpu", weights_only=False)
    if not isinstance(state, dict) or state.get("format") != _CHECKPOINT_FORMAT:
        raise ValueError(f"{path}: not a MAPPO policy written by uav-swarm rl-train ({_CHECKPOINT_FORMAT})")
    config = MappoConfig.from_dict(state["config"])
    norm = FeatureNorm(state["norm"]["mean"], state["norm"]["std"])
    actor, _ = _networks(config, state["obs_dim"], norm)
    actor.load_state_dict(state["actor"])
    actor.eval()
    return MappoPolicy(config, actor)
