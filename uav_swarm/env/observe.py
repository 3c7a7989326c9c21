"""What the agents of ``uav_swarm_v0`` see and earn, over B worlds at once: observations, reward, infos.

The layout of one agent's observation (the table of :class:`uav_swarm.env.parallel.raw_env`) is fixed
by :class:`Layout`; :func:`observe`, :func:`team_reward` and :func:`info_arrays` compute them for every
UAV of every world as batch-first arrays. The PettingZoo environment is the batch of one world.

Examples:
    >>> from uav_swarm.env.config import EnvConfig
    >>> layout = Layout(EnvConfig(n_uavs=3), 200.0, 200.0)
    >>> layout.obs_dim, layout.state_dim, layout.action_high.tolist()
    (260, 4102, [1.0, 1.0])
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from uav_swarm.env.config import MAX_UAVS, EnvConfig
from uav_swarm.world.comms_batch import CoverageBatch

__all__ = ["Layout", "observe", "team_reward", "info_arrays", "TEAM_INFO_KEYS", "AGENT_INFO_KEYS"]

N_OTHERS = MAX_UAVS - 1
"""Slots for the other UAVs in an observation (padded)."""
N_STATS = 4
"""Coverage statistics at the end of an observation."""
TEAM_INFO_KEYS = ("qos_s1", "qos_s2", "mean_throughput_mbps", "covered_users", "n_pedestrians",
                  "separation_penalty", "closest_separation_m")
"""Info keys shared by the team: ``(B,)`` arrays."""
AGENT_INFO_KEYS = ("users_served", "throughput_per_user_mbps", "separation_held")
"""Info keys of each agent: ``(B, K)`` arrays."""


class Layout:
    """The observation layout, the boxes and the pixel geometry of one config and area.

    Args:
        config: The environment configuration.
        width_m: Area width (m).
        height_m: Area height (m).

    Attributes:
        obs_dim: Length of one agent's observation.
        state_dim: Length of the global state.
        obs_low: (obs_dim,) float32 lower bounds; ``obs_high`` the upper ones.
        action_low: (2,) float32 lower bounds of an action; ``action_high`` the upper ones.
        action_bounds: The two as float64, for clipping.
    """

    def __init__(self, config: EnvConfig, width_m: float, height_m: float) -> None:
        n, p, (h, w) = config.n_uavs, config.patch_px, config.density_shape
        self.n_uavs, self.patch_px = n, p
        self.obs_dim = 4 + 3 * N_OTHERS + p * p + N_STATS
        self.state_dim = h * w + 2 * n
        low = np.zeros(self.obs_dim, dtype=np.float32)
        low[2:4 + 2 * N_OTHERS] = -1.0
        self.obs_low, self.obs_high = low, np.ones(self.obs_dim, dtype=np.float32)
        if config.action_mode == "velocity":
            self.action_low, self.action_high = np.full(2, -1.0, np.float32), np.ones(2, np.float32)
        else:
            self.action_low = np.zeros(2, np.float32)
            self.action_high = np.array([width_m, height_m], dtype=np.float32)
        self.action_bounds = (self.action_low.astype(np.float64), self.action_high.astype(np.float64))
        self.max_speed_m_s = config.uav.max_speed_m_s
        self.area_m = np.array([width_m, height_m])
        # Index pairs (i, j != i) of the other UAVs, in agent order, grouped by observer.
        self.others = (np.repeat(np.arange(n), n - 1),
                       np.array([j for i in range(n) for j in range(n) if j != i], dtype=np.intp))
        self.px_per_m = np.array([w / width_m, h / height_m])
        self.last_px = np.array([w - 1, h - 1])
        self._patch_start = 4 + 3 * N_OTHERS

    def observation_space(self) -> spaces.Box:
        """One agent's observation box."""
        return spaces.Box(self.obs_low, self.obs_high, dtype=np.float32)

    def action_space(self) -> spaces.Box:
        """One agent's action box."""
        return spaces.Box(self.action_low, self.action_high, dtype=np.float32)

    def state_space(self) -> spaces.Box:
        """The global state's box."""
        return spaces.Box(0.0, 1.0, shape=(self.state_dim,), dtype=np.float32)


