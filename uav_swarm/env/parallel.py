"""The ``uav_swarm_v0`` PettingZoo parallel environment: a shell over one world of :mod:`uav_swarm.env.core`.

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
from uav_swarm.env.config import EnvConfig, merge_overrides
from uav_swarm.env.core import SwarmCore
from uav_swarm.env.observe import AGENT_INFO_KEYS, TEAM_INFO_KEYS
from uav_swarm.env.render import HumanViewer, draw_frame
from uav_swarm.world.comms import Coverage
from uav_swarm.world.scenario import Scenario

__all__ = ["raw_env", "parallel_env", "env", "EnvConfig"]

logger = logging.getLogger(__name__)


class raw_env(ParallelEnv):  # PettingZoo's name for the environment class
    """UAV swarm over a moving crowd (``uav_swarm_v0``).

    **Description.** Up to 10 UAVs fly at a fixed altitude over a rectangular area where a
    crowd walks (a social-force simulation of a random scenario: obstacles, waypoints,
    groups). Each UAV is a Wi-Fi access point: by default the 802.11 model (docs/radio.md: air-to-ground
    path loss, SINR, 802.11ax rates, airtime shared by co-channel access points that hear each other, a
    channel per UAV that the environment plans unless given one); ``radio={"propagation": "paper"}`` runs
    the paper's model (a Gaussian rescaled signal, 0.1 at 30 m; users join their strongest UAV; 200 Mbps
    shared by its users). The team is rewarded for the share of the crowd it serves.

    **Agents.** ``uav_0`` ... ``uav_{n-1}``, ``1 <= n_uavs <= 10``, all acting at once.

    **Action space.** ``Box(2,)`` float32 per agent:

    - ``action_mode="velocity"``: ``[-1, 1]^2``, the commanded velocity (East, North) as a
      fraction of ``uav.max_speed_m_s`` (per axis; the speed is then capped at the maximum).
    - ``action_mode="waypoint"``: ``[0, width_m] x [0, height_m]``, a target position in metres;
      a controller flies there at most at the caps and brakes to a stop on it. Its commands pass a
      separation guard (:func:`~uav_swarm.world.step_guard.guard_commands`) that keeps every pair of
      UAVs at least ``uav.min_separation_m`` apart: a UAV whose command would close a gap below it is
      turned around its neighbour or brakes (``separation_held = 1``), lower indices first. UAVs start
      at random and may start closer than the minimum; such a pair may only widen its gap.

    Velocity actions (the learning path) are not guarded: separation is learnt from the reward's penalty.
    Speeds are capped at ``uav.max_speed_m_s`` and velocity changes at ``uav.max_accel_m_s2``;
    UAVs stay inside the area (:func:`~uav_swarm.world.uav.fly_step`). Out-of-bounds values are
    clipped into the box; a missing agent keeps its last target (waypoint) or is commanded to stop
    (velocity). Any float
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
    share of pedestrians with network, under 802.11 a usable rate with no user refused on rate; strategy 2:
    share with network and at least ``radio.min_user_rate_mbps``, 5 Mbps, under 802.11 with admission on
    rate) minus
    ``separation_weight * separation_penalty``, where the penalty sums ``1 - d / min_separation_m``
    over UAV pairs closer than ``uav.min_separation_m``. ``infos[agent]`` holds the team's ``qos_s1``,
    ``qos_s2``, ``mean_throughput_mbps``, ``covered_users``, ``n_pedestrians``,
    ``separation_penalty`` and ``closest_separation_m`` (the distance of the closest pair of UAVs, m),
    and the agent's own ``users_served``, ``throughput_per_user_mbps`` and ``separation_held`` (1 when
    the guard held its waypoint command back this step, else 0) (numbers only, so that RL libraries can
    stack them; ``env.coverage.model`` names the association).

    **Altitudes.** UAV ``k`` flies at ``uav.alt_m + k * uav.layer_step_m`` (``env.uav_altitudes_m``; one
    layer by default). With layers, distances between UAVs (the guard, the penalty, the closest pair) are
    3-D, and with ``use_3d_distance`` the paper's radio measures each user's distance to each UAV at that
    UAV's own altitude (the 802.11 radio always does).

    **Association.** Under 802.11 a user keeps its access point while its link holds (docs/radio.md).
    On the paper's radio ``radio.station_limit`` chooses it (:mod:`uav_swarm.world.comms`): ``None``, the
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
    start positions (``env.np_random``, Gymnasium's name, which wrappers such as SuperSuit's frame
    skip draw from). ``render_mode`` is ``None``, ``"rgb_array"`` or ``"human"``.

    **Implementation.** This class is a PettingZoo shell over one world of
    :class:`~uav_swarm.env.core.SwarmCore`; :class:`~uav_swarm.env.batched.BatchedUAVSwarm` is the same
    core over B worlds, so both compute the same numbers with the same code.

    **Version history.** v0: initial release.
    """

    metadata: dict[str, Any] = {
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
        self._core = core = SwarmCore(1, self.config, scene, stacked_crowd=False)
        self.width_m, self.height_m = core.width_m, core.height_m
        self.dt_s = core.dt_s
        self.radio = core.radio
        self.possible_agents = [f"uav_{i}" for i in range(self.config.n_uavs)]
        self.agents: list[str] = []
        self._agent_index = {agent: i for i, agent in enumerate(self.possible_agents)}
        observation_space, action_space = core.layout.observation_space(), core.layout.action_space()
        self._observation_spaces = {a: observation_space for a in self.possible_agents}
        self._action_spaces = {a: action_space for a in self.possible_agents}
        self.state_space = core.layout.state_space()
        # Horizontal radius within which a user is covered (for drawing).
        self.coverage_radius_m = self.radio.coverage_radius_m
        self._given = np.zeros((1, self.config.n_uavs), dtype=bool)
        self._values = np.zeros((1, self.config.n_uavs, 2))
        self._reset_done = False
        self._viewer: HumanViewer | None = None

    # --- PettingZoo API -----------------------------------------------------------------

    def observation_space(self, agent: str) -> spaces.Box:
        """The observation space of ``agent`` (see the class docstring)."""
        return self._observation_spaces[agent]

    def action_space(self, agent: str) -> spaces.Box:
        """The action space of ``agent`` (see the class docstring)."""
        return self._action_spaces[agent]

    @property
    def np_random(self) -> np.random.Generator:
        """The environment's one generator (Gymnasium's name): it draws scenario, crowd and UAV starts."""
        return self._core.rng(0)

    def reset(
        self, seed: int | None = None, options: dict | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, dict[str, Any]]]:
        """Draw a new scenario, crowd and UAV start positions.

        Args:
            seed: Seeds the environment's generator; None continues the current one.
            options: Unused.
        """
        self._core.reset([seed], np.zeros(1, np.intp))
        self._reset_done = True
        self.agents = self.possible_agents[:]
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
        given, values = parse_actions(actions, self._agent_index)
        every = len(given) == self.config.n_uavs
        if every and given == list(range(len(given))):
            self._core.step(values[None])
        else:
            self._given[:] = False
            self._given[0, given] = True
            self._values[0, given] = values
            self._core.step(self._values, None if every else self._given)
        core, agents = self._core, self.agents
        done = bool(core.cycle[0] >= self.config.max_cycles)
        rewards = dict.fromkeys(agents, float(core.reward[0]))
        terminations = dict.fromkeys(agents, False)
        truncations = dict.fromkeys(agents, done)
        observations, infos = self._observations(), self._infos()
        if done:
            self.agents = []
        if self.render_mode == "human":
            self.render()
        return observations, rewards, terminations, truncations, infos

    def state(self) -> np.ndarray:
        """The global density map (share of the crowd per pixel) and all UAV positions, normalised."""
        self._require_reset()
        return self._core.states()[0]

    def render(self) -> np.ndarray | None:
        """An (H, W, 3) uint8 picture in ``rgb_array`` mode; shows it in ``human`` mode."""
        if self.render_mode is None:
            logger.warning("render() called without a render_mode: nothing drawn")
            return None
        self._require_reset()
        frame = draw_frame(
            self.width_m, self.height_m, obstacles_m=self.scenario.obstacles,
            pedestrians_m=self.pedestrian_positions_m, covered=self._core.coverage.association >= 0,
            uavs_m=self.uav_positions_m, coverage_radius_m=self.coverage_radius_m)
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
        self._require_reset()
        return self._core.crowd.scenario

    @property
    def pedestrian_positions_m(self) -> np.ndarray:
        """(N, 2) pedestrian positions in metres (read-only view)."""
        self._require_reset()
        return _read_only(self._core.crowd.positions_m)

    @property
    def pedestrian_velocities_m_s(self) -> np.ndarray:
        """(N, 2) pedestrian velocities in m/s (read-only view)."""
        self._require_reset()
        return _read_only(self._core.crowd.velocities_m_s)

    @property
    def uav_positions_m(self) -> np.ndarray:
        """(K, 2) UAV positions in metres (read-only view)."""
        return _read_only(self._core.positions_m[0])

    @property
    def uav_velocities_m_s(self) -> np.ndarray:
        """(K, 2) UAV velocities in m/s (read-only view)."""
        return _read_only(self._core.velocities_m_s[0])

    def set_channel_plan(self, channels: np.ndarray | None) -> None:
        """Each UAV's channel from the next step on (``propagation = "802.11"``).

        ``channels``: (K,) channel numbers (``uav_swarm.world.wifi.channels.plan_channels`` computes them);
        None: the environment plans them itself at every step (the default: ``plan_channels`` on the UAVs'
        positions, the plan in force kept while valid).

        Raises:
            ValueError: The paper's radio, or a channel outside ``radio.ieee80211``'s usable channels.
        """
        self._core.set_channel_plan(channels)

    def set_access_points(self, enabled: np.ndarray | None) -> None:
        """Which UAVs' access points are on from the next step on (``propagation = "802.11"``).

        ``enabled``: (K,) bool; an AP that is off transmits nothing, so it takes no airtime from the others
        (under admission on rate ``simulate`` turns off the AP of a UAV its plan gives no users). None: every
        AP on, the default.

        Raises:
            ValueError: The paper's radio, or a shape the environment does not take.
        """
        self._core.set_access_points(enabled)

    @property
    def uav_altitudes_m(self) -> np.ndarray:
        """(K,) UAV flight altitudes in metres (``uav.alt_m`` plus ``uav.layer_step_m`` per index)."""
        return _read_only(self._core.altitudes_m)

    @property
    def coverage(self) -> Coverage:
        """The coverage of the crowd after the last reset or step."""
        self._require_reset()
        return self._core.coverage.copy(0)

    @property
    def density(self) -> np.ndarray:
        """(h, w) float32 pedestrian counts per pixel after the last reset or step (read-only view)."""
        self._require_reset()
        return _read_only(self._core.density[0])

    # --- internals ----------------------------------------------------------------------

    def _require_reset(self) -> None:
        if not self._reset_done:
            raise RuntimeError("the environment has not been reset: call reset() first")

    def _observations(self) -> dict[str, np.ndarray]:
        return dict(zip(self.agents, self._core.observations()[0], strict=True))

    def _infos(self) -> dict[str, dict[str, Any]]:
        arrays = self._core.infos()
        team = {key: arrays[key][0].item() for key in TEAM_INFO_KEYS}
        served, rate, held = (arrays[key][0].tolist() for key in AGENT_INFO_KEYS)
        return {agent: {**team, "users_served": k, "throughput_per_user_mbps": r, "separation_held": h}
                for agent, k, r, h in zip(self.agents, served, rate, held, strict=True)}


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
