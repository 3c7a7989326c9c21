"""A fleet of up to 10 vehicles: discovery, concurrent mission uploads, state, replanning.

Vehicles that share a connection string share one :class:`~bridge.mavlink.MavlinkLink`;
each vehicle's transfers run in their own thread, so uploads to every vehicle proceed
at once.

Example (the planner's path from ENU targets to flying vehicles)::

    config = typed_config.load_toml(BridgeConfig, "configs/bridge/px4_sitl_10.toml")
    with Fleet(config) as fleet:
        fleet.wait_for_vehicles()
        missions = fleet.upload_plans({1: [(10.0, 20.0)], 2: [(40.0, -5.0, 25.0)]})
        states = fleet.states()
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

from bridge.commands import reposition
from bridge.config import BridgeConfig
from bridge.errors import BridgeError, HeartbeatTimeoutError
from bridge.mavlink import LinkReader, MavlinkLink
from bridge.mission import Mission, MissionItem, build_mission
from bridge.mission_protocol import MissionClient
from bridge.mission_upload import upload_concurrently
from bridge.signing import SigningKey, load_signing_key
from bridge.vehicle_state import VehicleState, VehicleStateTracker

__all__ = ["Fleet", "FleetError"]

log = logging.getLogger(__name__)

T = TypeVar("T")


class FleetError(BridgeError):
    """One or more vehicles failed an operation; ``errors`` maps system id to its named exception.

    Attributes:
        errors: The failure of each vehicle that failed.
        results: The result of each vehicle that succeeded.
    """

    def __init__(
        self, operation: str, errors: Mapping[int, BaseException], results: Mapping[int, object]
    ) -> None:
        self.errors = dict(errors)
        self.results = dict(results)
        lines = "; ".join(
            f"vehicle {sid}: {type(exc).__name__}: {exc}" for sid, exc in sorted(self.errors.items())
        )
        super().__init__(f"{operation} failed on {len(self.errors)} vehicle(s): {lines}")


class Fleet:
    """The vehicles of a :class:`BridgeConfig`, reached over their configured connections.

    Args:
        config: Home, mission shape, geofence, protocol timing, signing and endpoints.
        signing_key: Overrides the key named by ``config.signing`` (``None``: load it from there).
    """

    def __init__(self, config: BridgeConfig, signing_key: SigningKey | None = None) -> None:
        self.config = config
        key = signing_key if signing_key is not None else load_signing_key(config.signing)
        self.tracker = VehicleStateTracker(config.home)
        self._autopilots: dict[int, int] = {}
        self._pool = ThreadPoolExecutor(max_workers=max(1, len(config.vehicles)), thread_name_prefix="fleet")
        self._reader = LinkReader("fleet mavlink reader")
        self._links: dict[str, MavlinkLink] = {}
        self._link_of: dict[int, MavlinkLink] = {}
        try:
            for vehicle in config.vehicles:
                if vehicle.url not in self._links:
                    link = MavlinkLink(
                        vehicle.url,
                        source_system=config.source_system,
                        source_component=config.source_component,
                        signing_key=key,
                        signing_link_id=config.signing.link_id,
                        allow_unsigned=config.signing.allow_unsigned,
                        reader=self._reader,
                    )
                    link.add_listener(self.tracker.update)
                    self._links[vehicle.url] = link
                self._link_of[vehicle.system_id] = self._links[vehicle.url]
        except BaseException:
            self.close()
            raise

    @property
    def system_ids(self) -> tuple[int, ...]:
        """The configured vehicles' system ids."""
        return tuple(self._link_of)

    def close(self) -> None:
        """Close every connection."""
        self._pool.shutdown(wait=True)
        for link in self._links.values():
            link.close()
        self._links.clear()
        self._reader.close()

    def __enter__(self) -> Fleet:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def client(self, system_id: int) -> MissionClient:
        """The mission protocol client of one vehicle.

        Raises:
            KeyError: ``system_id`` is not a configured vehicle.
        """
        if system_id not in self._link_of:
            raise KeyError(f"vehicle {system_id} is not configured; configured: {sorted(self._link_of)}")
        return MissionClient(self._link_of[system_id], system_id, self.config.protocol)

    def wait_for_vehicles(
        self, system_ids: Sequence[int] | None = None, timeout_s: float | None = None
    ) -> dict[int, int]:
        """Wait for a HEARTBEAT of each vehicle; returns each one's ``MAV_AUTOPILOT_*``.

        Raises:
            FleetError: Holding a :class:`HeartbeatTimeoutError` per silent vehicle.
        """
        ids = list(system_ids or self.system_ids)
        timeout_s = self.config.protocol.heartbeat_timeout_s if timeout_s is None else timeout_s
        deadline = time.monotonic() + timeout_s
        errors: dict[int, BaseException] = {}
        for sid in ids:
            try:
                heartbeat = self._link_of[sid].wait_heartbeat(sid, max(0.0, deadline - time.monotonic()))
                self._autopilots[sid] = heartbeat.autopilot
            except HeartbeatTimeoutError as exc:
                errors[sid] = exc
        if errors:
            raise FleetError(
                "discovery", errors, {sid: self._autopilots[sid] for sid in ids if sid not in errors}
            )
        return {sid: self._autopilots[sid] for sid in ids}

    def autopilot(self, system_id: int) -> int:
        """The vehicle's ``MAV_AUTOPILOT_*``, waiting for its heartbeat if needed."""
        if system_id not in self._autopilots:
            self.wait_for_vehicles([system_id])
        return self._autopilots[system_id]

    def build_missions(self, plans_m: Mapping[int, Sequence[Sequence[float]]]) -> dict[int, Mission]:
        """Missions from ENU plans (``{system_id: [(x_m, y_m[, z_m]), ...]}``, the last point the target).

        Every plan is checked against the geofence before any mission is returned.

        Raises:
            GeofenceError: A point is outside the fence (naming the vehicle).
            KeyError: An unknown vehicle.
        """
        missions = {}
        for sid, points in plans_m.items():
            autopilot = self.autopilot(sid)
            try:
                missions[sid] = build_mission(
                    points, self.config.home, self.config.mission, self.config.geofence, autopilot
                )
            except ValueError as exc:
                raise type(exc)(f"vehicle {sid}: {exc}") from None
        return missions

    def _each(self, operation: str, system_ids: Sequence[int], work: Callable[[int], T]) -> dict[int, T]:
        results: dict[int, T] = {}
        errors: dict[int, BaseException] = {}
        if len(system_ids) == 1:  # no thread hand-off for a single vehicle
            try:
                results[system_ids[0]] = work(system_ids[0])
            except BridgeError as exc:
                errors[system_ids[0]] = exc
        else:
            futures = {sid: self._pool.submit(work, sid) for sid in system_ids}
            for sid, future in futures.items():
                try:
                    results[sid] = future.result()
                except BridgeError as exc:
                    errors[sid] = exc
        if errors:
            raise FleetError(operation, errors, results)
        return results

    def upload(
        self, missions: Mapping[int, Mission | Sequence[MissionItem]], verify: bool = True
    ) -> dict[int, float]:
        """Upload missions to their vehicles concurrently; returns each vehicle's upload time in seconds.

        Without ``verify`` every upload runs from the calling thread (see
        :func:`~bridge.mission_upload.upload_concurrently`); with it, one thread per vehicle
        uploads, downloads and compares.

        Args:
            missions: Mission (or its items) per system id.
            verify: Download each mission back and compare it with what was sent.

        Raises:
            FleetError: With each failed vehicle's named exception; the others succeeded.
        """
        items = {sid: m.items if isinstance(m, Mission) else tuple(m) for sid, m in missions.items()}
        for sid in items:
            self.client(sid)  # raises KeyError for an unknown vehicle
        if not verify:  # all from this thread, requests answered on the reader thread
            links = {sid: self._link_of[sid] for sid in items}
            seconds, errors = upload_concurrently(links, items, self.config.protocol)
            if errors:
                raise FleetError("upload", errors, seconds)
            return seconds

        def work(sid: int) -> float:
            start_s = time.monotonic()
            self.client(sid).upload_verified(items[sid])
            return time.monotonic() - start_s

        return self._each("upload", list(items), work)

    def upload_plans(
        self, plans_m: Mapping[int, Sequence[Sequence[float]]], verify: bool = True
    ) -> dict[int, Mission]:
        """Build missions from ENU plans (geofence first, nothing sent on refusal) and upload them.

        Raises:
            GeofenceError: A point is outside the fence.
            FleetError: With each failed vehicle's named exception.
        """
        missions = self.build_missions(plans_m)
        self.upload(missions, verify=verify)
        return missions

    def download(self, system_ids: Sequence[int] | None = None) -> dict[int, Mission]:
        """Download the missions of some (default: all) vehicles concurrently."""

        def work(sid: int) -> Mission:
            items = self.client(sid).download()
            return Mission(home=self.config.home, items=items, autopilot=self._autopilots.get(sid, 0))

        return self._each("download", list(system_ids or self.system_ids), work)

    def clear(self, system_ids: Sequence[int] | None = None) -> None:
        """Clear the missions of some (default: all) vehicles concurrently."""
        self._each("clear", list(system_ids or self.system_ids), lambda sid: self.client(sid).clear())

    def reposition(self, system_id: int, x_m: float, y_m: float, z_m: float, speed_m_s: float = -1.0) -> None:
        """Guided replanning: send one vehicle to an ENU point now (``MAV_CMD_DO_REPOSITION``)."""
        self.client(system_id)  # raises KeyError for an unknown vehicle
        reposition(
            self._link_of[system_id],
            system_id,
            self.config.home,
            self.config.geofence,
            x_m,
            y_m,
            z_m,
            speed_m_s=speed_m_s,
            protocol=self.config.protocol,
        )

    def states(self) -> dict[int, VehicleState]:
        """Latest state of every vehicle heard so far, by system id.

        To be told of every update instead, ``fleet.tracker.add_listener(callback)``.
        """
        return self.tracker.states()