def observe(layout: Layout, positions_m: np.ndarray, velocities_m_s: np.ndarray, patch_windows: np.ndarray,
            coverage: CoverageBatch) -> np.ndarray:
    """Every agent's observation in every world.

    Args:
        layout: The layout.
        positions_m: (B, K, 2) UAV positions.
        velocities_m_s: (B, K, 2) UAV velocities.
        patch_windows: (B, h, w, p, p) the p x p windows of each world's zero-bordered share map; the window
            at (row, column) is centred on that pixel.
        coverage: The worlds' coverage.

    Returns:
        (B, K, obs_dim) float32.
    """
    b, n = positions_m.shape[:2]
    p, start = layout.patch_px, layout._patch_start
    obs = np.zeros((b, n, layout.obs_dim), dtype=np.float32)
    pos = positions_m / layout.area_m
    obs[:, :, 0:2] = pos
    obs[:, :, 2:4] = velocities_m_s / layout.max_speed_m_s
    if n > 1:
        rel = pos[:, layout.others[1]] - pos[:, layout.others[0]]  # (B, n (n - 1), 2), by observer
        obs[:, :, 4:4 + 2 * (n - 1)] = rel.reshape(b, n, -1)
        obs[:, :, 4 + 2 * N_OTHERS:4 + 2 * N_OTHERS + n - 1] = 1.0
    # The patch is centred on the density-map pixel that contains the UAV (as density_map bins it).
    pixel = np.minimum((positions_m * layout.px_per_m).astype(np.intp), layout.last_px)  # (B, n, 2) x, y
    world = np.arange(b)[:, None] if b > 1 else 0
    patches = patch_windows[world, pixel[..., 1], pixel[..., 0]]  # (B, n, p, p)
    obs[:, :, start:start + p * p] = patches.reshape(b, n, p * p)
    served = coverage.users_per_uav
    stats = obs[:, :, -N_STATS:]
    stats[:, :, 0] = served / np.maximum(1, coverage.n_users)[:, None]
    stats[:, :, 1] = 1.0 / np.maximum(served, 1) * (served > 0)
    stats[:, :, 2] = coverage.qos_s1[:, None]
    stats[:, :, 3] = coverage.qos_s2[:, None]
    # Guards the velocities against rounding (a speed capped at the maximum may exceed it by an ulp). The
    # rest is in its box exactly: positions clamped to the area, differences of two of them, shares.
    velocity = obs[:, :, 2:4]
    np.minimum(velocity, 1.0, out=velocity)
    np.maximum(velocity, -1.0, out=velocity)
    return obs


def team_reward(coverage: CoverageBatch, separation: np.ndarray, config: EnvConfig) -> np.ndarray:
    """(B,) the shared team reward: the strategy's QoS minus ``separation_weight`` times the penalty."""
    qos = coverage.qos_s1 if config.strategy == 1 else coverage.qos_s2
    return qos - config.separation_weight * separation


def info_arrays(coverage: CoverageBatch, separation: np.ndarray, closest_m: np.ndarray, held: np.ndarray
                ) -> dict[str, np.ndarray]:
    """The infos of every world: :data:`TEAM_INFO_KEYS` ``(B,)`` and :data:`AGENT_INFO_KEYS` ``(B, K)``.

    Args:
        coverage: The worlds' coverage.
        separation: (B,) separation penalty.
        closest_m: (B,) closest distance between two UAVs of each world (m).
        held: (B, K) bool, the UAV's waypoint command was held back by the separation guard.
    """
    return {
        "qos_s1": coverage.qos_s1,
        "qos_s2": coverage.qos_s2,
        "mean_throughput_mbps": coverage.mean_throughput_mbps,
        "covered_users": coverage.covered_users,
        "n_pedestrians": coverage.n_users,
        "separation_penalty": separation,
        "closest_separation_m": closest_m,
        "users_served": coverage.users_per_uav,
        "throughput_per_user_mbps": coverage.throughput_per_user_mbps,
        "separation_held": held.astype(np.int64),
    }
