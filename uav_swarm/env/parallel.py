"""The ``uav_swarm_v0`` PettingZoo parallel environment: a thin shell over :mod:`uav_swarm.world`.

Examples:
    >>> from uav_swarm.env.parallel import parallel_env
    >>> env = parallel_env(n_uavs=2, max_cycles=3)
    >>> observations, infos = env.reset(seed=0)
    >>> env.agents
    ['uav_0', 'uav_1']
    >>> while env.agents:
    ...     _ = env.step({agent: env.action_space(agent).sample() for agent in env.agents})
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import AECEnv, ParallelEnv
from pettingzoo.utils.conversions import parallel_to_aec

from uav_swarm.env.actions import parse_actions
from uav_swarm.env.config import MAX_UAVS, EnvConfig, merge_overrides
from uav_swarm.env.render import HumanViewer, draw_frame
from uav_swarm.world.comms import Association, Coverage
from uav_swarm.world.crowd import CrowdSim
from uav_swarm.world.raster import density_map
from uav_swarm.world.scenario import Scenario, random_scenario
from uav_swarm.world.separation import separation_penalty
from uav_swarm.world.uav import UAVFleet

__all__ = ["raw_env", "parallel_env", "env", "EnvConfig"]

logger = logging.getLogger(__name__)

_N_OTHERS = MAX_UAVS - 1
_N_STATS = 4


class raw_env(ParallelEnv):  # noqa: N801 (PettingZoo's name for the environment class)
    """UAV swarm over a moving crowd (``uav_swarm_v0``).

    **Description.** Up to 10 UAVs fly at a fixed altitude over a rectangular area where a
    crowd walks (a social-force simulation of a random scenario: obstacles, waypoints,
    groups). Each UAV is a Wi-Fi access point (the paper's model: a Gaussian rescaled
    signal, 0.1 at 30 m; users join their strongest UAV; 200 Mbps shared by its users).
    The team is rewarded for the share of the crowd it serves.

    **Agents.** ``uav_0`` ... ``uav_{n-1}``, ``1 <= n_uavs <= 10``, all acting at once.

    **Action space.** ``Box(2,)`` float32 per agent:

    - ``action_mode="velocity"``: ``[-1, 1]^2``, the commanded velocity (East, North) as a
      fraction of ``uav.max_speed_m_s`` (per axis; the speed is then capped at the maximum).
    - ``action_mode="waypoint"``: ``[0, width_m] x [0, height_m]``, a target position in metres;
      a controller flies there at most at the caps and brakes to a stop on it.

    Speeds are capped at ``uav.max_speed_m_s`` and velocity changes at ``uav.max_accel_m_s2``;
    UAVs stay inside the area. Out-of-bounds values are clipped into the box; a missing
    agent keeps its last target (waypoint) or is commanded to stop (velocity). Any float
    or int numpy dtype is accepted; an unknown agent, a shape other than ``(2,)`` or a NaN/inf
    raises ``ValueError`` naming the agent.

    **Observation space.** ``Box(4 + 27 + patch_px**2 + 4,)`` float32 (260 by default), per agent:

    ====================  ======  ==============================================================
    slice                 range   meaning
    ====================  ======  ==============================================================
    ``[0:2]``             [0, 1]  own position / (width_m, height_m)
    ``[2:4]``             [-1, 1] own velocity / max_speed_m_s
    ``[4:22]``            [-1, 1] positions of the other UAVs relative to this one / (width_m, height_m),
                                  in agent order, zero-padded to 9 UAVs
    ``[22:31]``           {0, 1}  1 where the slot above holds a UAV
    ``[31:31+p*p]``       [0, 1]  local density patch: share of the crowd in each of the p x p
                                  density-map pixels centred on the UAV's pixel, row-major,
                                  row 0 = South (p = ``patch_px``; 0 outside the area)
    last 4                [0, 1]  share of the crowd this UAV serves; its per-user rate / capacity;
                                  team QoS strategy 1; team QoS strategy 2
    ====================  ======  ==============================================================

    **State.** ``state()``: ``Box(h*w + 2n,)`` float32 in [0, 1]: the global density map
    (share of the crowd per pixel, ``density_shape = (h, w)``, row-major, row 0 = South)
    followed by all UAV positions / (width_m, height_m).

    **Rewards.** One shared team reward, a Python float: the chosen strategy's QoS (strategy 1:
    share of pedestrians with network; strategy 2: share with network and at least
    ``radio.min_user_rate_mbps``, 5 Mbps) minus
    ``separation_weight * separation_penalty``, where the penalty sums ``1 - d / min_separation_m``
    over UAV pairs closer than ``uav.min_separation_m``. ``infos[agent]`` holds ``qos_s1``,
    ``qos_s2``, ``mean_throughput_mbps``, ``covered_users``, ``n_pedestrians``,
    ``separation_penalty``, and the agent's own ``users_served`` and ``throughput_per_user_mbps``
    (numbers only, so that RL libraries can stack them; ``env.coverage.model`` names the association).

    **Association.** ``radio.station_limit`` chooses it (:mod:`uav_swarm.world.comms`): ``None``, the
    paper's model, joins every user in range to its strongest UAV at every step; a limit (an integer, or
    ``"auto"`` = capacity / minimum rate = 40) is admission control as a deployed access point does it:
    a full UAV refuses newcomers, who try their next UAV in range, and a user keeps its UAV while it stays
    in range. ``reset`` clears the associations.

    **Episode end.** No termination; all agents are truncated after ``max_cycles`` steps.
    One step lasts ``crowd_steps_per_env_step * crowd.dt_s`` simulated seconds (0.1 s by default).

    **Rendering.** ``"rgb_array"``: ``render()`` returns an (H, W, 3) uint8 North-up picture
    (512 px wide): coverage discs, obstacles, pedestrians (green when covered) and UAVs.
    ``"human"``: the picture is shown in a matplotlib window at every reset and step (nothing
    on a non-interactive backend). With ``render_mode=None`` nothing is drawn.

    **Arguments.** ``raw_env(render_mode=None, config=None, scene=None, **overrides)``:
    ``config`` is an :class:`EnvConfig` (defaults otherwise); ``overrides`` are its fields
    (``n_uavs``, ``action_mode``, ``strategy``, ``max_cycles``, ``crowd_steps_per_env_step``,
    ``density_shape``, ``patch_px``, ``separation_weight``, ``use_3d_distance``) and its nested
    configs ``uav``, ``scenario``, ``crowd``, ``radio`` as a Config or a partial dict;
    ``scene`` (a :class:`~uav_swarm.world.scenario.Scenario`) fixes the scene for every episode
    (else a random one is drawn from ``config.scenario`` at each reset). ``reset(seed)``
    seeds the one ``numpy.random.Generator`` that draws the scenario, the crowd and the UAV
    start positions. ``render_mode`` is ``None``, ``"rgb_array"`` or ``"human"``.

    **Version history.** v0: initial release.
    """

    metadata = {
        "name": "uav_swarm_v0",
        "render_modes": ["human", "rgb_array"],
        "is_parallelizable": True,
        "render_fps": 10,
    }

    def __init__(
        self,
        render_mode: str | None = None,
        config: EnvConfig | None = None,
        scene: Scenario | None = None,
        **overrides: Any,
    ) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode = {render_mode!r}: choose None or one of {self.metadata['render_modes']}")
        self.config = merge_overrides(config or EnvConfig(), overrides)
        self.render_mode = render_mode
        self._scene = scene
        cfg = self.config
        if scene is not None:
            self.width_m, self.height_m = float(scene.width_m), float(scene.height_m)
        else:
            self.width_m, self.height_m = float(cfg.scenario.width_m), float(cfg.scenario.height_m)
        self._area_m = np.array([self.width_m, self.height_m])
        self.dt_s = cfg.crowd_steps_per_env_step * cfg.crowd.dt_s
        self.radio = cfg.effective_radio
        self._association = Association(self.radio)
        self.possible_agents = [f"uav_{i}" for i in range(cfg.n_uavs)]
        self.agents: list[str] = []
        self._agent_index = {agent: i for i, agent in enumerate(self.possible_agents)}

        n, p = cfg.n_uavs, cfg.patch_px
        self._obs_dim = 4 + 3 * _N_OTHERS + p * p + _N_STATS
        low = np.zeros(self._obs_dim, dtype=np.float32)
        low[2:4 + 2 * _N_OTHERS] = -1.0
        self._obs_low, self._obs_high = low, np.ones(self._obs_dim, dtype=np.float32)
        self._observation_spaces = {
            a: spaces.Box(low, self._obs_high, dtype=np.float32) for a in self.possible_agents}
        if cfg.action_mode == "velocity":
            act_low, act_high = np.full(2, -1.0, np.float32), np.ones(2, np.float32)
        else:
            act_low, act_high = np.zeros(2, np.float32), self._area_m.astype(np.float32)
        self._act_low, self._act_high = act_low.astype(np.float64), act_high.astype(np.float64)
        self._action_spaces = {
            a: spaces.Box(act_low, act_high, dtype=np.float32) for a in self.possible_agents}
        h, w = cfg.density_shape
        self.state_space = spaces.Box(0.0, 1.0, shape=(h * w + 2 * n,), dtype=np.float32)
        # Index pairs (i, j != i) of the other UAVs, in agent order, for the observation.
        self._others = (np.repeat(np.arange(n), n - 1),
                        np.array([j for i in range(n) for j in range(n) if j != i], dtype=np.intp))
        # Flat offsets of a p x p patch in the zero-bordered map, whose top-left is the UAV's pixel.
        self._patch_flat = (np.arange(p)[:, None] * (w + p - 1) + np.arange(p)[None, :]).ravel()
        self._px_per_m = np.array([w / self.width_m, h / self.height_m])
        self._last_px = np.array([w - 1, h - 1])
        self._padded_share_map = np.zeros((h + p - 1, w + p - 1), dtype=np.float32)  # zero border
        # Horizontal radius within which a user is covered (for drawing).
        self.coverage_radius_m = self.radio.coverage_radius_m

        self._rng: np.random.Generator | None = None
        self._scenario: Scenario | None = None
        self._crowd: CrowdSim | None = None
        self._fleet: UAVFleet | None = None
        self._viewer: HumanViewer | None = None

    # --- PettingZoo API -----------------------------------------------------------------

    def observation_space(self, agent: str) -> spaces.Box:
        """The observation space of ``agent`` (see the class docstring)."""
        return self._observation_spaces[agent]

    def action_space(self, agent: str) -> spaces.Box:
        """The action space of ``agent`` (see the class docstring)."""
        return self._action_spaces[agent]

    def reset(
        self, seed: int | None = None, options: dict | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, dict[str, Any]]]:
        """Draw a new scenario, crowd and UAV start positions.

        Args:
            seed: Seeds the environment's generator; None continues the current one.
            options: Unused.
        """
        if seed is not None or self._rng is None:
            self._rng = np.random.default_rng(seed)
        rng, cfg = self._rng, self.config
        self._scenario = self._scene if self._scene is not None else random_scenario(rng, cfg.scenario)
        self._crowd = CrowdSim(self._scenario, cfg.crowd, rng)
        self._fleet = UAVFleet(rng.uniform(0.0, self._area_m, size=(cfg.n_uavs, 2)), cfg.uav,
                               self.width_m, self.height_m)
        self._targets_m = self._fleet.positions_m.copy()
        self.agents = self.possible_agents[:]
        self._cycle = 0
        self._association.reset()
        self._update_world_view()
        if self.render_mode == "human":
            self.render()
        return self._observations(), self._infos()

    def step(self, actions: Mapping[str, Any]) -> tuple[
        dict[str, np.ndarray], dict[str, float], dict[str, bool], dict[str, bool], dict[str, dict[str, Any]]
    ]:
        """Apply one action per agent, advance the crowd and the UAVs by ``dt_s``.

        Raises:
            ValueError: An unknown agent, or an action of the wrong shape, dtype or with NaN/inf.
            RuntimeError: The episode is over (call ``reset``).
        """
        if not self.agents:
            raise RuntimeError("step() called on a finished episode: call reset() first")
        command = self._command(actions)
        self._crowd.step(self.config.crowd_steps_per_env_step)
        self._fleet.step(command, self.dt_s)
        self._cycle += 1
        self._update_world_view()
        agents = self.agents
        rewards = dict.fromkeys(agents, self._reward)
        terminations = dict.fromkeys(agents, False)
        truncations = dict.fromkeys(agents, self._cycle >= self.config.max_cycles)
        observations, infos = self._observations(), self._infos()
        if self._cycle >= self.config.max_cycles:
            self.agents = []
        if self.render_mode == "human":
            self.render()
        return observations, rewards, terminations, truncations, infos

    def state(self) -> np.ndarray:
        """The global density map (share of the crowd per pixel) and all UAV positions, normalised."""
        self._require_reset()
        positions = self._fleet.positions_m / self._area_m
        return np.concatenate([self._share_map.ravel(), positions.ravel().astype(np.float32)])

    def render(self) -> np.ndarray | None:
        """An (H, W, 3) uint8 picture in ``rgb_array`` mode; shows it in ``human`` mode."""
        if self.render_mode is None:
            logger.warning("render() called without a render_mode: nothing drawn")
            return None
        self._require_reset()
        frame = draw_frame(
            self.width_m, self.height_m, obstacles_m=self._scenario.obstacles,
            pedestrians_m=self._crowd.positions_m, covered=self._coverage.covered,
            uavs_m=self._fleet.positions_m, coverage_radius_m=self.coverage_radius_m)
        if self.render_mode == "rgb_array":
            return frame
        if self._viewer is None:
            self._viewer = HumanViewer(self.metadata["name"], self.metadata["render_fps"])
        self._viewer.show(frame)
        return None

    def close(self) -> None:
        """Close the window of ``human`` rendering."""
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None

    # --- accessors for planners and simulators -----------------------------------------

    @property
    def scenario(self) -> Scenario:
        """The current scenario (obstacles, waypoints, groups)."""
        return self._scenario

    @property
    def pedestrian_positions_m(self) -> np.ndarray:
        """(N, 2) pedestrian positions in metres (read-only view)."""
        return _read_only(self._crowd.positions_m)

    @property
    def pedestrian_velocities_m_s(self) -> np.ndarray:
        """(N, 2) pedestrian velocities in m/s (read-only view)."""
        return _read_only(self._crowd.velocities_m_s)

    @property
    def uav_positions_m(self) -> np.ndarray:
        """(K, 2) UAV positions in metres (read-only view)."""
        return _read_only(self._fleet.positions_m)

    @property
    def uav_velocities_m_s(self) -> np.ndarray:
        """(K, 2) UAV velocities in m/s (read-only view)."""
        return _read_only(self._fleet.velocities_m_s)

    @property
    def coverage(self) -> Coverage:
        """The coverage of the crowd after the last reset or step."""
        return self._coverage

    @property
    def density(self) -> np.ndarray:
        """(h, w) float32 pedestrian counts per pixel after the last reset or step (read-only view)."""
        return _read_only(self._density)

    # --- internals ----------------------------------------------------------------------

    def _require_reset(self) -> None:
        if self._fleet is None:
            raise RuntimeError("the environment has not been reset: call reset() first")

    def _command(self, actions: Mapping[str, Any]) -> np.ndarray:
        """Validate the actions and turn them into (K, 2) velocity commands in m/s."""
        given, values = parse_actions(actions, self._agent_index)
        values = np.minimum(np.maximum(values, self._act_low), self._act_high)
        if self.config.action_mode == "velocity":
            command = np.zeros_like(self._fleet.positions_m)
            command[given] = values * self.config.uav.max_speed_m_s
            return command
        self._targets_m[given] = values
        return self._fleet.waypoint_command(self._targets_m, self.dt_s)

    def _update_world_view(self) -> None:
        """Density map, coverage and reward after the world moved (once per step)."""
        cfg, peds = self.config, self._crowd.positions_m
        self._density = density_map(peds, self.width_m, self.height_m, cfg.density_shape)
        self._share_map = self._density / max(1, peds.shape[0])
        half, (h, w) = cfg.patch_px // 2, cfg.density_shape
        self._padded_share_map[half:half + h, half:half + w] = self._share_map
        self._coverage = self._association.update(peds, self._fleet.positions_m)
        self._separation = float(separation_penalty(self._fleet.positions_m, cfg.uav.min_separation_m))
        qos = self._coverage.qos_s1 if cfg.strategy == 1 else self._coverage.qos_s2
        self._reward = float(qos - cfg.separation_weight * self._separation)

    def _observations(self) -> dict[str, np.ndarray]:
        cfg, fleet, cov = self.config, self._fleet, self._coverage
        n, p = cfg.n_uavs, cfg.patch_px
        obs = np.zeros((n, self._obs_dim), dtype=np.float32)
        pos = fleet.positions_m / self._area_m
        obs[:, 0:2] = pos
        obs[:, 2:4] = fleet.velocities_m_s / cfg.uav.max_speed_m_s
        if n > 1:
            rel = pos[self._others[1]] - pos[self._others[0]]  # (n (n - 1), 2), grouped by observer
            obs[:, 4:4 + 2 * (n - 1)] = rel.reshape(n, -1)
            obs[:, 4 + 2 * _N_OTHERS:4 + 2 * _N_OTHERS + n - 1] = 1.0
        start = 4 + 3 * _N_OTHERS
        # The patch is centred on the density-map pixel that contains the UAV (as density_map bins it).
        pixel = np.minimum((fleet.positions_m * self._px_per_m).astype(np.intp), self._last_px)  # (n, 2) x, y
        flat = (pixel[:, 1] * self._padded_share_map.shape[1] + pixel[:, 0])[:, None] + self._patch_flat
        obs[:, start:start + p * p] = self._padded_share_map.ravel()[flat]  # (n, p * p)
        served = cov.users_per_uav
        stats = obs[:, -_N_STATS:]
        stats[:, 0] = served / max(1, cov.covered.shape[0])
        stats[:, 1] = 1.0 / np.maximum(served, 1) * (served > 0)
        stats[:, 2:] = (cov.qos_s1, cov.qos_s2)
        np.minimum(obs, self._obs_high, out=obs)  # guards against rounding only
        np.maximum(obs, self._obs_low, out=obs)
        return dict(zip(self.agents, obs, strict=True))

    def _infos(self) -> dict[str, dict[str, Any]]:
        cov = self._coverage
        team = {
            "qos_s1": cov.qos_s1,
            "qos_s2": cov.qos_s2,
            "mean_throughput_mbps": cov.mean_throughput_mbps,
            "covered_users": int(np.count_nonzero(cov.covered)),
            "n_pedestrians": int(cov.covered.shape[0]),
            "separation_penalty": self._separation,
        }
        served = cov.users_per_uav.tolist()
        capacity = self.radio.capacity_mbps
        return {
            agent: {**team, "users_served": k, "throughput_per_user_mbps": capacity / k if k else 0.0}
            for agent, k in zip(self.agents, served, strict=True)
        }


def _read_only(array: np.ndarray) -> np.ndarray:
    view = array.view()
    view.flags.writeable = False
    return view


def parallel_env(**kwargs: Any) -> raw_env:
    """The parallel environment; keyword arguments as :class:`raw_env`."""
    return raw_env(**kwargs)


def env(**kwargs: Any) -> AECEnv:
    """The AEC version (``parallel_to_aec``, with order enforcing); kwargs as :class:`raw_env`."""
    return parallel_to_aec(raw_env(**kwargs))
