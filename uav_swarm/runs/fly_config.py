"""Configuration of a live flight (``uav-swarm fly``): one dataclass, defaults embedded.

A TOML file (``uav-swarm fly --config file.toml``) holds the top-level keys below and the tables
``[task]`` (the crowd world and Wi-Fi model, as for ``simulate``), ``[uav]`` (``alt_m`` is the cruise
altitude above each vehicle's home; ``min_separation_m`` the distance the guard keeps between any two
vehicles), ``[planning]``, ``[telemetry]``, ``[ros2]``, ``[flight]``
(:class:`bridge.flight.guided.FlightConfig`: launch timeouts, link timeout, end action), ``[launch]``
(:class:`uav_swarm.runs.flight.launch_plan.LaunchConfig`: where the vehicles take off) and ``[guard]``
(:class:`uav_swarm.runs.flight.guard.GuardConfig`: the separation guard). Every key is optional except
the bridge config, which names the vehicles.

Examples:
    >>> cfg = FlyConfig.from_dict({"bridge_config": "configs/bridge/ardupilot_sitl_10.toml", "speedup": 2})
    >>> cfg.mode, cfg.flight.end_action, cfg.speedup
    ('guided', 'rtl', 2.0)
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from bridge.flight.guided import FlightConfig
from bridge.telemetry.config import TelemetryConfig
from typed_config import Config, ConfigError, load_with_overrides, param
from uav_swarm.env.config import MAX_UAVS
from uav_swarm.missions.wifi.task import WifiConfig
from uav_swarm.planning.base import task_with_uav_separation
from uav_swarm.planning.planner import PlannerConfig
from uav_swarm.runs.flight.guard import GuardConfig
from uav_swarm.runs.flight.launch_plan import LaunchConfig, check_launch_grid
from uav_swarm.runs.outputs.ros2.config import Ros2Config
from uav_swarm.runs.radio_altitude import check_radio_altitude, radio_for_run, run_task, with_run_radio
from uav_swarm.world.uav import UAVConfig

__all__ = ["FlyConfig", "load_fly_config"]


@dataclass(frozen=True)
class FlyConfig(Config):
    """Everything ``uav-swarm fly`` needs besides the bridge config's vehicles."""

    bridge_config: str = param("", doc="bridge TOML: home, geofence, protocol and the vehicles (required)")
    n_uavs: int = param(0, ge=0, le=MAX_UAVS, doc="vehicles flown: the bridge config's first ones (0: all)")
    seed: int = param(0, ge=0, doc="seed of the simulated scenario and crowd")
    duration_s: float = param(300.0, gt=0.0, le=86400.0, doc="simulated crowd time of the flight, seconds")
    speedup: float = param(1.0, ge=0.1, le=100.0, doc="simulated crowd seconds per wall-clock second")
    replan_every_s: float = param(1.0, ge=0.1, le=600.0, doc="simulated seconds between two replans")
    record_every_s: float = param(0.5, ge=0.1, le=60.0,
                                  doc="simulated seconds between two QoS / track records (and /qos messages)")
    static_every_s: float = param(10.0, gt=0.0, le=3600.0,
                                  doc="crowd seconds between static reference instants (summary.json)")
    status_every_s: float = param(5.0, ge=0.5, le=60.0,
                                  doc="wall-clock seconds between two status lines (what fly waits for)")
    planner: Literal["learned", "expert"] = param("learned", doc="the planner that flies the vehicles")
    checkpoint: str = param("", doc="learned planner checkpoint (empty: the shipped one the task flies)")
    mode: Literal["guided", "mission"] = param(
        "guided", doc="how targets reach the vehicles: 'guided' (MAV_CMD_DO_REPOSITION) or 'mission' "
                      "(a new mission uploaded and flown in AUTO)")
    publish_telemetry: bool = param(True, doc="publish states, plans and QoS over Zenoh ([telemetry])")
    task: WifiConfig = param(run_task(), doc="the crowd world and Wi-Fi model (802.11 unless [task.radio] "
                             "propagation = \"paper\") ([task])")
    uav: UAVConfig = param(UAVConfig(), doc="alt_m: cruise altitude above each vehicle's home ([uav])")
    planning: PlannerConfig = param(PlannerConfig(), doc="assignment and inference ([planning])")
    telemetry: TelemetryConfig = param(TelemetryConfig(), doc="Zenoh session ([telemetry]); loopback only")
    ros2: Ros2Config = param(Ros2Config(), doc="ROS 2 topics and operator targets ([ros2]); loopback only")
    flight: FlightConfig = param(FlightConfig(), doc="launch, link and end of the flight ([flight])")
    launch: LaunchConfig = param(LaunchConfig(), doc="where the vehicles take off ([launch])")
    guard: GuardConfig = param(GuardConfig(), doc="the separation guard on measured positions ([guard])")
    set_failsafe: bool = param(False, doc="set a vehicle's missing link-loss failsafe to return to launch "
                                          "(PARAM_SET, read back) instead of refusing it")

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, where: str | None = None) -> FlyConfig:
        """As :meth:`Config.from_dict`; the 802.11 radio unless told, at ``uav.alt_m`` unless told."""
        return super().from_dict(with_run_radio(data), where=where)

    def check(self) -> None:
        """A bridge config; S2 takes admission control unless told; the radio's altitude; one separation.

        The radio's altitude and admission: :mod:`uav_swarm.runs.radio_altitude`.

        The placements keep ``[uav] min_separation_m``, which the fleet must be able to keep in the area; a
        launch grid keeps it too.
        """
        if not self.bridge_config:
            raise ConfigError("bridge_config is empty: name the bridge TOML that lists the "
                              "vehicles (--bridge-config FILE), or fly a simulated fleet started here "
                              "(--simulated ardupilot or --simulated px4)")
        if self.task == run_task():  # the default task flies at the UAVs' altitude
            object.__setattr__(self, "task", run_task(self.uav))
        object.__setattr__(self, "task", radio_for_run(self.task))
        check_launch_grid(self.launch, self.uav, 2)
        check_radio_altitude(self.task, self.uav, "FlyConfig")
        fleet = self.n_uavs or MAX_UAVS  # 0: all the bridge's vehicles, at most MAX_UAVS
        object.__setattr__(self, "task", task_with_uav_separation(self.task, self.uav, fleet))


def load_fly_config(path: str | Path | None = None, overrides: dict[str, Any] | None = None) -> FlyConfig:
    """The config from an optional TOML file, then ``overrides`` (top-level keys; a table's dict is merged).

    Raises:
        ConfigError: Unreadable file, unknown key or table, or an invalid value (named).
    """
    return load_with_overrides(FlyConfig, path, overrides)
