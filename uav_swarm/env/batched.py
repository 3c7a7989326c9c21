"""Many copies of ``uav_swarm_v0`` stepped together in numpy: :class:`BatchedUAVSwarm`.

Copy ``k`` behaves exactly as ``raw_env(config=cfg)`` (same scenario, crowd, UAV start positions,
observations, rewards, infos and state): both are shells over :class:`~uav_swarm.env.core.SwarmCore`,
raw_env over one world and this class over B, whose crowds advance in one
:class:`~uav_swarm.world.crowd_batch.BatchedCrowd` and whose UAVs are ``(B, n, 2)`` arrays.

Examples:
    >>> import numpy as np
    >>> envs = BatchedUAVSwarm(3, n_uavs=2, max_cycles=2)
    >>> obs, info = envs.reset(seed=7)  # copy k is raw_env's reset(seed=7 + k)
    >>> obs.shape, envs.state().shape
    ((3, 2, 260), (3, 4100))
    >>> obs, reward, terminated, truncated, info = envs.step(np.zeros((3, 2, 2)))
    >>> reward.shape, truncated.tolist(), info["users_served"].shape
    ((3,), [False, False, False], (3, 2))
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium import spaces

from uav_swarm.env.config import EnvConfig, merge_overrides
from uav_swarm.env.core import SwarmCore
from uav_swarm.world.crowd_batch import BatchedCrowd
from uav_swarm.world.scenario import Scenario

__all__ = ["BatchedUAVSwarm"]


class BatchedUAVSwarm:
    """``num_envs`` copies of ``uav_swarm_v0`` (:class:`uav_swarm.env.parallel.raw_env`) as one numpy batch.

    Arrays are batch-first: observations ``(B, n, obs_dim)`` float32, actions ``(B, n, 2)``, rewards
    ``(B,)`` float32 (the shared team reward), ``terminated`` / ``truncated`` ``(B,)`` bool, ``state()``
    ``(B, state_dim)`` float32. The spaces, units and rewards are raw_env's (its docstring).

    **Seeding.** Each copy owns one ``numpy.random.Generator`` that draws its scenario, crowd and UAV
    start positions in raw_env's order. ``reset(seed=s)`` gives copy ``k`` the generator
    ``default_rng(s + k)``, so copy ``k`` equals ``raw_env(config=cfg).reset(seed=s + k)``; a sequence
    gives one seed (or None) per copy; None continues each copy's generator.

    **Episode end.** No termination; a copy is truncated after ``max_cycles`` steps and stays finished:
    stepping it raises ``RuntimeError`` until ``reset(mask=...)`` resets it (no auto-reset here; see
    :class:`uav_swarm.env.vector.UAVSwarmVectorEnv`).

    Args:
        num_envs: Number of copies B (>= 1).
        config: The environment configuration (defaults otherwise).
        scene: Fixes the scene of every copy and episode (else each reset draws one per copy).
        **overrides: :class:`EnvConfig` fields, as for raw_env.
    """

    def __init__(
        self, num_envs: int, config: EnvConfig | None = None, scene: Scenario | None = None, **overrides: Any
    ) -> None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs = {num_envs!r} must be an integer >= 1")
        self.config = cfg = merge_overrides(config or EnvConfig(), overrides)
        self.num_envs = int(num_envs)
        self._core = core = SwarmCore(self.num_envs, cfg, scene)
        self.n_agents = cfg.n_uavs
        self.possible_agents = [f"uav_{i}" for i in range(cfg.n_uavs)]
        self.single_observation_space: spaces.Box = core.layout.observation_space()
        self.single_action_space: spaces.Box = core.layout.action_space()
        self.state_space: spaces.Box = core.layout.state_space()
        self.obs_dim, self.state_dim = core.layout.obs_dim, core.layout.state_dim
        self.width_m, self.height_m = core.width_m, core.height_m
        self.dt_s = core.dt_s
        self.radio = core.radio
        self._finished = np.zeros(self.num_envs, dtype=bool)
        self._reset_done = False

    # --- API ------------------------------------------------------------------------------

    def reset(
        self, seed: int | Sequence[int | None] | None = None, mask: np.ndarray | None = None
    ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Draw new scenarios, crowds and UAV start positions for all copies or those in ``mask``.

        Args:
            seed: ``s``: copy ``k`` restarts from ``default_rng(s + k)``; a sequence of B seeds (or None):
                one per copy; None: every copy continues its generator (seeded from entropy at first).
            mask: ``(B,)`` bool, the copies to reset (all by default); the others are untouched.

        Returns:
            Observations ``(B, n, obs_dim)`` (the untouched copies' unchanged) and the info arrays.

        Raises:
            ValueError: A seed sequence or mask of the wrong length, or an empty mask.
            RuntimeError: A partial reset before the first full one.
        """
        b = self.num_envs
        mask = np.ones(b, dtype=bool) if mask is None else np.asarray(mask)
        if mask.shape != (b,) or mask.dtype != bool or not mask.any():
            raise ValueError(f"mask must be a (num_envs,) = ({b},) bool array with a True, got {mask!r}")
        if not self._reset_done and not mask.all():
            raise RuntimeError("the first reset must reset every copy (mask=None)")
        self._core.reset(_per_copy_seeds(seed, b), np.flatnonzero(mask))
        self._reset_done = True
        self._finished[mask] = False
        return self._core.observations(), self._core.infos()

    def step(
        self, actions: np.ndarray, mask: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        """Apply one action per UAV of every copy and advance the copies by ``dt_s``.

        Args:
            actions: ``(B, n, 2)`` float or int; clipped into the action box like raw_env.
            mask: ``(B,)`` bool, the copies to step (all by default); the others do not move and their
                outputs describe their current state (rewards as of now, ``truncated`` as it stands).

        Returns:
            Observations ``(B, n, obs_dim)`` float32, rewards ``(B,)`` float32, terminated ``(B,)``
            (always False), truncated ``(B,)`` bool and the info arrays: ``qos_s1``, ``qos_s2``,
            ``mean_throughput_mbps``, ``separation_penalty``, ``closest_separation_m`` ``(B,)``;
            ``covered_users``, ``n_pedestrians`` ``(B,)`` int; ``users_served``, ``separation_held``
            ``(B, n)`` int; ``throughput_per_user_mbps`` ``(B, n)``.

        Raises:
            ValueError: Actions of another shape, a non-numeric dtype, or NaN/inf; a bad mask.
            RuntimeError: A stepped copy is finished (truncated) or the batch was never reset.
        """
        b = self.num_envs
        values = self._check_actions(actions)
        active = None if mask is None else np.asarray(mask)
        if active is not None and (active.shape != (b,) or active.dtype != bool):
            raise ValueError(f"mask must be a (num_envs,) = ({b},) bool array, got {active!r}")
        self._require_reset()
        stepped = self._finished if active is None else self._finished & active
        if stepped.any():
            raise RuntimeError(f"copies {np.flatnonzero(stepped).tolist()} are finished "
                               "(truncated): reset them with reset(mask=...) first")
        core = self._core
        core.step(values, active=None if active is None or active.all() else active)
        truncated = core.cycle >= self.config.max_cycles
        self._finished |= truncated
        terminated = np.zeros(b, dtype=bool)
        return core.observations(), core.reward.astype(np.float32), terminated, truncated, core.infos()

    def state(self) -> np.ndarray:
        """``(B, h*w + 2n)`` float32: each copy's share map and normalised UAV positions (raw_env's state)."""
        self._require_reset()
        return self._core.states()

    def set_channel_plan(self, channels: np.ndarray | None) -> None:
        """Each UAV's channel from the next step on (``propagation = "802.11"``).

        ``channels``: (n,) or (B, n) channel numbers; None: the environment plans them itself at every step
        (the default: ``plan_channels`` on the UAVs' positions, the plan in force kept while valid).

        Raises:
            ValueError: The paper's radio, or a channel outside ``radio.ieee80211``'s usable channels.
        """
        self._core.set_channel_plan(channels)

    def set_access_points(self, enabled: np.ndarray | None) -> None:
        """Which UAVs' access points are on from the next step on (``propagation = "802.11"``).

        ``enabled``: (n,) or (B, n) bool; an AP that is off transmits nothing, so it takes no airtime from the
        others (under admission on rate ``simulate`` turns off the AP of a UAV its plan gives no users).
        None: every AP on, the default.

        Raises:
            ValueError: The paper's radio, or a shape the environment does not take.
        """
        self._core.set_access_points(enabled)

    # --- accessors --------------------------------------------------------------------

    @property
    def crowd(self) -> BatchedCrowd:
        """All copies' crowds (``positions_m`` stacked; ``copy_index``, ``offsets``, ``scenarios``)."""
        self._require_reset()
        return self._core.batched_crowd

    @property
    def uav_positions_m(self) -> np.ndarray:
        """``(B, n, 2)`` UAV positions in metres (a copy)."""
        return self._core.positions_m.copy()

    @property
    def uav_velocities_m_s(self) -> np.ndarray:
        """``(B, n, 2)`` UAV velocities in m/s (a copy)."""
        return self._core.velocities_m_s.copy()

    @property
    def finished(self) -> np.ndarray:
        """``(B,)`` bool: copies truncated and not reset since."""
        return self._finished.copy()

    # --- internals --------------------------------------------------------------------

    def _require_reset(self) -> None:
        if not self._reset_done:
            raise RuntimeError("the batch has not been reset: call reset() first")

    def _check_actions(self, actions: Any) -> np.ndarray:
        shape = (self.num_envs, self.n_agents, 2)
        try:
            values = np.asarray(actions)
        except ValueError as error:  # ragged
            raise ValueError(f"actions must be an array of shape {shape}: {error}") from None
        if values.shape != shape:
            raise ValueError(f"actions must have shape (num_envs, n_agents, 2) = {shape}, got {values.shape}")
        if values.dtype.kind not in "fiu":
            raise ValueError(f"actions must be a float or int array, got dtype {values.dtype}")
        values = values.astype(np.float64, copy=False)
        finite = np.isfinite(values).all(axis=2)
        if not finite.all():
            bad = [(int(c), int(a)) for c, a in np.argwhere(~finite)[:5]]
            raise ValueError(f"actions contain NaN or inf at (copy, agent) {bad}")
        return values


def _per_copy_seeds(seed: int | Sequence[int | None] | None, n: int) -> list[int | None]:
    """One seed (or None) per copy: ``s + k`` for an int ``s``."""
    if seed is None:
        return [None] * n
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer, Sequence)):
        raise ValueError(f"seed must be an int, None or a sequence of num_envs = {n} seeds, got {seed!r}")
    if isinstance(seed, (int, np.integer)):
        return [int(seed) + k for k in range(n)]
    seeds = list(seed)
    if len(seeds) != n:
        raise ValueError(f"seed must be an int, None or a sequence of num_envs = {n} seeds, got {len(seeds)}")
    return seeds
