"""A fleet of up to 10 vehicles: discovery, concurrent mission uploads, state, replanning.

Vehicles that share a connection string share one :class:`~bridge.link.mavlink.MavlinkLink`;
each vehicle's transfers run in their own thread, so uploads to every vehicle proceed
at once. Each vehicle is on its own: one that cannot be reached, stays silent or fails
is reported by name (:class:`FleetError`) while every other one gets its mission
(:meth:`Fleet.deliver`: heartbeat, home check, mission, upload, verification, per vehicle).

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
from dataclasses import dataclass

from bridge.errors import BridgeError, MissionResultError, MissionRunningError, PlanError
from bridge.flight.readiness import request_message
from bridge.flight.vehicle_home import ReportedHome, check_home_offset
from bridge.flight.vehicles import FleetError, FleetVehicles
from bridge.geo import Home
from bridge.link.mavlink import MavlinkLink
from bridge.link.vehicle_state import VehicleState
from bridge.missions.items import Mission, MissionItem, build_mission
from bridge.missions.protocol import MissionClient
from bridge.missions.upload import upload_concurrently

__all__ = ["Fleet", "FleetError", "Delivery", "MissionBuilder"]

MissionBuilder = Callable[[int, int, Home], Mission]
"""``build(system_id, autopilot, home)``: a vehicle's mission around ``home``, as its autopilot wants it."""

_MISSION_CURRENT_ASKS = 3  # MAV_CMD_REQUEST_MESSAGE tries, one per handshake timeout

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Delivery:
    """One vehicle's successful upload (:meth:`Fleet.deliver`).

    Attributes:
        mission: The mission it now holds.
        reported_home: Its home as it reported it (``None``: not asked, the check is off).
        upload_s: Seconds spent sending the mission (all attempts).
        verify_s: Seconds spent reading it back and comparing (``None``: not verified).
    """

    mission: Mission
    reported_home: ReportedHome | None
    upload_s: float
    verify_s: float | None


