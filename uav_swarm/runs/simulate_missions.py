"""The final missions of a ``simulate`` run: the bridge config checked, one plan per UAV, written, uploaded.

The run ends with each UAV's last target as a mission (``missions/vehicle_<id>.plan``) and, when the
bridge config lists vehicles, uploads them (:class:`bridge.flight.fleet.Fleet`).
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from uav_swarm.planning.spacing import separate_targets

if TYPE_CHECKING:
    from bridge.config import BridgeConfig
    from uav_swarm.runs.simulate_config import SimulateConfig
    from uav_swarm.world.uav import UAVConfig

__all__ = ["load_bridge", "final_plans", "write_plan_files", "upload_plans"]

logger = logging.getLogger(__name__)


def load_bridge(config: SimulateConfig) -> BridgeConfig:
    """The run's bridge config, checked: a vehicle per UAV, the area at the flight altitude in the fence."""
    from bridge.config import BridgeConfig
    from bridge.geofence import check_geofence
    from bridge.missions.items import takeoff_altitude
    from typed_config import ConfigError, load_toml

    bridge = load_toml(BridgeConfig, config.bridge_config) if config.bridge_config else BridgeConfig()
    if bridge.vehicles and len(bridge.vehicles) < config.n_uavs:
        raise ConfigError(f"{config.bridge_config}: {len(bridge.vehicles)} vehicles for n_uavs = "
                          f"{config.n_uavs}: list at least one vehicle per UAV")
    # Every target lies in the area: its corners at the flight altitude must be inside the fence.
    width_m, height_m, alt_m = config.task.scenario.width_m, config.task.scenario.height_m, config.uav.alt_m
    corners = [(0.0, 0.0, alt_m), (width_m, 0.0, alt_m), (0.0, height_m, alt_m), (width_m, height_m, alt_m)]
    check_geofence([(0.0, 0.0, takeoff_altitude(corners, bridge.mission)), *corners], bridge.geofence)
    return bridge


def final_plans(bridge: BridgeConfig, targets_m: np.ndarray, uav: UAVConfig, area_m: np.ndarray
                 ) -> dict[int, list[tuple]]:
    """Each UAV's plan, its final target at its simulated altitude (``uav.altitudes_m``), by system id.

    Ids are the configured vehicles' (else 1..n). The take-off then climbs no higher than the
    altitude (:func:`bridge.missions.items.takeoff_altitude`): the mission never descends. The targets
    are the planner's, at least ``uav.min_separation_m`` apart (horizontally); a plan file never holds
    closer ones (:func:`uav_swarm.planning.spacing.separate_targets`, a no-op on the planner's targets).
    """
    targets_m = separate_targets(targets_m, uav.min_separation_m, upper_m=area_m)
    ids = [v.system_id for v in bridge.vehicles[:len(targets_m)]] or list(range(1, len(targets_m) + 1))
    altitudes = uav.altitudes_m(len(targets_m))
    return {sid: [(float(x), float(y), float(z))]
            for sid, (x, y), z in zip(ids, targets_m, altitudes, strict=True)}


def write_plan_files(bridge: BridgeConfig, plans: dict[int, list[tuple]], folder: Path) -> list[Path]:
    """One QGroundControl ``.plan`` per UAV (generic autopilot convention)."""
    from bridge.missions.files import save_mission
    from bridge.missions.items import build_mission

    folder.mkdir(parents=True, exist_ok=True)
    files = []
    for sid, points in plans.items():
        path = folder / f"vehicle_{sid}.plan"
        save_mission(path, build_mission(points, bridge.home, bridge.mission, bridge.geofence))
        files.append(path)
    return files


def upload_plans(bridge: BridgeConfig, plans: dict[int, list[tuple]]) -> None:
    """Upload each UAV's mission to its vehicle (each on its own: heartbeat, home check, verified upload).

    Raises:
        bridge.flight.fleet.FleetError: Naming each vehicle that failed; the others have their missions.
    """
    from bridge.flight.fleet import Fleet

    logger.info("uploading the final missions to vehicles %s (they must be running: SITL, real autopilots or "
                "uav-swarm vehicles); each waits for its heartbeat first", sorted(plans))
    with Fleet(bridge) as fleet:
        fleet.upload_plans(plans)
    logger.info("uploaded the final missions to vehicles %s", sorted(plans))
