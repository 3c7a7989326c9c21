"""The baseline table of ``uav_swarm_v0``: random actions, MAPPO, the learned planner and the expert.

Every controller flies the same held-out episodes (seed ``seed + e`` for episode ``e``: the same
scenario, crowd and UAV start positions, since the action mode draws nothing), in the world of
``uav-swarm simulate`` (the Wi-Fi task's scenario, crowd and radio), for ``duration_s`` of simulated
time at 0.1 s per step:

- ``random``: velocity actions drawn uniformly from the action box (seeded);
- ``mappo``: a policy trained by :func:`uav_swarm.marl.mappo.train_mappo`, velocity actions, the
  deterministic (mean) action;
- ``learned`` and ``expert``: the placement planners (:mod:`uav_swarm.planning.planner`) in waypoint mode,
  replanning every ``replan_every`` steps from the live crowd, as ``uav-swarm simulate`` flies them.
  Their episodes fly in lockstep, one world each, and every replan plans all of them at once
  (:func:`uav_swarm.planning.batch.plan_batch`: the learned planner's network runs once per replan on
  the batch of worlds, each world keeping its own sequence state), which gives every episode the
  targets it would get alone.

Measures per controller, over all steps of all episodes: mean QoS S1, mean QoS S2, mean user
throughput, and the decision time per step (the controller's wall time, planners' replans included,
divided by the steps), with the mean time of one replan for the planners.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from tqdm import tqdm

from uav_swarm.env.config import EnvConfig
from uav_swarm.env.parallel import parallel_env

if TYPE_CHECKING:
    from uav_swarm.planning.planner import Planner
    from uav_swarm.runs.simulate_config import SimulateConfig

__all__ = ["ControllerScore", "CONTROLLERS", "compare_controllers"]

CONTROLLERS = ("random", "mappo", "learned", "expert")
"""The controllers :func:`compare_controllers` knows."""


@dataclass(frozen=True)
class ControllerScore:
    """One row of the table (means over every step of every episode)."""

    controller: str
    episodes: int
    steps: int
    mean_qos_s1: float
    mean_qos_s2: float
    mean_throughput_mbps: float
    decision_ms_per_step: float
    replan_ms: float | None


def _episode(env_config: EnvConfig, seed: int, decide: Callable[[int, dict, Any], dict], steps: int
             ) -> tuple[np.ndarray, float]:
    """Fly one episode; returns ``(steps, 3)`` QoS S1, QoS S2, throughput and the decision seconds."""
    env = parallel_env(config=env_config.replace(max_cycles=steps))
    observations, _ = env.reset(seed=seed)
    measures = np.zeros((steps, 3))
    spent = 0.0
    for step in range(steps):
        start = time.perf_counter()
        actions = decide(step, observations, env)
        spent += time.perf_counter() - start
        observations, _, _, _, _ = env.step(actions)
        cov = env.coverage
        measures[step] = cov.qos_s1, cov.qos_s2, cov.mean_throughput_mbps
    return measures, spent


def _planned_episodes(env_config: EnvConfig, seeds: list[int], planner: Planner, replan_every: int,
                      steps: int, progress: bool) -> tuple[list[np.ndarray], float]:
    """Fly one episode per seed in lockstep, all worlds replanned together; measures and planning seconds."""
    from uav_swarm.planning.batch import plan_batch

    envs = [parallel_env(config=env_config.replace(max_cycles=steps)) for _ in seeds]
    for env, seed in zip(envs, seeds, strict=True):
        env.reset(seed=seed)
    planners = [planner.fork() for _ in seeds]  # type: ignore[attr-defined]
    held: list[dict] = [{} for _ in seeds]
    measures = np.zeros((len(seeds), steps, 3))
    spent = 0.0
    for step in tqdm(range(steps), desc=planner.name, unit="step", disable=None if progress else True,
                     leave=False):
        start = time.perf_counter()
        if step % replan_every == 0:
            results = plan_batch(planners, [env.pedestrian_positions_m for env in envs],
                                 [env.uav_positions_m for env in envs],
                                 [env.pedestrian_velocities_m_s for env in envs])
            for targets, env, result in zip(held, envs, results, strict=True):
                targets.update(zip(env.agents, result.targets_m, strict=True))
        spent += time.perf_counter() - start
        for episode, env in enumerate(envs):
            env.step(dict(held[episode]))
            cov = env.coverage
            measures[episode, step] = cov.qos_s1, cov.qos_s2, cov.mean_throughput_mbps
    return list(measures), spent


def compare_controllers(controllers: list[str], *, episodes: int = 20, seed: int = 100_000,
                        duration_s: float = 60.0, n_uavs: int = 10, strategy: int = 1, replan_every: int = 10,
                        mappo_policy: str | Path | None = None, checkpoint: str | Path | None = None,
                        progress: bool = False) -> list[ControllerScore]:
    """Score each controller on the same ``episodes`` held-out episodes (module docstring).

    Args:
        controllers: Names from :data:`CONTROLLERS`.
        episodes: Number of episodes (seeds ``seed .. seed + episodes - 1``).
        seed: First episode's seed (the default lies outside the training seeds of ``rl-train``).
        duration_s: Simulated seconds per episode (0.1 s per step).
        n_uavs: UAVs.
        strategy: The environment's reward strategy (both QoS are measured either way).
        replan_every: Steps between two replans of the planners.
        mappo_policy: ``policy.pt`` of ``rl-train`` (needed for ``mappo``).
        checkpoint: The learned planner's checkpoint (default: the shipped one).
        progress: Show a progress bar per controller (on a terminal only).

    Raises:
        ValueError: An unknown controller, or ``mappo`` without a policy.
    """
    from uav_swarm.missions.wifi.task import WifiConfig
    from uav_swarm.runs.simulate_config import SimulateConfig

    unknown = [name for name in controllers if name not in CONTROLLERS]
    if unknown:
        raise ValueError(f"unknown controller(s) {unknown}: choose from {list(CONTROLLERS)}")
    if "mappo" in controllers and mappo_policy is None:
        raise ValueError("the mappo controller needs a policy file (--policy, written by uav-swarm rl-train)")
    # the paper's radio, which the MAPPO baseline was trained on (simulate's default is the 802.11 radio)
    world = SimulateConfig(n_uavs=n_uavs, duration_s=duration_s, replan_every=replan_every,
                           task=WifiConfig(strategy=strategy))
    velocity = world.env_config().replace(action_mode="velocity")
    steps = world.n_steps
    scores = []
    for name in controllers:
        env_config, decide, planner = _controller(name, velocity, world, mappo_policy, checkpoint, seed)
        if planner is not None:
            measures, spent = _planned_episodes(env_config, [seed + e for e in range(episodes)], planner,
                                                replan_every, steps, progress)
        elif decide is not None:
            measures, spent = [], 0.0
            for episode in tqdm(range(episodes), desc=name, unit="episode",
                                disable=None if progress else True, leave=False):
                m, s = _episode(env_config, seed + episode, decide, steps)
                measures.append(m)
                spent += s
        all_steps = np.concatenate(measures)
        n_replans = episodes * -(-steps // replan_every)
        scores.append(ControllerScore(
            controller=name, episodes=episodes, steps=steps, mean_qos_s1=float(all_steps[:, 0].mean()),
            mean_qos_s2=float(all_steps[:, 1].mean()), mean_throughput_mbps=float(all_steps[:, 2].mean()),
            decision_ms_per_step=1e3 * spent / (episodes * steps),
            replan_ms=1e3 * spent / n_replans if planner is not None else None))
    return scores


def _controller(name: str, velocity: EnvConfig, world: SimulateConfig, mappo_policy: str | Path | None,
                checkpoint: str | Path | None, seed: int
                ) -> tuple[EnvConfig, Callable[[int, dict, Any], dict] | None, Planner | None]:
    """The environment settings and the decision function of a policy, or the planner of a planner."""
    if name == "random":
        rng = np.random.default_rng(seed)

        def random_actions(step: int, observations: dict, env: Any) -> dict:
            return {agent: rng.uniform(-1.0, 1.0, 2).astype(np.float32) for agent in observations}

        return velocity, random_actions, None
    if name == "mappo":
        if mappo_policy is None:
            raise ValueError("controller 'mappo' needs mappo_policy (the policy.pt of rl-train)")
        import torch

        from uav_swarm.marl.mappo import load_policy

        torch.set_num_threads(1)  # as the learned planner's default: one thread is the fastest at batch 1
        policy = load_policy(mappo_policy)
        if policy.config.n_uavs != velocity.n_uavs:
            raise ValueError(f"the MAPPO policy is for {policy.config.n_uavs} UAVs, "
                             f"the table for {velocity.n_uavs}")

        def mappo_actions(step: int, observations: dict, env: Any) -> dict:
            agents = list(observations)
            actions = policy.act(np.stack([observations[a] for a in agents]))
            return dict(zip(agents, actions, strict=True))

        return velocity, mappo_actions, None
    from uav_swarm.planning.planner import make_planner

    planner = make_planner(name, world.n_uavs, world.task, checkpoint=checkpoint or None,
                           config=world.planning, uav_config=world.uav)
    return world.env_config(), None, planner
