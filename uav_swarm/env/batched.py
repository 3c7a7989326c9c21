"""Many copies of ``uav_swarm_v0`` stepped together in numpy: :class:`BatchedUAVSwarm`.

Copy ``k`` behaves exactly as ``raw_env(config=cfg)`` (same scenario, crowd, UAV start positions,
observations, rewards, infos and state) but all copies advance in one set of arrays: the crowds in a
:class:`~uav_swarm.world.crowd_batch.BatchedCrowd`, the UAVs as ``(B, n, 2)`` arrays, density maps in
one ``bincount`` and coverage over ``(n, N)`` distances of every pedestrian to its own copy's UAVs.

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
from numpy.lib.stride_tricks import sliding_window_view

from uav_swarm.env.config import MAX_UAVS, EnvConfig
from uav_swarm.env.parallel import raw_env
from uav_swarm.world.comms import Association
from uav_swarm.world.crowd import CrowdSim
from uav_swarm.world.crowd_batch import BatchedCrowd
from uav_swarm.world.scenario import Scenario, random_scenario

__all__ = ["BatchedUAVSwarm"]

_N_OTHERS = MAX_UAVS - 1
_N_STATS = 4


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
        template = raw_env(config=config, scene=scene, **overrides)  # spaces and constants, never reset
        self.config = cfg = template.config
        self.num_envs = int(num_envs)
        self.n_agents = cfg.n_uavs
        self.possible_agents = list(template.possible_agents)
        self.single_observation_space: spaces.Box = template.observation_space(self.possible_agents[0])
        self.single_action_space: spaces.Box = template.action_space(self.possible_agents[0])
        self.state_space: spaces.Box = template.state_space
        self.obs_dim = int(self.single_observation_space.shape[0])
        self.state_dim = int(self.state_space.shape[0])
        self.width_m, self.height_m = template.width_m, template.height_m
        self._area_m = np.array([self.width_m, self.height_m])
        self._scene = scene
        self.dt_s = template.dt_s
        self.radio = template.radio
        # Admission control keeps per-copy association state; the paper's model is computed for all at once.
        self._links = [Association(self.radio) for _ in range(self.num_envs)] \
            if self.radio.max_stations is not None else []
        self._obs_low = self.single_observation_space.low
        self._obs_high = self.single_observation_space.high
        self._act_low = self.single_action_space.low.astype(np.float64)
        self._act_high = self.single_action_space.high.astype(np.float64)
        n, p, (h, w) = cfg.n_uavs, cfg.patch_px, cfg.density_shape
        self._others = (np.repeat(np.arange(n), n - 1),
                        np.array([j for i in range(n) for j in range(n) if j != i], dtype=np.intp))
        self._px_per_m = np.array([w / self.width_m, h / self.height_m])
        self._last_px = np.array([w - 1, h - 1])
        b = self.num_envs
        self._padded_share_map = np.zeros((b, h + p - 1, w + p - 1), dtype=np.float32)  # zero border
        self._patch_windows = sliding_window_view(self._padded_share_map, (p, p), axis=(1, 2))
        self._rngs: list[np.random.Generator | None] = [None] * b
        self._crowd: BatchedCrowd | None = None
        self._positions_m = np.zeros((b, n, 2))
        self._velocities_m_s = np.zeros((b, n, 2))
        self._targets_m = np.zeros((b, n, 2))
        self._cycle = np.zeros(b, dtype=np.int64)
        self._finished = np.zeros(b, dtype=bool)

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
        b, cfg = self.num_envs, self.config
        mask = np.ones(b, dtype=bool) if mask is None else np.asarray(mask)
        if mask.shape != (b,) or mask.dtype != bool or not mask.any():
            raise ValueError(f"mask must be a (num_envs,) = ({b},) bool array with a True, got {mask!r}")
        if self._crowd is None and not mask.all():
            raise RuntimeError("the first reset must reset every copy (mask=None)")
        seeds = _per_copy_seeds(seed, b)
        copies = np.flatnonzero(mask)
        sims = []
        for c in copies:
            if seeds[c] is not None or self._rngs[c] is None:
                self._rngs[c] = np.random.default_rng(seeds[c])
            rng = self._rngs[c]
            scenario = self._scene if self._scene is not None else random_scenario(rng, cfg.scenario)
            sims.append(CrowdSim(scenario, cfg.crowd, rng))
            start = rng.uniform(0.0, self._area_m, size=(cfg.n_uavs, 2))
            self._positions_m[c] = np.clip(start, 0.0, self._area_m)  # as UAVFleet does
        if self._crowd is None or mask.all():
            self._crowd = BatchedCrowd(sims)
        else:
            self._crowd.replace(copies, sims)
        self._velocities_m_s[copies] = 0.0
        self._targets_m[copies] = self._positions_m[copies]
        self._cycle[copies] = 0
        self._finished[copies] = False
        for c in copies if self._links else ():
            self._links[c].reset()
        self._update_world_view()
        return self._observations(), self._infos()

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
            ``mean_throughput_mbps``, ``separation_penalty`` ``(B,)``; ``covered_users``,
            ``n_pedestrians`` ``(B,)`` int; ``users_served`` ``(B, n)`` int; ``throughput_per_user_mbps``
            ``(B, n)``.

        Raises:
            ValueError: Actions of another shape, a non-numeric dtype, or NaN/inf; a bad mask.
            RuntimeError: A stepped copy is finished (truncated) or the batch was never reset.
        """
        b = self.num_envs
        values = self._check_actions(actions)
        active = np.ones(b, dtype=bool) if mask is None else np.asarray(mask)
        if active.shape != (b,) or active.dtype != bool:
            raise ValueError(f"mask must be a (num_envs,) = ({b},) bool array, got {active!r}")
        if self._crowd is None:
            raise RuntimeError("the batch has not been reset: call reset() first")
        if (self._finished & active).any():
            raise RuntimeError(f"copies {np.flatnonzero(self._finished & active).tolist()} are finished "
                               "(truncated): reset them with reset(mask=...) first")
        values = np.minimum(np.maximum(values, self._act_low), self._act_high)
        if self.config.action_mode == "velocity":
            command = values * self.config.uav.max_speed_m_s
        else:
            self._targets_m[active] = values[active]
            command = self._waypoint_command()
        self._crowd.step(self.config.crowd_steps_per_env_step, active=None if mask is None else active)
        self._fly(command, active)
        self._cycle += active
        self._update_world_view()
        truncated = self._cycle >= self.config.max_cycles
        self._finished |= truncated
        terminated = np.zeros(b, dtype=bool)
        return self._observations(), self._reward.astype(np.float32), terminated, truncated, self._infos()

    def state(self) -> np.ndarray:
        """``(B, h*w + 2n)`` float32: each copy's share map and normalised UAV positions (raw_env's state)."""
        self._require_reset()
        positions = (self._positions_m / self._area_m).reshape(self.num_envs, -1).astype(np.float32)
        return np.concatenate([self._share_map.reshape(self.num_envs, -1), positions], axis=1)

    # --- accessors --------------------------------------------------------------------

    @property
    def crowd(self) -> BatchedCrowd:
        """All copies' crowds (``positions_m`` stacked; ``copy_index``, ``offsets``, ``scenarios``)."""
        self._require_reset()
        return self._crowd

    @property
    def uav_positions_m(self) -> np.ndarray:
        """``(B, n, 2)`` UAV positions in metres (a copy)."""
        return self._positions_m.copy()

    @property
    def uav_velocities_m_s(self) -> np.ndarray:
        """``(B, n, 2)`` UAV velocities in m/s (a copy)."""
        return self._velocities_m_s.copy()

    @property
    def finished(self) -> np.ndarray:
        """``(B,)`` bool: copies truncated and not reset since."""
        return self._finished.copy()

    # --- internals --------------------------------------------------------------------

    def _require_reset(self) -> None:
        if self._crowd is None:
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

    def _waypoint_command(self) -> np.ndarray:
        """``(B, n, 2)`` velocity commands flying to the targets (``UAVFleet.waypoint_command``)."""
        uav = self.config.uav
        offset = self._targets_m - self._positions_m
        dist = np.sqrt(np.einsum("bkc,bkc->bk", offset, offset))
        speed = np.minimum(np.minimum(uav.max_speed_m_s, dist / self.dt_s),
                           np.sqrt(2.0 * uav.max_accel_m_s2 * dist))
        with np.errstate(invalid="ignore", divide="ignore"):
            scale = np.where(dist > 1e-9, speed / dist, 0.0)
        return offset * scale[..., None]

    def _fly(self, command: np.ndarray, active: np.ndarray) -> None:
        """``UAVFleet.step`` for the active copies."""
        uav = self.config.uav
        desired = _cap_norm(command, uav.max_speed_m_s)
        delta = _cap_norm(desired - self._velocities_m_s, uav.max_accel_m_s2 * self.dt_s)
        velocities = self._velocities_m_s + delta
        positions = self._positions_m + velocities * self.dt_s
        clamped = np.clip(positions, 0.0, self._area_m)
        velocities[clamped != positions] = 0.0  # stopped by the border
        self._positions_m[active] = clamped[active]
        self._velocities_m_s[active] = velocities[active]

    def _update_world_view(self) -> None:
        """Density maps, coverage, separation and rewards of all copies (raw_env's ``_update_world_view``)."""
        cfg, crowd, b = self.config, self._crowd, self.num_envs
        (h, w), half = cfg.density_shape, cfg.patch_px // 2
        peds, copy = crowd.positions_m, crowd.copy_index
        self._n_users = crowd.counts()
        x, y = peds[:, 0], peds[:, 1]
        inside = (x >= 0) & (x <= self.width_m) & (y >= 0) & (y <= self.height_m)
        cols = np.minimum((x * (w / self.width_m)).astype(np.intp), w - 1)
        rows = np.minimum((y * (h / self.height_m)).astype(np.intp), h - 1)
        pixel = (copy * h + rows) * w + cols
        counts = np.bincount(pixel[inside] if not inside.all() else pixel, minlength=b * h * w)
        density = counts.reshape(b, h, w).astype(np.float32)
        self._share_map = density / np.maximum(self._n_users, 1).astype(np.float32)[:, None, None]
        self._padded_share_map[:, half:half + h, half:half + w] = self._share_map
        self._coverage(peds, copy)
        self._separation = _separation_penalty(self._positions_m, cfg.uav.min_separation_m)
        qos = self._qos_s1 if cfg.strategy == 1 else self._qos_s2
        self._reward = qos - cfg.separation_weight * self._separation

    def _coverage(self, peds: np.ndarray, copy: np.ndarray) -> None:
        """Strongest-UAV association per pedestrian within its copy (``evaluate_coverage``)."""
        if self._links:
            self._admitted_coverage(peds, copy)
            return
        radio, b, n = self.radio, self.num_envs, self.n_agents
        x, y = peds[:, 0], peds[:, 1]
        uav_x = np.ascontiguousarray(self._positions_m[:, :, 0].T)  # (n, B)
        uav_y = np.ascontiguousarray(self._positions_m[:, :, 1].T)
        # Nearest UAV per pedestrian (the first of equals, as argmin) and its squared distance, UAV by UAV.
        nearest = np.zeros(len(x), dtype=np.intp)
        best = np.empty(len(x))
        d2, tmp = np.empty(len(x)), np.empty(len(x))
        for k in range(n):
            dx = np.subtract(uav_x[k][copy], x, out=tmp)
            np.multiply(dx, dx, out=d2)
            dy = np.subtract(uav_y[k][copy], y, out=tmp)
            d2 += np.multiply(dy, dy, out=tmp)
            if radio.altitude_m:
                d2 += radio.altitude_m**2
            if k == 0:
                best[:] = d2
            else:
                nearest[d2 < best] = k
                np.minimum(best, d2, out=best)
        best_signal = np.exp(best * (-0.5 / radio.effective_sigma_sq_m2))
        covered = best_signal >= radio.signal_at_range
        served = np.bincount((copy * n + nearest)[covered], minlength=b * n).reshape(b, n)
        rate_mbps = radio.capacity_mbps / np.maximum(served, 1)
        n_fast = (served * (rate_mbps >= radio.min_user_rate_mbps)).sum(axis=1)
        total_mbps = radio.capacity_mbps * np.count_nonzero(served, axis=1)
        users = self._n_users
        some = users > 0
        self._users_per_uav = served
        self._covered_users = served.sum(axis=1)
        self._qos_s1 = np.divide(self._covered_users, users, out=np.zeros(b), where=some)
        self._qos_s2 = np.divide(n_fast, users, out=np.zeros(b), where=some)
        self._mean_throughput = np.divide(total_mbps, users, out=np.zeros(b), where=some)

    def _admitted_coverage(self, peds: np.ndarray, copy: np.ndarray) -> None:
        """Admission control: each copy's own association sequence (``comms.Association``)."""
        b, n = self.num_envs, self.n_agents
        starts = np.searchsorted(copy, np.arange(b + 1))
        coverages = [link.update(peds[starts[c]:starts[c + 1]], self._positions_m[c])
                     for c, link in enumerate(self._links)]
        self._users_per_uav = np.array([cov.users_per_uav for cov in coverages]).reshape(b, n)
        self._covered_users = self._users_per_uav.sum(axis=1)
        self._qos_s1 = np.array([cov.qos_s1 for cov in coverages])
        self._qos_s2 = np.array([cov.qos_s2 for cov in coverages])
        self._mean_throughput = np.array([cov.mean_throughput_mbps for cov in coverages])

    def _observations(self) -> np.ndarray:
        cfg, b, n, p = self.config, self.num_envs, self.n_agents, self.config.patch_px
        obs = np.zeros((b, n, self.obs_dim), dtype=np.float32)
        pos = self._positions_m / self._area_m
        obs[:, :, 0:2] = pos
        obs[:, :, 2:4] = self._velocities_m_s / cfg.uav.max_speed_m_s
        if n > 1:
            rel = pos[:, self._others[1]] - pos[:, self._others[0]]  # (B, n (n - 1), 2), by observer
            obs[:, :, 4:4 + 2 * (n - 1)] = rel.reshape(b, n, -1)
            obs[:, :, 4 + 2 * _N_OTHERS:4 + 2 * _N_OTHERS + n - 1] = 1.0
        start = 4 + 3 * _N_OTHERS
        pixel = np.minimum((self._positions_m * self._px_per_m).astype(np.intp), self._last_px)  # (B, n, 2)
        # The p x p window of the zero-bordered map whose top-left is the UAV's pixel: centred on it.
        patches = self._patch_windows[np.arange(b)[:, None], pixel[..., 1], pixel[..., 0]]  # (B, n, p, p)
        obs[:, :, start:start + p * p] = patches.reshape(b, n, p * p)
        served = self._users_per_uav
        stats = obs[:, :, -_N_STATS:]
        stats[:, :, 0] = served / np.maximum(1, self._n_users)[:, None]
        stats[:, :, 1] = 1.0 / np.maximum(served, 1) * (served > 0)
        stats[:, :, 2] = self._qos_s1[:, None]
        stats[:, :, 3] = self._qos_s2[:, None]
        # Guards against rounding only; the patch (shares of a count, <= 1 exactly) needs none.
        for part in (slice(0, start), slice(-_N_STATS, None)):
            np.clip(obs[:, :, part], self._obs_low[part], self._obs_high[part], out=obs[:, :, part])
        return obs

    def _infos(self) -> dict[str, np.ndarray]:
        served = self._users_per_uav
        capacity = self.radio.capacity_mbps
        return {
            "qos_s1": self._qos_s1.copy(),
            "qos_s2": self._qos_s2.copy(),
            "mean_throughput_mbps": self._mean_throughput.copy(),
            "covered_users": self._covered_users.copy(),
            "n_pedestrians": self._n_users.copy(),
            "separation_penalty": self._separation.copy(),
            "users_served": served.copy(),
            "throughput_per_user_mbps": np.where(served > 0, capacity / np.maximum(served, 1), 0.0),
        }


