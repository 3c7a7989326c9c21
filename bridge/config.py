"""The bridge's configuration: home, mission shape, geofence, protocol timing, signing, vehicles.

Loaded from ``configs/bridge/*.toml`` with ``typed_config.load_toml(BridgeConfig, path)``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

from bridge.geo import Home
from bridge.geofence import GeofenceConfig
from bridge.missions.items import MissionConfig
from typed_config import Config, ConfigError, param

__all__ = [
    "ProtocolConfig",
    "SigningConfig",
    "VehicleEndpoint",
    "BridgeConfig",
    "MAX_VEHICLES",
    "URL_SCHEMES",
]

MAX_VEHICLES = 10
URL_SCHEMES = ("udpin:", "udpout:", "tcp:")


@dataclass(frozen=True)
class ProtocolConfig(Config):
    """MAVLink mission protocol timing (defaults: the protocol's own 1.5 s / 0.25 s / 5 retries)."""

    handshake_timeout_s: float = param(1.5, gt=0.0, le=60.0, doc="wait for the first answer, seconds")
    item_timeout_s: float = param(0.25, gt=0.0, le=60.0, doc="wait for each later answer, seconds")
    max_retries: int = param(5, ge=0, le=20, doc="re-sends of an unanswered message before giving up")
    transfer_attempts: int = param(
        3, ge=1, le=10, doc="whole-transfer attempts when one breaks off after the handshake"
    )
    heartbeat_timeout_s: float = param(5.0, gt=0.0, le=600.0, doc="vehicle discovery time, seconds")
    busy_retry_s: float = param(
        20.0,
        ge=0.0,
        le=600.0,
        doc="keep asking, with back-off, a vehicle that answers MISSION_COUNT with MAV_MISSION_NO_SPACE "
        "or MAV_MISSION_DENIED (still booting, or busy), seconds (0: no retry)",
    )
    home_timeout_s: float = param(
        60.0, gt=0.0, le=600.0,
        doc="wait for a vehicle's home (HOME_POSITION or, not ArduPilot, a position fix) before an upload, "
        "seconds (a freshly booted ArduPilot sets its home some 20 s after boot)",
    )


@dataclass(frozen=True)
class SigningConfig(Config):
    """MAVLink 2 message signing; the key comes from a file or an environment variable, never the TOML.

    The key text is 64 hex digits (the 32-byte key) or a passphrase, hashed with SHA-256 as
    MAVProxy and QGroundControl do; a key file may also hold the 32 raw bytes.
    """

    key_file: str = param("", doc="file holding the signing key (empty: none)")
    key_env: str = param("", doc="environment variable holding the signing key (empty: none)")
    link_id: int = param(0, ge=0, le=255, doc="MAVLink 2 signing link id of this ground station")
    allow_unsigned: bool = param(False, doc="accept unsigned messages from vehicles")

    def check(self) -> None:
        """At most one key source."""
        if self.key_file and self.key_env:
            raise ConfigError("SigningConfig: set key_file or key_env, not both")

    @property
    def enabled(self) -> bool:
        """True when a key source is configured."""
        return bool(self.key_file or self.key_env)


@dataclass(frozen=True)
class VehicleEndpoint(Config):
    """One vehicle: its MAVLink system id and the pymavlink connection string that reaches it."""

    system_id: int = param(1, ge=1, le=250, doc="the vehicle's MAVLink system id")
    url: str = param("udpin:127.0.0.1:14540", doc="pymavlink connection string: udpin:, udpout: or tcp:")

    def check(self) -> None:
        """The connection string must use a supported transport."""
        if not self.url.startswith(URL_SCHEMES) or self.url.count(":") != 2:
            raise ConfigError(
                f"VehicleEndpoint.url = {self.url!r}: use one of {list(URL_SCHEMES)} followed by host:port"
            )


@dataclass(frozen=True)
class BridgeConfig(Config):
    """Everything the MAVLink bridge needs for a fleet of up to 10 vehicles.

    In TOML, ``home = "vehicle"`` (instead of a ``[home]`` table) is short for
    ``home_source = "vehicle"``: each mission is built around its vehicle's own home.
    """

    home: Home = param(Home(), doc="geodetic origin of the local ENU frame")
    home_source: Literal["config", "vehicle"] = param(
        "config",
        doc="the home missions are built around: 'config' ([home], checked against each vehicle's "
        "reported home) or 'vehicle' (each vehicle's own reported home)",
    )
    max_home_offset_m: float = param(
        100.0,
        ge=0.0,
        le=20_000_000.0,
        doc="refuse an upload when a vehicle's reported home is farther than this from the mission's "
        "home, metres (0: do not check)",
    )
    mission: MissionConfig = param(MissionConfig(), doc="how plans become missions")
    geofence: GeofenceConfig = param(GeofenceConfig(), doc="allowed area and altitude band")
    protocol: ProtocolConfig = param(ProtocolConfig(), doc="mission protocol timing")
    signing: SigningConfig = param(SigningConfig(), doc="MAVLink 2 signing")
    source_system: int = param(255, ge=1, le=255, doc="our (ground station) MAVLink system id")
    source_component: int = param(190, ge=1, le=255, doc="our MAVLink component id (190: mission planner)")
    vehicles: tuple[VehicleEndpoint, ...] = param((), doc="the vehicles, one table each")

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, where: str | None = None) -> BridgeConfig:
        """Like :meth:`Config.from_dict`, reading ``home = "vehicle"`` as ``home_source = "vehicle"``."""
        if data.get("home") == "vehicle":
            if data.get("home_source", "vehicle") != "vehicle":
                raise ConfigError(
                    f"{where or cls.__name__}: home = \"vehicle\" contradicts home_source = "
                    f"{data['home_source']!r}"
                )
            data = {**{k: v for k, v in data.items() if k != "home"}, "home_source": "vehicle"}
        return super().from_dict(data, where=where)

    def check(self) -> None:
        """At most 10 vehicles, distinct system ids, none equal to ours."""
        if len(self.vehicles) > MAX_VEHICLES:
            raise ConfigError(
                f"BridgeConfig.vehicles has {len(self.vehicles)} entries: allowed at most {MAX_VEHICLES}"
            )
        ids = [v.system_id for v in self.vehicles]
        if len(set(ids)) != len(ids):
            raise ConfigError(f"BridgeConfig.vehicles: system ids must be distinct, got {ids}")
        if self.source_system in ids:
            raise ConfigError(
                f"BridgeConfig.source_system = {self.source_system} is also a vehicle's system id"
            )
