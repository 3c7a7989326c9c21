"""MAVSDK (>= 4, the native binding) configured as autopilots: an independent mission server.

Each vehicle is a ``Mavsdk`` instance with component type AUTOPILOT and its own system id;
its MissionRawServer plugin records every mission it receives.
"""

from __future__ import annotations

import threading

from mavsdk import ComponentType, Configuration, Mavsdk, log_subscribe
from mavsdk.plugins.mission_raw_server import MissionRawServer, MissionRawServerResult

from bridge.missions.items import MissionItem

__all__ = ["MavsdkVehicle", "quiet_mavsdk_logs"]


def quiet_mavsdk_logs() -> None:
    """Keep MAVSDK's console logging out of the test output."""
    log_subscribe(lambda level, message, file, line: True)


class MavsdkVehicle:
    """A MAVSDK autopilot with system id ``system_id`` on ``url`` (e.g. ``udpout://127.0.0.1:14550``)."""

    def __init__(self, system_id: int, url: str) -> None:
        config = Configuration.create_with_component_type(ComponentType.AUTOPILOT)
        config.system_id = system_id
        config.component_id = 1
        self.system_id = system_id
        self.missions: list[tuple[MissionItem, ...]] = []
        self._received = threading.Condition()
        self._config = config
        self._mavsdk = Mavsdk(config)
        self._mavsdk.add_any_connection(url)
        self._server = MissionRawServer(self._mavsdk.server_component())
        self._server.subscribe_incoming_mission(self._on_mission)

    def _on_mission(self, result: MissionRawServerResult, plan, _user_data) -> None:
        if result != MissionRawServerResult.SUCCESS:
            return
        items = tuple(
            MissionItem(
                seq=i.seq,
                frame=i.frame,
                command=i.command,
                current=i.current,
                autocontinue=i.autocontinue,
                param1=i.param1,
                param2=i.param2,
                param3=i.param3,
                param4=i.param4,
                x=i.x,
                y=i.y,
                z=i.z,
                mission_type=i.mission_type,
            )
            for i in plan.mission_items
        )
        with self._received:
            self.missions.append(items)
            self._received.notify_all()

    def wait_missions(self, count: int, timeout_s: float) -> list[tuple[MissionItem, ...]]:
        """The missions received once there are ``count`` of them (or whatever came within the time)."""
        with self._received:
            self._received.wait_for(lambda: len(self.missions) >= count, timeout=timeout_s)
            return list(self.missions)

    def close(self) -> None:
        self._mavsdk.destroy()
        self._config.destroy()