def _per_copy_seeds(seed: int | Sequence[int | None] | None, n: int) -> list[int | None]:
    """One seed (or None) per copy: ``s + k`` for an int ``s``."""
    if seed is None:
        return [None] * n
    if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
        return [int(seed) + k for k in range(n)]
    seeds = list(seed)
    if len(seeds) != n:
        raise ValueError(f"seed must be an int, None or a sequence of num_envs = {n} seeds, got {len(seeds)}")
    return seeds


def _cap_norm(vectors: np.ndarray, cap: float) -> np.ndarray:
    """Scale down the vectors (last axis, 2) whose norm exceeds ``cap`` (a new array)."""
    norm = np.hypot(vectors[..., 0], vectors[..., 1])
    return vectors * (cap / np.maximum(norm, cap))[..., None]


def _separation_penalty(positions_m: np.ndarray, min_separation_m: float) -> np.ndarray:
    """``(B,)`` summed intrusion of UAV pairs closer than ``min_separation_m`` (``separation_penalty``)."""
    b, k = positions_m.shape[:2]
    if k < 2 or min_separation_m <= 0:
        return np.zeros(b)
    dx = positions_m[:, :, None, 0] - positions_m[:, None, :, 0]  # (B, K, K)
    dy = positions_m[:, :, None, 1] - positions_m[:, None, :, 1]
    d2 = dx * dx + dy * dy
    close = d2 < min_separation_m**2  # includes the diagonal (d = 0): k entries of 1 per copy
    intrusion = np.where(close, 1.0 - np.sqrt(d2) / min_separation_m, 0.0)
    return (intrusion.sum(axis=(1, 2)) - k) / 2.0  # each pair is counted twice
