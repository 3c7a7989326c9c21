"""Configuration of the ``uav_swarm_v0`` environment (one dataclass, nested world configs).

Examples:
    >>> cfg = EnvConfig.from_dict({"n_uavs": 3, "uav": {"max_speed_m_s": 6.0}})
    >>> cfg.n_uavs, cfg.uav.max_speed_m_s, cfg.density_shape
    (3, 6.0, (64, 64))
    >>> EnvConfig(n_uavs=11)
    Traceback (most recent call last):
    ...
    typed_config.ConfigError: EnvConfig.n_uavs = 11 is out of range: allowed 1 <= n_uavs <= 10
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

from typed_config import Config, ConfigError, param
from uav_swarm.world.crowd import CrowdConfig
from uav_swarm.world.radio_config import RUN_PROPAGATION, RadioConfig
from uav_swarm.world.scenario import ScenarioConfig
from uav_swarm.world.separation import check_fleet_fits
from uav_swarm.world.uav import UAVConfig

__all__ = ["EnvConfig", "MAX_UAVS", "merge_overrides"]

MAX_UAVS = 10
"""The largest swarm the environment accepts; observations are padded to this size."""


@dataclass(frozen=True)
class EnvConfig(Config):
    """Everything that defines a ``uav_swarm_v0`` environment."""

    n_uavs: int = param(4, ge=1, le=MAX_UAVS, doc="number of UAVs (agents uav_0 .. uav_{n-1})")
    action_mode: Literal["velocity", "waypoint"] = param(
        "velocity", doc="'velocity': normalised velocity commands; 'waypoint': target positions in metres")
    strategy: int = param(1, ge=1, le=2,
                          doc="reward QoS: 1 = share covered, 2 = share covered with >= min_user_rate_mbps")
    max_cycles: int = param(500, ge=1, le=1_000_000, doc="steps before the episode is truncated")
    crowd_steps_per_env_step: int = param(1, ge=1, le=100, doc="crowd simulation steps per env step")
    density_shape: tuple[int, int] = param((64, 64), doc="(rows, columns) of the global density map")
    patch_px: int = param(15, ge=1, le=63, doc="side (density-map pixels, odd) of the local density patch")
    separation_weight: float = param(0.1, ge=0.0, le=100.0,
                                     doc="reward penalty per unit of separation intrusion")
    use_3d_distance: bool = param(False, doc="radio distance includes the flight altitude uav.alt_m")
    uav: UAVConfig = param(UAVConfig(), doc="UAV flight limits")
    scenario: ScenarioConfig = param(ScenarioConfig(), doc="random scenario generation")
    crowd: CrowdConfig = param(CrowdConfig(), doc="crowd simulation")
    radio: RadioConfig = param(
        RadioConfig(propagation=RUN_PROPAGATION), doc="Wi-Fi model: the 802.11 radio unless propagation = "
        "'paper' (under 802.11 an admission on rate not given is the strategy's)")

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, where: str | None = None) -> EnvConfig:
        """As :meth:`Config.from_dict`; a ``radio`` table without ``propagation`` is the 802.11 radio."""
        radio = data.get("radio")
        if isinstance(radio, Mapping) and "propagation" not in radio:
            data = {**data, "radio": {**radio, "propagation": RUN_PROPAGATION}}
        return super().from_dict(data, where=where)

    def check(self) -> None:
        """Cross-field rules: density map size, odd patch, one source for the altitude."""
        for side in self.density_shape:
            if not 4 <= side <= 1024:
                raise ConfigError(
                    f"EnvConfig.density_shape = {self.density_shape} is out of range: "
                    "allowed 4 <= each side <= 1024")
        if self.patch_px % 2 == 0:
            raise ConfigError(f"EnvConfig.patch_px = {self.patch_px} must be odd (the patch is centred)")
        if self.radio.altitude_m != 0.0:
            raise ConfigError(
                f"EnvConfig.radio.altitude_m = {self.radio.altitude_m}: the environment takes the altitude "
                "from uav.alt_m; set use_3d_distance = true instead")
        area = self.scenario
        check_fleet_fits(self.n_uavs, self.uav.min_separation_m, area.width_m, area.height_m)

    @property
    def effective_radio(self) -> RadioConfig:
        """The radio model of the strategy, with the flight altitude when ``use_3d_distance`` is set.

        Under 802.11 an admission on rate not given is the strategy's
        (:meth:`~uav_swarm.world.radio_config.RadioConfig.for_strategy`).
        """
        radio = self.radio.for_strategy(self.strategy)
        return radio.replace(altitude_m=self.uav.alt_m) if self.use_3d_distance else radio


def merge_overrides(config: EnvConfig, overrides: Mapping[str, Any]) -> EnvConfig:
    """A copy of ``config`` with keyword overrides; nested configs accept partial tables.

    Args:
        config: The base configuration.
        overrides: Field names to values; a nested config (``uav``, ``scenario``, ``crowd``,
            ``radio``) takes a Config instance or a mapping of some of its fields.

    Raises:
        ConfigError: An unknown field or an invalid value, named.
    """
    data = config.to_dict()
    for key, value in overrides.items():
        if isinstance(value, Config):
            data[key] = value.to_dict()
        elif isinstance(value, Mapping) and isinstance(data.get(key), dict):
            data[key] = {**data[key], **value}
        else:
            data[key] = value
    return EnvConfig.from_dict(data)