class Fleet(FleetVehicles):
    """The vehicles of a :class:`BridgeConfig` and their missions (:class:`FleetVehicles` for the rest).

    Args:
        config: Home, mission shape, geofence, protocol timing, signing and endpoints.
        signing_key: Overrides the key named by ``config.signing`` (``None``: load it from there).
    """

    def __enter__(self) -> Fleet:
        return self

    def client(self, system_id: int) -> MissionClient:
        """The mission protocol client of one vehicle.

        Raises:
            KeyError: ``system_id`` is not a configured vehicle.
            VehicleUnreachableError: Its connection could not be opened.
        """
        return MissionClient(self.link(system_id), system_id, self.config.protocol)

    def build_missions(self, plans_m: Mapping[int, Sequence[Sequence[float]]]) -> dict[int, Mission]:
        """Missions from ENU plans (``{system_id: [(x_m, y_m[, z_m]), ...]}``, the last point the target).

        Every plan is checked against the geofence before any mission is returned.

        Raises:
            GeofenceError: A point is outside the fence (naming the vehicle).
            KeyError: An unknown vehicle.
        """
        self.check_plans(plans_m)
        home = self.config.home
        return {sid: self._build(sid, self.autopilot(sid), home, points) for sid, points in plans_m.items()}

    def check_plans(self, plans_m: Mapping[int, Sequence[Sequence[float]]]) -> None:
        """Refuse, without waiting for or sending anything, unknown vehicles and points outside the fence.

        Raises:
            KeyError: An unknown vehicle (naming the configured ids).
            GeofenceError: A point is outside the fence (naming the vehicle and the user's point).
            ValueError: A malformed plan.
        """
        for sid, points in plans_m.items():
            self.configured(sid)
            self._build(sid, 0, self.config.home, points)

    def _build(
        self, system_id: int, autopilot: int, home: Home, points: Sequence[Sequence[float]]
    ) -> Mission:
        try:
            return build_mission(points, home, self.config.mission, self.config.geofence, autopilot)
        except ValueError as exc:
            raise type(exc)(f"vehicle {system_id}: {exc}") from None

    def _flying_mission(self, system_id: int) -> VehicleState | None:
        """The vehicle's state when it flies its mission, else ``None``.

        Flying its mission is being armed in its autopilot's mission mode (ArduPilot AUTO, PX4
        AUTO.MISSION: :attr:`~bridge.autopilots.Conventions.mission_mode_names`) at any item, its
        take-off included (PX4's take-off is item 0, ArduPilot's item 1). Waits for its HEARTBEAT
        first (a state not heard yet is not "not flying"). Armed in that mode, its mission item is
        asked for (``MAV_CMD_REQUEST_MESSAGE`` MISSION_CURRENT: ArduPilot does not stream it on a new
        link) once per handshake timeout, three times, to name it in the refusal; still unknown, the
        state has ``mission_seq_current`` None.

        Raises:
            HeartbeatTimeoutError: The vehicle is silent.
        """
        protocol = self.config.protocol
        self.discover(system_id, protocol.heartbeat_timeout_s)
        deadline_s = time.monotonic() + protocol.handshake_timeout_s
        state = self.tracker.state(system_id)
        while state is None or state.armed is None:  # its heartbeat is not folded into the state yet
            if time.monotonic() >= deadline_s:
                return None
            time.sleep(0.02)
            state = self.tracker.state(system_id)
        if not state.armed or state.mode not in self.conventions(system_id).mission_mode_names:
            return None
        link = self.link(system_id)
        for _ in range(_MISSION_CURRENT_ASKS):
            if state.mission_seq_current is not None:
                break
            request_message(link, system_id, link.mavlink.MAVLINK_MSG_ID_MISSION_CURRENT)
            deadline_s = time.monotonic() + protocol.handshake_timeout_s
            while state.mission_seq_current is None and time.monotonic() < deadline_s:
                time.sleep(0.02)
                state = self.tracker.state(system_id) or state
        if state.mission_seq_current is None:
            log.warning("vehicle %d: armed in %s and no MISSION_CURRENT after asking %d times: flying its "
                        "mission at an unknown item", system_id, state.mode, _MISSION_CURRENT_ASKS)
        return state

    def _refuse_if_flying(self, system_id: int, operation: str, force: bool) -> VehicleState | None:
        """Raise :class:`MissionRunningError` when the vehicle flies its mission, unless ``force``."""
        state = self._flying_mission(system_id)
        if state is not None and not force:
            raise MissionRunningError(system_id, operation, str(state.mode), state.mission_seq_current)
        return state

    def upload(
        self,
        missions: Mapping[int, Mission | Sequence[MissionItem]],
        verify: bool = True,
        *,
        strict: bool = False,
        force: bool = False,
    ) -> dict[int, float]:
        """Upload ready-made missions as they are (no home check); returns each vehicle's seconds.

        Without ``verify`` every upload runs from the calling thread (see
        :func:`~bridge.missions.upload.upload_concurrently`) and the time is the upload's;
        with it, one thread per vehicle uploads, downloads and compares, and the time is both.

        Args:
            missions: Mission (or its items) per system id.
            verify: Download each mission back and compare it with what was sent.
            strict: Compare exactly (see :func:`~bridge.missions.compare.compare_missions`).
            force: Replace a mission the vehicle is flying (otherwise :class:`MissionRunningError`).

        Raises:
            KeyError: An unknown vehicle (before anything is sent).
            FleetError: With each failed vehicle's named exception; the others succeeded.
        """
        items = {sid: m.items if isinstance(m, Mission) else tuple(m) for sid, m in missions.items()}
        for sid in items:
            self.configured(sid)
        if not verify:  # all from this thread, requests answered on the reader thread
            links: dict[int, MavlinkLink] = {}
            refused: dict[int, BridgeError] = {}
            for sid in items:
                try:
                    self._refuse_if_flying(sid, "replace", force)
                    links[sid] = self.link(sid)
                except BridgeError as exc:
                    refused[sid] = exc
            to_send = {sid: items[sid] for sid in links}
            seconds, errors = upload_concurrently(links, to_send, self.config.protocol)
            if errors or refused:
                raise FleetError("upload", {**refused, **errors}, seconds)
            return seconds

        def work(sid: int) -> float:
            start_s = time.monotonic()
            self._refuse_if_flying(sid, "replace", force)
            home = self.conventions(sid).home_item
            self.client(sid).upload_verified(items[sid], strict=strict, vehicle_home=home)
            return time.monotonic() - start_s

        return self.each("upload", list(items), work)

    def upload_plans(
        self,
        plans_m: Mapping[int, Sequence[Sequence[float]]],
        verify: bool = True,
        *,
        strict: bool = False,
        force: bool = False,
    ) -> dict[int, Mission]:
        """Build missions from ENU plans and give each vehicle its own (:meth:`deliver`).

        Every plan is checked first (:meth:`check_plans`): a refusal sends nothing to any vehicle.

        Raises:
            KeyError: An unknown vehicle.
            GeofenceError: A point is outside the fence.
            FleetError: With each failed vehicle's named exception; ``results`` holds the
                missions of the vehicles that got theirs.
        """
        self.check_plans(plans_m)
        builders = {
            sid: (lambda sid, autopilot, home, points=points: self._build(sid, autopilot, home, points))
            for sid, points in plans_m.items()
        }
        try:
            deliveries = self.deliver(builders, verify=verify, strict=strict, force=force)
        except FleetError as exc:
            missions = {sid: delivery.mission for sid, delivery in exc.results.items()
                        if isinstance(delivery, Delivery)}  # deliver's results: every one a Delivery
            raise FleetError("upload", exc.errors, missions) from None
        return {sid: delivery.mission for sid, delivery in deliveries.items()}

    def deliver(
        self,
        builders: Mapping[int, MissionBuilder],
        *,
        verify: bool = True,
        strict: bool = False,
        force: bool = False,
    ) -> dict[int, Delivery]:
        """Give each vehicle its mission, every vehicle on its own and all at once.

        Per vehicle, in its own thread, each step bounded in time: its HEARTBEAT (for its
        autopilot); its home (HOME_POSITION or first fix, unless ``max_home_offset_m = 0``
        with ``home_source = "config"``; waited for, see :meth:`vehicle_home`); its mission,
        ``builders[sid](sid, autopilot, home)``
        with ``home`` the configured one or, with ``home_source = "vehicle"``, the vehicle's;
        the mission's home against the vehicle's (:class:`HomeMismatchError` beyond
        ``max_home_offset_m``); the vehicle must not be flying its mission
        (:class:`MissionRunningError` unless ``force``); the upload and, with ``verify``, the
        read-back comparison (``strict``: exact). A vehicle that is absent or fails is reported
        while the others get theirs.

        Raises:
            KeyError: An unknown vehicle (before anything is sent).
            FleetError: ``errors`` per failed vehicle, ``results`` a :class:`Delivery` per other one.
        """
        for sid in builders:
            self.configured(sid)
        config, protocol = self.config, self.config.protocol
        ask_home = config.home_source == "vehicle" or config.max_home_offset_m > 0

        def work(sid: int) -> Delivery:
            autopilot = self.discover(sid, protocol.heartbeat_timeout_s)
            reported = self.vehicle_home(sid) if ask_home else None
            home = reported.home if reported is not None and config.home_source == "vehicle" else config.home
            try:
                mission = builders[sid](sid, autopilot, home)
            except BridgeError:
                raise
            except ValueError as exc:
                raise PlanError(f"vehicle {sid}: {exc}") from None
            if reported is not None and config.max_home_offset_m > 0:
                check_home_offset(sid, mission.home, reported, config.max_home_offset_m)
            self._refuse_if_flying(sid, "replace", force)
            client = self.client(sid)
            if verify:
                home_item = self.conventions(sid).home_item
                times = client.upload_verified(mission.items, strict=strict, vehicle_home=home_item)
                return Delivery(mission, reported, times.upload_s, times.verify_s)
            start_s = time.monotonic()
            client.upload(mission.items)
            return Delivery(mission, reported, time.monotonic() - start_s, None)

        return self.each("upload", list(builders), work)

    def download(self, system_ids: Sequence[int] | None = None) -> dict[int, Mission]:
        """Download the missions of some (default: all) vehicles concurrently."""

        def work(sid: int) -> Mission:
            items = self.client(sid).download()
            return Mission(home=self.config.home, items=items, autopilot=self._autopilots.get(sid, 0))

        return self.each("download", list(system_ids or self.system_ids), work)

    def clear(self, system_ids: Sequence[int] | None = None, *, force: bool = False) -> None:
        """Clear the missions of some (default: all) vehicles concurrently.

        Args:
            system_ids: The vehicles (default: all).
            force: Clear a mission the vehicle is flying (otherwise :class:`MissionRunningError`);
                ArduPilot itself refuses that in AUTO, and the error says so.

        Raises:
            FleetError: With each failed vehicle's named exception.
        """

        def work(sid: int) -> None:
            flying = self._refuse_if_flying(sid, "clear", force)
            try:
                self.client(sid).clear()
            except MissionResultError as exc:
                if flying is not None:
                    exc.add_detail(self.conventions(sid).clear_hint)
                raise

        self.each("clear", list(system_ids or self.system_ids), work)

