"""The Wi-Fi missions as :class:`learning.task.Task`: strategy 1 (``wifi-s1``) and strategy 2 (``wifi-s2``).

A scene is the crowd of a random scenario (:func:`uav_swarm.world.scenario.random_scenario`)
after a warm-up of the social-force simulation (:class:`uav_swarm.world.crowd.CrowdSim`),
drawn uniformly in ``[warmup_min_s, warmup_max_s]`` so that groups have formed and walk
their routes (a scene keeps the pedestrians' velocities too); the expert placement
(:func:`uav_swarm.missions.wifi.expert.place_uavs`: the search expert for strategy 1, the group
expert of :mod:`uav_swarm.missions.wifi.group_expert` for strategy 2) is
solved by ``expert(scene)``, so regenerating a scene only for its QoS (as evaluation does)
costs the warm-up alone.

Observation (``float32``, shape ``(1, size_px, size_px)``): the pedestrian density map
(:func:`uav_swarm.world.raster.density_map`, row 0 = South) divided by ``density_scale``
(pedestrians per pixel that read as 1.0). With ``velocity_channels`` (shape ``(3, size_px, size_px)``)
two more channels hold the pedestrians' velocity components summed per pixel, scaled the same way.
The same function, :func:`crowd_raster`, rasterises
the live crowd for the placement planner.

Positions crossing the Task interface are pixel coordinates ``(x = column, y = row)``
(:func:`uav_swarm.world.raster.metres_to_pixels`); ``mission_dimension_px`` is the raster side,
so the metrics' match radius (10 %) is 6.4 px = 20 m on the default 64 px raster of 200 m.

The experts' rules (:class:`uav_swarm.missions.wifi.rules.CoverageRules`): a user is covered
within the radio's horizontal coverage radius (30 m by default); every UAV must be justified by
more than ``expert.min_group_size`` (30) users (strategy 1: users only it covers; strategy 2:
users it serves); strategy 2 also caps a UAV at ``capacity / min_user_rate`` (200 / 5 = 40)
users so that every covered user gets at least 5 Mbps.

QoS (:meth:`WifiTask.qos`, judged on the real crowd with :func:`uav_swarm.world.comms.evaluate_coverage`):
``"qos"`` is the strategy's QoS (strategy 1: share of users covered; strategy 2: share covered
with at least ``min_user_rate_mbps``), plus ``"qos_s1"``, ``"qos_s2"`` and ``"mean_throughput_mbps"``.

Examples:
    >>> task = WifiTask(WifiConfig(strategy=1))
    >>> scene = task.sample(np.random.default_rng(0))
    >>> task.observe(scene).shape
    (1, 64, 64)
    >>> task.qos(scene, task.expert(scene))["qos"] > 0.5
    True
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from learning.task import MAX_POSITIONS
from typed_config import Config, ConfigError, param
from uav_swarm.missions.wifi.expert import WifiExpertConfig, place_uavs
from uav_swarm.missions.wifi.ieee80211_expert import Ieee80211ExpertConfig, place_uavs_80211, refine_80211
from uav_swarm.missions.wifi.refine import WifiRefineConfig, refine_placement, strategy_refinement
from uav_swarm.missions.wifi.rule_check import WifiRuleCheck
from uav_swarm.missions.wifi.rules import CoverageRules
from uav_swarm.world.comms import RadioConfig, evaluate_coverage
from uav_swarm.world.crowd import CrowdConfig, CrowdSim
from uav_swarm.world.raster import density_map, metres_to_pixels, pixels_to_metres
from uav_swarm.world.scenario import ScenarioConfig, random_scenario
from uav_swarm.world.separation import check_fleet_fits
from uav_swarm.world.wifi.channels import plan_channels

__all__ = ["WifiConfig", "WifiScene", "WifiTask", "WifiRefiner", "coverage_rules", "crowd_raster",
           "planner_task"]


@dataclass(frozen=True)
class WifiConfig(Config):
    """Config of the Wi-Fi task (both strategies)."""

    strategy: int = param(1, ge=1, le=2, doc="1: maximise covered users; 2: the same with >= 5 Mbps each")
    size_px: int = param(64, ge=8, le=1024, doc="side of the square density raster (pixels)")
    density_scale: float = param(4.0, gt=0.0, le=1000.0, doc="pedestrians per pixel that read as 1.0")
    velocity_channels: bool = param(
        False, doc="two more observation channels: the pedestrians' x and y velocity summed per pixel, "
        "divided by density_scale (the crowd's motion, which the strategy-2 group expert plans for)")
    warmup_min_s: float = param(5.0, ge=0.0, le=3600.0, doc="shortest crowd warm-up before a scene (s)")
    warmup_max_s: float = param(30.0, ge=0.0, le=3600.0, doc="longest crowd warm-up before a scene (s)")
    scenario: ScenarioConfig = param(ScenarioConfig(), doc="random scenarios (table [task.scenario])")
    crowd: CrowdConfig = param(CrowdConfig(), doc="social-force crowd (table [task.crowd])")
    radio: RadioConfig = param(RadioConfig(), doc="Wi-Fi model (table [task.radio])")
    expert: WifiExpertConfig = param(WifiExpertConfig(), doc="the expert optimiser (table [task.expert])")
    min_separation_m: float = param(
        5.0, ge=0.0, le=1000.0, doc="no two UAV positions of a placement (expert, learned, refined) closer "
        "than this, metres (0: none); simulate, fly and the env take it from [uav] min_separation_m")

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, where: str | None = None) -> WifiConfig:
        """:meth:`typed_config.Config.from_dict`, reading the configs saved before the task had one minimum.

        Those (the shipped checkpoints' among them) kept the group expert's own ``[task.expert.groups]
        min_separation_m``: it becomes the task's ``min_separation_m`` (refused when both differ).
        """
        groups = data.get("expert", {}).get("groups") if isinstance(data.get("expert"), Mapping) else None
        if isinstance(groups, Mapping) and "min_separation_m" in groups:
            legacy = groups["min_separation_m"]
            if data.get("min_separation_m", legacy) != legacy:
                raise ConfigError(
                    f"{where or cls.__name__}: expert.groups.min_separation_m = {legacy!r} differs from "
                    f"min_separation_m = {data['min_separation_m']!r}: keep min_separation_m only")
            rest = {k: v for k, v in groups.items() if k != "min_separation_m"}
            data = {**data, "expert": {**data["expert"], "groups": rest}, "min_separation_m": legacy}
        return super().from_dict(data, where=where)

    def check(self) -> None:
        """A square area, ordered warm-ups, a radius or an altitude, the expert, a separation that fits.

        Under the 802.11 radio an admission on rate not given is the strategy's
        (:meth:`~uav_swarm.world.radio_config.RadioConfig.for_strategy`).
        """
        object.__setattr__(self, "radio", self.radio.for_strategy(self.strategy))
        if self.warmup_min_s > self.warmup_max_s:
            raise ConfigError(f"WifiConfig.warmup_min_s = {self.warmup_min_s} must be <= "
                              f"warmup_max_s = {self.warmup_max_s}")
        if self.scenario.width_m != self.scenario.height_m:
            raise ConfigError(f"WifiConfig.scenario: width_m = {self.scenario.width_m} must equal "
                              f"height_m = {self.scenario.height_m} (the raster is square)")
        if self.radio.propagation == "paper" and self.radio.coverage_radius_m <= 0.0:
            raise ConfigError(f"WifiConfig.radio.altitude_m = {self.radio.altitude_m} leaves no coverage: "
                              "allowed altitude_m < the radio range")
        if self.radio.propagation == "802.11":
            if self.expert.method != "auto":
                raise ConfigError(f"WifiConfig.expert.method = {self.expert.method!r} is the paper's "
                                  "radio's; under radio.propagation = '802.11' the 802.11 expert runs: "
                                  "use 'auto'")
            if not self.radio.altitude_m > 0.0:
                raise ConfigError("WifiConfig.radio.altitude_m = 0: the 802.11 radio needs the UAVs' height "
                                  "above the users; allowed 0 < altitude_m")
        check_fleet_fits(self.expert.max_uavs, self.min_separation_m, self.scenario.width_m,
                         self.scenario.height_m, field="task.min_separation_m")


@dataclass(frozen=True, eq=False)
class WifiScene:
    """One crowd.

    Attributes:
        users_m: ``(N, 2)`` float64 read-only pedestrian positions, metres.
        time_s: Simulated warm-up time of the crowd (s).
        velocities_m_s: ``(N, 2)`` float64 read-only pedestrian velocities (zeros for a crowd at rest).
    """

    users_m: np.ndarray
    time_s: float
    velocities_m_s: np.ndarray


def _scene(users_m: np.ndarray, time_s: float, velocities_m_s: np.ndarray | None = None) -> WifiScene:
    velocities_m_s = np.zeros_like(users_m) if velocities_m_s is None else velocities_m_s
    users_m.setflags(write=False)
    velocities_m_s.setflags(write=False)
    return WifiScene(users_m, time_s, velocities_m_s)


def coverage_rules(config: WifiConfig, max_uavs: int | None = None) -> CoverageRules:
    """The geometric constraints of the config's strategy (see the module docstring).

    Args:
        config: The task config.
        max_uavs: UAV budget; default ``config.expert.max_uavs``.
    """
    radio = config.radio
    max_users = None
    admission = config.strategy == 2 and radio.max_stations is not None
    if admission:
        max_users = radio.max_stations
    elif config.strategy == 2 and radio.min_user_rate_mbps > 0:
        max_users = int(math.floor(radio.capacity_mbps / radio.min_user_rate_mbps + 1e-9))
    return CoverageRules(radius_m=radio.coverage_radius_m, min_users=config.expert.min_group_size + 1,
                         max_users=max_users,
                         max_uavs=config.expert.max_uavs if max_uavs is None else max_uavs,
                         exclusive=config.strategy == 1, admission_control=admission,
                         min_separation_m=config.min_separation_m)


def planner_task(config: WifiConfig | None, n_uavs: int, *, min_separation_m: float = 0.0,
                 velocity_channels: bool | None = None) -> WifiTask:
    """The one task a planner of ``n_uavs`` UAVs plans, judges and rasterises with, built in one step.

    The config (default ``WifiConfig()``) with the expert's ``max_uavs`` capped to ``n_uavs``, the minimum
    separation the larger of the task's and ``min_separation_m`` (the UAVs'), and the raster's
    ``velocity_channels`` where given (a network's own).

    Examples:
        >>> task = planner_task(WifiConfig(min_separation_m=2.0), 3, min_separation_m=8.0)
        >>> task.config.min_separation_m, task.config.expert.max_uavs, task.rules.max_uavs
        (8.0, 3, 3)
    """
    config = WifiConfig() if config is None else config
    changes: dict[str, Any] = {}
    if min_separation_m > config.min_separation_m:
        changes["min_separation_m"] = min_separation_m
    if velocity_channels is not None and velocity_channels != config.velocity_channels:
        changes["velocity_channels"] = velocity_channels
    if config.expert.max_uavs > n_uavs:
        changes["expert"] = config.expert.replace(max_uavs=n_uavs)
    return WifiTask(config.replace(**changes) if changes else config)


def crowd_raster(users_m: np.ndarray, config: WifiConfig, velocities_m_s: np.ndarray | None = None
                 ) -> np.ndarray:
    """The observation of a crowd: ``(C, size_px, size_px)`` float32 (module docstring).

    Channel 0 is the scaled density; with ``config.velocity_channels``, channels 1 and 2 are the
    velocities' x and y components summed per pixel and scaled the same way.

    Raises:
        ValueError: ``config.velocity_channels`` without ``velocities_m_s``.
    """
    side = config.size_px
    area = (config.scenario.width_m, config.scenario.height_m, (side, side))
    channels = [density_map(users_m, *area)]
    if config.velocity_channels:
        if velocities_m_s is None:
            raise ValueError("this task's raster has velocity channels: pass the pedestrians' velocities_m_s")
        velocities_m_s = np.asarray(velocities_m_s, dtype=np.float64).reshape(-1, 2)
        channels += [density_map(users_m, *area, weights=velocities_m_s[:, axis]) for axis in (0, 1)]
    return np.stack(channels) / np.float32(config.density_scale)


class WifiRefiner:
    """Learned UAV positions refined on the real crowd (:mod:`uav_swarm.missions.wifi.refine`).

    Args:
        task: The Wi-Fi task (strategy 1 or 2).
        config: The refinement's effort; default the strategy's
            (:func:`uav_swarm.missions.wifi.refine.strategy_refinement`).

    Raises:
        ConfigError: ``config.relocation`` on strategy 1.
    """

    config_class = WifiRefineConfig

    def __init__(self, task: WifiTask, config: WifiRefineConfig | None = None) -> None:
        self.task = task
        self.config = config or strategy_refinement(task.config.strategy)
        self.config.check_rules(task.rules, "[refine]")

    @staticmethod
    def default_settings(task: WifiTask) -> dict[str, Any]:
        """The ``[refine]`` values a table leaves out: the strategy's own settings."""
        return strategy_refinement(task.config.strategy).to_dict()

    def refine(self, scene: WifiScene, positions_px: np.ndarray) -> np.ndarray:
        """``(k, 2)`` pixel positions obeying the strategy's rules, found from ``positions_px``."""
        task = self.task
        proposals_m = task.to_metres(positions_px)
        if task.config.radio.propagation == "802.11":
            refined_m = task.refine_80211(scene.users_m, proposals_m)
        else:
            refined_m = refine_placement(scene.users_m, proposals_m, task.rules, task.width_m, task.height_m,
                                         self.config)
        return task.to_pixels(refined_m)

    def solve(self, scene: WifiScene) -> np.ndarray:
        """The expert's placement (pixels), computed from the crowd."""
        return self.task.expert(scene)


class WifiTask:
    """Wi-Fi placement over a moving crowd, strategy 1 or 2 (see the module docstring).

    Args:
        config: The task config; default ``WifiConfig()`` (strategy 1).
    """

    config_class = WifiConfig
    refiner_class = WifiRefiner
    rule_check_class = WifiRuleCheck

    def __init__(self, config: WifiConfig | None = None) -> None:
        config = WifiConfig() if config is None else config
        if not isinstance(config, WifiConfig):
            raise TypeError(f"WifiTask needs a WifiConfig, got {type(config).__name__}")
        self.config = config
        self.channels = 3 if config.velocity_channels else 1
        self.vector_channels = (1, 2) if config.velocity_channels else ()
        self.name = f"wifi-s{config.strategy}"
        self.shape = (config.size_px, config.size_px)
        self.mission_dimension_px = float(config.size_px)
        self.rules = coverage_rules(config, min(config.expert.max_uavs, MAX_POSITIONS))
        self.width_m = config.scenario.width_m
        self.height_m = config.scenario.height_m

    def to_pixels(self, xy_m: np.ndarray) -> np.ndarray:
        """Metres to raster pixel coordinates ``(x, y)``."""
        return metres_to_pixels(np.asarray(xy_m, np.float64).reshape(-1, 2), self.width_m, self.height_m,
                                self.shape)

    def to_metres(self, xy_px: np.ndarray) -> np.ndarray:
        """Raster pixel coordinates ``(x, y)`` to metres."""
        return pixels_to_metres(np.asarray(xy_px, np.float64).reshape(-1, 2), self.width_m, self.height_m,
                                self.shape)

    @property
    def expert_name(self) -> str:
        """The expert that places for this task, in words (the table and ``summary.json`` name it).

        Examples:
            >>> WifiTask(WifiConfig()).expert_name
            "search expert (strategy 1, the paper's radio without admission control)"
        """
        config = self.config
        method = "802.11" if config.radio.propagation == "802.11" else {
            "search": "search", "groups": "group", "capacitated": "capacitated", "stable": "stable"}[
            config.expert.method_for(self.rules)]
        return f"{method} expert (strategy {config.strategy}, {config.radio.radio_and_admission})"

    def expert_placement_m(self, users_m: np.ndarray, velocities_m_s: np.ndarray | None = None) -> np.ndarray:
        """The expert's ``(k, 2)`` UAV positions (metres) for any crowd ``users_m`` (metres).

        ``velocities_m_s`` (``(N, 2)``, optional) lets the strategy-2 group expert plan for the crowd
        of the next second (:mod:`uav_swarm.missions.wifi.group_expert`); the search expert ignores it.
        """
        config = self.config
        if config.radio.propagation == "802.11":
            return place_uavs_80211(users_m, config.radio, self.width_m, self.height_m,
                                    strategy=config.strategy, max_uavs=self.rules.max_uavs,
                                    min_separation_m=config.min_separation_m, config=config.expert.ieee80211)
        return place_uavs(users_m, self.rules, self.width_m, self.height_m, config.expert,
                          velocities_m_s=velocities_m_s)

    def refine_80211(self, users_m: np.ndarray, proposals_m: np.ndarray, max_uavs: int | None = None,
                     config: Ieee80211ExpertConfig | None = None) -> np.ndarray:
        """Proposed positions (metres) refined on the crowd under the 802.11 radio, at most ``max_uavs``.

        The 802.11 expert's search from the proposals
        (:func:`~uav_swarm.missions.wifi.ieee80211_expert.refine_80211`), with the task's
        ``[task.expert.ieee80211]`` settings unless ``config`` is given.
        """
        task = self.config
        return refine_80211(users_m, proposals_m, task.radio, self.width_m, self.height_m,
                            strategy=task.strategy, max_uavs=max_uavs or self.rules.max_uavs,
                            min_separation_m=task.min_separation_m, config=config or task.expert.ieee80211)

    def sample(self, rng: np.random.Generator) -> WifiScene:
        """Draw a scenario and warm its crowd up for a random time."""
        cfg = self.config
        scenario = random_scenario(rng, cfg.scenario)
        crowd = CrowdSim(scenario, cfg.crowd, rng)
        warmup_s = float(rng.uniform(cfg.warmup_min_s, cfg.warmup_max_s))
        steps = int(round(warmup_s / cfg.crowd.dt_s))
        if steps:
            crowd.step(steps)
        return _scene(np.array(crowd.positions_m, dtype=np.float64), float(crowd.time_s),
                      np.array(crowd.velocities_m_s, dtype=np.float64))

    def transform_scene(self, scene: WifiScene, flip_x: bool, flip_y: bool, transpose: bool) -> WifiScene:
        """The crowd under a symmetry of the square area (as :mod:`learning.symmetry` acts on pixels)."""
        users_m = np.array(scene.users_m, dtype=np.float64)
        velocities = np.array(scene.velocities_m_s, dtype=np.float64)
        if flip_x:
            users_m[:, 0] = self.width_m - users_m[:, 0]
            velocities[:, 0] = -velocities[:, 0]
        if flip_y:
            users_m[:, 1] = self.height_m - users_m[:, 1]
            velocities[:, 1] = -velocities[:, 1]
        if transpose:
            users_m = users_m[:, ::-1].copy()
            velocities = velocities[:, ::-1].copy()
        return _scene(users_m, scene.time_s, velocities)

    def jitter_scene(self, scene: WifiScene, rng: np.random.Generator, scale: float) -> WifiScene:
        """The crowd, each pedestrian moved by a normal draw of ``scale`` metres per axis, kept inside.

        Velocities are kept as they are.
        """
        users_m = scene.users_m + rng.normal(0.0, scale, scene.users_m.shape)
        upper = np.nextafter(np.array([self.width_m, self.height_m]), 0.0)
        return _scene(np.clip(users_m, 0.0, upper), scene.time_s, np.array(scene.velocities_m_s))

    def observe(self, scene: WifiScene) -> np.ndarray:
        """``(1, size, size)`` float32 scaled pedestrian density."""
        return crowd_raster(scene.users_m, self.config, scene.velocities_m_s)

    def expert(self, scene: WifiScene) -> np.ndarray:
        """The expert's ``(k, 2)`` float64 positions in pixels, ``0 <= k <= 10``, sorted by ``(y, x)``."""
        return self.to_pixels(self.expert_placement_m(scene.users_m, scene.velocities_m_s))

    def qos(self, scene: WifiScene, positions_px: np.ndarray) -> dict[str, float]:
        """QoS of UAVs at ``positions_px`` over the scene's crowd (see the module docstring).

        Raises:
            ValueError: ``positions_px`` is not a finite ``(k, 2)`` array.
        """
        positions = np.asarray(positions_px, dtype=np.float64)
        if positions.size == 0:
            positions = positions.reshape(0, 2)
        if positions.ndim != 2 or positions.shape[1] != 2 or not np.all(np.isfinite(positions)):
            raise ValueError(f"positions_px must be a finite (k, 2) array, got shape {positions.shape}")
        uavs_m = self.to_metres(positions)
        radio = self.config.radio
        channels = plan_channels(uavs_m, radio) if radio.propagation == "802.11" and len(uavs_m) else None
        coverage = evaluate_coverage(scene.users_m, uavs_m, radio, channels=channels)
        qos = coverage.qos_s1 if self.config.strategy == 1 else coverage.qos_s2
        return {"qos": float(qos), "qos_s1": float(coverage.qos_s1), "qos_s2": float(coverage.qos_s2),
                "mean_throughput_mbps": float(coverage.mean_throughput_mbps)}
