"""The batch-first core of ``uav_swarm_v0``: the state of B worlds and their step, in numpy arrays.

A world is a scenario, a crowd walking in it and K UAVs over it. :class:`SwarmCore` holds B of them:
the crowds stacked in one :class:`~uav_swarm.world.crowd_batch.BatchedCrowd` (or one
:class:`~uav_swarm.world.crowd.CrowdSim` for a single world), the UAVs as ``(B, K, 2)`` arrays, and
after every reset or step the density maps, the coverage, the separation and the reward of every world.
It calls the world's own models and writes none of them again: the kinematics and the waypoint
controller of :mod:`uav_swarm.world.uav`, the separation of :mod:`uav_swarm.world.separation`, the radio
(both associations) of :mod:`uav_swarm.world.comms_batch`, the density of :mod:`uav_swarm.world.raster`;
observations, rewards and infos are :mod:`uav_swarm.env.observe`'s. The PettingZoo environment
(:class:`~uav_swarm.env.parallel.raw_env`) is a shell over one world, :class:`~uav_swarm.env.batched.
BatchedUAVSwarm` and the vector views shells over B.

Examples:
    >>> import numpy as np
    >>> from uav_swarm.env.config import EnvConfig
    >>> core = SwarmCore(2, EnvConfig(n_uavs=3, max_cycles=5))
    >>> core.reset([0, 1], np.array([0, 1]))
    >>> core.step(np.zeros((2, 3, 2)))
    >>> core.observations().shape, core.reward.shape, core.cycle.tolist()
    ((2, 3, 260), (2,), [1, 1])
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from uav_swarm.env.config import EnvConfig
from uav_swarm.env.observe import Layout, info_arrays, observe, team_reward
from uav_swarm.world.comms import Association
from uav_swarm.world.comms_batch import CoverageBatch, StackedIncumbents, coverage_batch
from uav_swarm.world.crowd import CrowdSim
from uav_swarm.world.crowd_batch import BatchedCrowd
from uav_swarm.world.raster import density_maps
from uav_swarm.world.scenario import Scenario, random_scenario
from uav_swarm.world.separation import (
    closest_distances_m,
    draw_apart_m,
    pair_distances_m,
    required_distances_m,
    separation_penalty,
)
from uav_swarm.world.step_guard import guard_commands
from uav_swarm.world.uav import fly_step, waypoint_velocity
from uav_swarm.world.wifi.channels import plan_channels
from uav_swarm.world.wifi.coverage import access_points_on, uav_channels

__all__ = ["SwarmCore"]


class SwarmCore:
    """B worlds of ``uav_swarm_v0`` (one config), reset and stepped as arrays.

    Args:
        num_worlds: Number of worlds B (>= 1).
        config: The environment configuration.
        scene: Fixes the scene of every world and episode (else each reset draws one per world).
        stacked_crowd: Keep the crowds in one :class:`BatchedCrowd` (else ``num_worlds`` must be 1 and the
            crowd is a :class:`CrowdSim`).

    Attributes:
        layout: The observation layout and boxes (:class:`~uav_swarm.env.observe.Layout`).
        positions_m: (B, K, 2) UAV positions (replaced, never written in place, at every step).
        velocities_m_s: (B, K, 2) UAV velocities.
        targets_m: (B, K, 2) waypoint targets (waypoint mode; the start positions otherwise).
        altitudes_m: (K,) each UAV's flight altitude (``uav.alt_m`` plus ``uav.layer_step_m`` per index).
        cycle: (B,) steps since each world's reset.
        coverage: The coverage after the last reset or step (:class:`CoverageBatch`).
        separation: (B,) separation penalty; ``closest_m`` (B,) the closest UAV pair's distance (m).
        held: (B, K) bool, the separation guard held the UAV's waypoint command back at the last step.
        reward: (B,) float64 team reward.
    """

    def __init__(self, num_worlds: int, config: EnvConfig, scene: Scenario | None = None,
                 stacked_crowd: bool = True) -> None:
        if not stacked_crowd and num_worlds != 1:
            raise ValueError("an unstacked crowd holds one world: num_worlds must be 1")
        self.config = cfg = config
        self.num_worlds = b = int(num_worlds)
        self.scene = scene
        area = scene if scene is not None else cfg.scenario
        self.width_m, self.height_m = float(area.width_m), float(area.height_m)
        self.area_m = np.array([self.width_m, self.height_m])
        self.dt_s = cfg.crowd_steps_per_env_step * cfg.crowd.dt_s
        self.radio = cfg.effective_radio
        self.layout = Layout(cfg, self.width_m, self.height_m)
        self.altitudes_m = cfg.uav.altitudes_m(cfg.n_uavs)
        layered = bool(np.any(self.altitudes_m != cfg.uav.alt_m))
        # The radio sees each UAV's own altitude when the layers differ and 3D distances are on; the 802.11
        # model always does (its path loss depends on the elevation angle).
        wifi = self.radio.propagation == "802.11"
        self._radio_altitudes_m = self.altitudes_m if (cfg.use_3d_distance and layered) or wifi else None
        self.channel_plan: np.ndarray | None = None
        """(B, K) each UAV's channel (802.11 model): :meth:`set_channel_plan`'s, else the environment's."""
        self.access_points_on: np.ndarray | None = None
        """(B, K) bool, the UAVs whose access point is on (802.11 model); None: all."""
        self._plans_channels = wifi
        """Whether the environment plans the channels itself (802.11, no plan given)."""
        self._guard_altitudes_m = self.altitudes_m if layered else None
        # UAVs start apart: a draw closer than the minimum is drawn again (world/separation.draw_apart_m).
        self._start_gaps_m = required_distances_m(cfg.uav.min_separation_m, self._guard_altitudes_m,
                                                  cfg.n_uavs)
        self._stacked = stacked_crowd
        # Admission control and the 802.11 model keep per-world incumbents; the paper's model is memoryless.
        self._links: list[Association] | StackedIncumbents | None = StackedIncumbents(b) if wifi else \
            [Association(self.radio) for _ in range(b)] if self.radio.max_stations is not None else None
        (h, w), p = cfg.density_shape, cfg.patch_px
        self._padded_share_map = np.zeros((b, h + p - 1, w + p - 1), dtype=np.float32)  # zero border
        self._patch_windows = sliding_window_view(self._padded_share_map, (p, p), axis=(1, 2))
        self.rngs: list[np.random.Generator | None] = [None] * b
        self._crowd: CrowdSim | None = None
        self._batched_crowd: BatchedCrowd | None = None
        n = cfg.n_uavs
        self.positions_m = np.zeros((b, n, 2))
        self.velocities_m_s = np.zeros((b, n, 2))
        self.targets_m = np.zeros((b, n, 2))
        self.cycle = np.zeros(b, dtype=np.int64)
        self.held = np.zeros((b, n), dtype=bool)

    def __getstate__(self) -> dict:
        """The state without the patch windows: a view of the share maps, rebuilt on the copy's own maps."""
        state = self.__dict__.copy()
        del state["_patch_windows"]
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        p = self.config.patch_px
        self._patch_windows = sliding_window_view(self._padded_share_map, (p, p), axis=(1, 2))

    # --- reset and step -------------------------------------------------------------------

    @property
    def crowd(self) -> CrowdSim:
        """The crowds: one :class:`CrowdSim`, or all worlds' in one :class:`BatchedCrowd`."""
        if self._crowd is None:
            raise RuntimeError("the worlds have not been reset: call reset() first")
        return self._crowd

    @property
    def batched_crowd(self) -> BatchedCrowd:
        """The stacked crowds of all worlds (``stacked_crowd=True``)."""
        if self._batched_crowd is None:
            raise RuntimeError("the crowds are not stacked, or the worlds have not been reset")
        return self._batched_crowd

    def rng(self, world: int) -> np.random.Generator:
        """World ``world``'s generator (seeded from entropy if it has none yet)."""
        rng = self.rngs[world]
        if rng is None:
            rng = self.rngs[world] = np.random.default_rng()
        return rng

    def reset(self, seeds: Sequence[int | None], worlds: np.ndarray) -> None:
        """Draw new scenarios, crowds and UAV start positions for ``worlds``.

        World ``c`` restarts from ``default_rng(seeds[c])`` when its seed is given (or it has no
        generator yet) and otherwise continues its generator, which draws the scenario, the crowd and the
        UAV start positions, in that order.

        Args:
            seeds: One seed or None per world (B entries; those of other worlds are ignored).
            worlds: Indices of the worlds to reset (all of them at the first reset).
        """
        cfg, sims = self.config, []
        self.positions_m = self.positions_m.copy()  # views handed out earlier keep their values
        self.velocities_m_s = self.velocities_m_s.copy()
        for c in worlds:
            if seeds[c] is not None or self.rngs[c] is None:
                self.rngs[c] = np.random.default_rng(seeds[c])
            rng = self.rngs[c]
            scenario = self.scene if self.scene is not None else random_scenario(rng, cfg.scenario)
            sims.append(CrowdSim(scenario, cfg.crowd, rng))
            self.positions_m[c] = draw_apart_m(rng, cfg.n_uavs, self.area_m, self._start_gaps_m)
        if not self._stacked:
            self._crowd = sims[0]
        elif self._batched_crowd is None or len(worlds) == self.num_worlds:
            self._crowd = self._batched_crowd = BatchedCrowd(sims)
        else:
            self._batched_crowd.replace(worlds, sims)
        self.velocities_m_s[worlds] = 0.0
        self.targets_m[worlds] = self.positions_m[worlds]
        self.cycle[worlds] = 0
        self.held[worlds] = False
        if isinstance(self._links, StackedIncumbents):
            self._links.reset(worlds)
        elif self._links is not None:
            for c in worlds:
                self._links[c].reset()
        self._update_view()

    def set_channel_plan(self, channels: np.ndarray | None) -> None:
        """Each UAV's channel from the next step on (802.11 radio).

        ``channels``: (K,) or (B, K) channel numbers; None: the environment plans them itself after every
        reset and step (:func:`~uav_swarm.world.wifi.channels.plan_channels` on the UAVs' positions and
        altitudes, the plan in force kept while it stays valid), the default.

        Raises:
            ValueError: The paper's radio, a shape or a channel the radio does not take.
        """
        if channels is not None and self.radio.propagation != "802.11":
            raise ValueError("a channel plan applies only with RadioConfig.propagation = '802.11'")
        self._plans_channels = channels is None and self.radio.propagation == "802.11"
        if channels is not None:
            self.channel_plan = uav_channels(channels, self.num_worlds, self.config.n_uavs, self.radio).copy()

    def set_access_points(self, enabled: np.ndarray | None) -> None:
        """Which UAVs' access points are on from the next step on (802.11 radio).

        ``enabled``: (K,) or (B, K) bool; an AP that is off transmits nothing (under admission on rate, a UAV
        the plan gives no users keeps its AP off, so that it takes no airtime from the APs that serve). None:
        every AP on (the default).

        Raises:
            ValueError: The paper's radio, or a shape that is neither.
        """
        if enabled is not None and self.radio.propagation != "802.11":
            raise ValueError("access points apply only with RadioConfig.propagation = '802.11'")
        self.access_points_on = None if enabled is None else \
            access_points_on(enabled, self.num_worlds, self.config.n_uavs).copy()

    def step(self, values: np.ndarray, given: np.ndarray | None = None, active: np.ndarray | None = None
             ) -> None:
        """Apply one action per UAV and advance the crowds and the UAVs of the active worlds by ``dt_s``.

        Args:
            values: (B, K, 2) actions (clipped into the action box here).
            given: (B, K) bool, the UAVs that act; the others keep their target (waypoint mode) or are
                commanded to stop (velocity mode). All by default.
            active: (B,) bool, the worlds to step; the others do not move. All by default.
        """
        command = self.command_m_s(values, given, active)
        if active is None:
            self.crowd.step(self.config.crowd_steps_per_env_step)
        elif active.any() and self._batched_crowd is not None:  # one world: active.any() is all of it
            self._batched_crowd.step(self.config.crowd_steps_per_env_step, active=active)
        elif active.any():
            self.crowd.step(self.config.crowd_steps_per_env_step)
        positions, velocities = fly_step(self.positions_m, self.velocities_m_s, command, self.dt_s,
                                         self.config.uav, self.area_m)
        if active is None:
            self.positions_m, self.velocities_m_s = positions, velocities
            self.cycle += 1
        else:
            moving = active[:, None, None]
            self.positions_m = np.where(moving, positions, self.positions_m)
            self.velocities_m_s = np.where(moving, velocities, self.velocities_m_s)
            self.cycle += active
        self._update_view()

    def command_m_s(self, values: np.ndarray, given: np.ndarray | None = None,
                    active: np.ndarray | None = None) -> np.ndarray:
        """(B, K, 2) velocity commands from actions: scaled (velocity mode) or flown to (waypoint mode).

        In waypoint mode the controller's commands pass through the separation guard
        (:func:`~uav_swarm.world.step_guard.guard_commands`), which records in :attr:`held` the UAVs it
        held back; velocity commands (the learning path) are not guarded.
        """
        cfg, layout = self.config, self.layout
        low, high = layout.action_bounds
        values = np.minimum(np.maximum(values, low), high)
        if cfg.action_mode == "velocity":
            command = values * cfg.uav.max_speed_m_s
            return command if given is None else np.where(given[..., None], command, 0.0)
        acting = np.ones(self.cycle.shape, bool)[:, None] if given is None else given
        if active is not None:
            acting = acting & active[:, None]
        self.targets_m = np.where(acting[..., None], values, self.targets_m)
        command = waypoint_velocity(self.positions_m, self.targets_m, self.dt_s, cfg.uav)
        safe, held = guard_commands(self.positions_m, self.velocities_m_s, command, self.dt_s, cfg.uav,
                                    altitudes_m=self._guard_altitudes_m, upper_m=self.area_m)
        self.held = held if active is None else np.where(active[:, None], held, self.held)
        return safe

    # --- what the worlds look like --------------------------------------------------------

    def _update_view(self) -> None:
        """Density maps, coverage, separation and rewards of every world (once per reset or step)."""
        cfg, b, stacked = self.config, self.num_worlds, self._batched_crowd
        (h, w), half = cfg.density_shape, cfg.patch_px // 2
        peds = self.crowd.positions_m
        copy = stacked.copy_index if stacked is not None else np.zeros(len(peds), np.intp)
        self.density = density_maps(peds, copy, b, self.width_m, self.height_m, cfg.density_shape)
        n_users = stacked.counts() if stacked is not None else np.array([len(peds)])
        self.share_map = self.density / np.maximum(n_users, 1).astype(np.float32)[:, None, None]
        self._padded_share_map[:, half:half + h, half:half + w] = self.share_map
        if self._plans_channels:  # a channel per UAV for where it is, few changes (docs/radio.md, section 7)
            self.channel_plan = plan_channels(self.positions_m, self.radio, self.altitudes_m,
                                              self.channel_plan, self.access_points_on)
        self.coverage: CoverageBatch = coverage_batch(peds, copy, self.positions_m, self.radio, self._links,
                                                      self._radio_altitudes_m, self.channel_plan,
                                                      self.access_points_on)
        distances_m = pair_distances_m(self.positions_m, self._guard_altitudes_m)
        self.separation = separation_penalty(self.positions_m, cfg.uav.min_separation_m,
                                             distances_m=distances_m)
        self.closest_m = closest_distances_m(self.positions_m, distances_m=distances_m)
        self.reward = team_reward(self.coverage, self.separation, cfg)

    def observations(self) -> np.ndarray:
        """(B, K, obs_dim) float32 observations of every agent."""
        return observe(self.layout, self.positions_m, self.velocities_m_s, self._patch_windows, self.coverage)

    def infos(self) -> dict[str, np.ndarray]:
        """The info arrays of every world (:func:`~uav_swarm.env.observe.info_arrays`)."""
        return info_arrays(self.coverage, self.separation, self.closest_m, self.held)

    def states(self) -> np.ndarray:
        """(B, h*w + 2K) float32: each world's share map and normalised UAV positions."""
        positions = (self.positions_m / self.area_m).reshape(self.num_worlds, -1).astype(np.float32)
        return np.concatenate([self.share_map.reshape(self.num_worlds, -1), positions], axis=1)
