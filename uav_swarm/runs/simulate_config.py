"""Configuration of the main job (``uav-swarm simulate``): one dataclass, defaults embedded.

A TOML file (``uav-swarm simulate --config file.toml``) holds the top-level keys below and the
tables ``[task]`` (:class:`uav_swarm.missions.wifi.task.WifiConfig`: raster, scenario, crowd, radio,
expert; the same table as a task settings file), ``[uav]`` (flight limits), ``[planning]``
(:class:`uav_swarm.planning.planner.PlannerConfig`), ``[telemetry]``
(:class:`bridge.telemetry.config.TelemetryConfig`) and ``[ros2]``
(:class:`uav_swarm.runs.outputs.ros2.config.Ros2Config`).
Every key is optional.

Examples:
    >>> cfg = SimulateConfig.from_dict({"duration_s": 10, "task": {"scenario": {"n_groups_max": 8}}})
    >>> cfg.n_steps, cfg.task.scenario.n_groups_max, cfg.env_config().action_mode
    (100, 8, 'waypoint')
    >>> SimulateConfig(n_uavs=11)
    Traceback (most recent call last):
    ...
    typed_config.ConfigError: SimulateConfig.n_uavs = 11 is out of range: allowed 1 <= n_uavs <= 10
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from bridge.telemetry.config import TelemetryConfig
from typed_config import Config, load_with_overrides, param
from uav_swarm.env.config import MAX_UAVS, EnvConfig
from uav_swarm.missions.wifi.task import WifiConfig
from uav_swarm.planning.base import task_with_uav_separation
from uav_swarm.planning.planner import PlannerConfig
from uav_swarm.runs.outputs.ros2.config import Ros2Config
from uav_swarm.runs.radio_altitude import check_radio_altitude, radio_for_run, run_task, with_run_radio
from uav_swarm.world.uav import UAVConfig

__all__ = ["SimulateConfig", "load_simulate_config"]


@dataclass(frozen=True)
class SimulateConfig(Config):
    """The dynamic sequence, the planners, and the outputs of ``uav-swarm simulate``."""

    seed: int = param(0, ge=0, doc="seed of the scenario, the crowd and the UAV start positions")
    duration_s: float = param(180.0, gt=0.0, le=3600.0, doc="simulated time of the sequence (s)")
    n_uavs: int = param(MAX_UAVS, ge=1, le=MAX_UAVS, doc="number of UAVs")
    replan_every: int = param(10, ge=1, le=100_000, doc="environment steps between replans (0.1 s each)")
    planner: Literal["learned", "expert"] = param("learned", doc="the planner flown (and published)")
    checkpoint: str = param("", doc="learned planner checkpoint (empty: the shipped one the task flies)")
    compare_expert: bool = param(True, doc="run the same sequence with the expert planner too")
    static_reference: bool = param(
        True, doc="judge the expert's placement of the crowd every static_every_s as if reached, and report "
        "flown / static (uav_swarm.runs.service)")
    static_every_s: float = param(10.0, gt=0.0, le=3600.0, doc="seconds between static reference instants")
    gif: bool = param(True, doc="write scene.gif of the flown planner's run")
    gif_max_frames: int = param(100, ge=2, le=1000, doc="most frames in scene.gif (every N-th step)")
    gif_width_px: int = param(1000, ge=900, le=2400,
                              doc="width of a scene.gif frame (px): scene and utility map side by side")
    publish_telemetry: bool = param(True, doc="publish states, plans and QoS over Zenoh ([telemetry])")
    telemetry_every: int = param(1, ge=1, le=100_000, doc="steps between two published states and QoS")
    wait_for_subscriber_s: float = param(0.0, ge=0.0, le=600.0,
                                         doc="wait this long for a telemetry subscriber before flying (s)")
    bridge_config: str = param("", doc="bridge TOML (home, mission, vehicles); vehicles: upload the plans")
    task: WifiConfig = param(run_task(), doc="Wi-Fi task: raster, scenario, crowd, radio (802.11 unless "
                             "[task.radio] propagation = \"paper\"), expert ([task])")
    uav: UAVConfig = param(UAVConfig(), doc="UAV flight limits ([uav])")
    planning: PlannerConfig = param(PlannerConfig(), doc="assignment and inference ([planning])")
    telemetry: TelemetryConfig = param(TelemetryConfig(), doc="Zenoh session ([telemetry]); loopback only")
    ros2: Ros2Config = param(Ros2Config(), doc="ROS 2 topics and operator targets ([ros2]); loopback only")

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, where: str | None = None) -> SimulateConfig:
        """As :meth:`Config.from_dict`; the 802.11 radio unless told, at ``uav.alt_m`` unless told."""
        return super().from_dict(with_run_radio(data), where=where)

    def check(self) -> None:
        """Strategy 2 takes admission control unless told; the radio's altitude; one separation.

        The radio's altitude and admission: :mod:`uav_swarm.runs.radio_altitude`. The placements keep
        ``[uav] min_separation_m``, which the fleet must be able to keep in the area.
        """
        if self.task == run_task():  # the default task flies at the UAVs' altitude
            object.__setattr__(self, "task", run_task(self.uav))
        object.__setattr__(self, "task", radio_for_run(self.task))
        check_radio_altitude(self.task, self.uav, "SimulateConfig")
        object.__setattr__(self, "task", task_with_uav_separation(self.task, self.uav, self.n_uavs))

    @property
    def dt_s(self) -> float:
        """Simulated seconds per environment step (one crowd step)."""
        return self.task.crowd.dt_s

    @property
    def n_steps(self) -> int:
        """Environment steps in the sequence (at least 1)."""
        return max(1, round(self.duration_s / self.dt_s))

    def env_config(self) -> EnvConfig:
        """The ``uav_swarm_v0`` config of the sequence: waypoint mode, the task's world.

        The environment gives the 802.11 radio each UAV's own altitude (``uav.altitudes_m``), never the
        radio's ``altitude_m``, which the planners' experts use: the environment's radio has it at 0.
        """
        side = self.task.size_px
        return EnvConfig(n_uavs=self.n_uavs, action_mode="waypoint", strategy=self.task.strategy,
                         max_cycles=self.n_steps, crowd_steps_per_env_step=1, density_shape=(side, side),
                         uav=self.uav, scenario=self.task.scenario, crowd=self.task.crowd,
                         radio=self.task.radio.replace(altitude_m=0.0))


def load_simulate_config(path: str | Path | None = None, overrides: dict[str, Any] | None = None
                         ) -> SimulateConfig:
    """The config from an optional TOML file, then ``overrides`` (top-level keys; a table's dict is merged).

    Raises:
        ConfigError: Unreadable file, unknown key or table, or an invalid value (named).
    """
    return load_with_overrides(SimulateConfig, path, overrides)
