"""A fleet of up to 10 vehicles: discovery, concurrent mission uploads, state, replanning.

Vehicles that share a connection string share one :class:`~bridge.mavlink.MavlinkLink`;
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
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import TypeVar

from bridge.commands import reposition
from bridge.config import BridgeConfig
from bridge.errors import (
    BridgeError,
    MissionResultError,
    MissionRunningError,
    PlanError,
    VehicleUnreachableError,
)
from bridge.geo import Home
from bridge.mavlink import LinkReader, MavlinkLink, use_mavlink2
from bridge.mission import ARDUPILOT, Mission, MissionItem, build_mission
from bridge.mission_protocol import MissionClient
from bridge.mission_upload import upload_concurrently
from bridge.readiness import request_message, wait_ready
from bridge.signing import SigningKey, load_signing_key
from bridge.vehicle_home import HomeWatcher, ReportedHome, check_home_offset
from bridge.vehicle_state import VehicleState, VehicleStateTracker

__all__ = ["Fleet", "FleetError", "Delivery", "MissionBuilder"]

MissionBuilder = Callable[[int, int, Home], Mission]
"""``build(system_id, autopilot, home)``: a vehicle's mission around ``home``, as its autopilot wants it."""

_AUTO_MODES = frozenset({"AUTO", "MISSION"})  # ArduPilot's and PX4's mission-flying modes
_MISSION_CURRENT_ASKS = 3  # MAV_CMD_REQUEST_MESSAGE tries, one per handshake timeout
_CLEAR_HINT = (
    "ArduPilot refuses (MAV_MISSION_ERROR) to clear the mission it is flying in AUTO: switch the "
    "vehicle to another mode (e.g. LOITER or GUIDED) first"
)

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
        lines = "; ".join(f"{type(exc).__name__}: {exc}" for _, exc in sorted(self.errors.items()))
        super().__init__(f"{operation} failed on {len(self.errors)} vehicle(s): {lines}")


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
        self._homes = HomeWatcher()
        self._autopilots: dict[int, int] = {}
        self._pool = ThreadPoolExecutor(max_workers=max(1, len(config.vehicles)), thread_name_prefix="fleet")
        self._reader = LinkReader("fleet mavlink reader")
        self._links: dict[str, MavlinkLink] = {}
        self._link_of: dict[int, MavlinkLink] = {}
        self._link_errors: dict[int, VehicleUnreachableError] = {}
        try:
            self._open_links(key)
        except BaseException:
            self.close()
            raise

    def _open_links(self, key: SigningKey | None) -> None:
        """Open every connection at once; one that cannot be opened fails only its vehicles."""
        use_mavlink2()  # once, before the threads

        def open_link(url: str) -> MavlinkLink:
            link = MavlinkLink(
                url,
                source_system=self.config.source_system,
                source_component=self.config.source_component,
                signing_key=key,
                signing_link_id=self.config.signing.link_id,
                allow_unsigned=self.config.signing.allow_unsigned,
                reader=self._reader,
            )
            link.add_listener(self.tracker.update, VehicleStateTracker.MESSAGE_TYPES)
            link.add_listener(self._homes.update, HomeWatcher.MESSAGE_TYPES)
            return link

        urls = dict.fromkeys(v.url for v in self.config.vehicles)
        futures = {url: self._pool.submit(open_link, url) for url in urls}
        failures: dict[str, OSError] = {}
        unexpected: BaseException | None = None
        for url, future in futures.items():
            try:
                self._links[url] = future.result()
            except OSError as exc:  # refused TCP connection, port in use, unknown host
                failures[url] = exc
            except BaseException as exc:
                unexpected = unexpected or exc
        if unexpected is not None:
            raise unexpected
        for vehicle in self.config.vehicles:
            if vehicle.url in failures:
                error = VehicleUnreachableError(vehicle.system_id, vehicle.url, failures[vehicle.url])
                log.warning("%s", error)
                self._link_errors[vehicle.system_id] = error
            else:
                self._link_of[vehicle.system_id] = self._links[vehicle.url]

    @property
    def system_ids(self) -> tuple[int, ...]:
        """The configured vehicles' system ids (reachable or not)."""
        return tuple(v.system_id for v in self.config.vehicles)

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

    def link(self, system_id: int) -> MavlinkLink:
        """The connection reaching one vehicle (shared with the vehicles on the same connection string).

        Raises:
            KeyError: ``system_id`` is not a configured vehicle.
            VehicleUnreachableError: Its connection could not be opened.
        """
        if system_id in self._link_errors:
            raise self._link_errors[system_id]
        if system_id not in self._link_of:
            raise KeyError(f"vehicle {system_id} is not configured; configured: {sorted(self.system_ids)}")
        return self._link_of[system_id]

    def client(self, system_id: int) -> MissionClient:
        """The mission protocol client of one vehicle.

        Raises:
            KeyError: ``system_id`` is not a configured vehicle.
            VehicleUnreachableError: Its connection could not be opened.
        """
        return MissionClient(self.link(system_id), system_id, self.config.protocol)

    def _configured(self, system_id: int) -> None:
        """Raise KeyError naming the configured ids unless ``system_id`` is one of them."""
        if system_id not in self.system_ids:
            raise KeyError(f"vehicle {system_id} is not configured; configured: {sorted(self.system_ids)}")

    def wait_for_vehicles(
        self, system_ids: Sequence[int] | None = None, timeout_s: float | None = None
    ) -> dict[int, int]:
        """Wait for a HEARTBEAT of each vehicle, all at once; returns each one's ``MAV_AUTOPILOT_*``.

        Raises:
            FleetError: Holding a :class:`HeartbeatTimeoutError` (or :class:`VehicleUnreachableError`)
                per absent vehicle, and the autopilots of the others in ``results``.
        """
        ids = list(system_ids or self.system_ids)
        timeout_s = self.config.protocol.heartbeat_timeout_s if timeout_s is None else timeout_s
        return self._each("discovery", ids, lambda sid: self._discover(sid, timeout_s))

    def _discover(self, system_id: int, timeout_s: float) -> int:
        """The vehicle's ``MAV_AUTOPILOT_*`` from its first HEARTBEAT, waiting at most ``timeout_s``.

        On that first heartbeat the vehicle is asked once for the messages the mission commands'
        decisions depend on, HOME_POSITION and MISSION_CURRENT (:func:`~bridge.readiness.request_message`:
        ArduPilot streams neither on a new link until asked).
        """
        if system_id not in self._autopilots:
            link = self.link(system_id)
            self._autopilots[system_id] = link.wait_heartbeat(system_id, timeout_s).autopilot
            m = link.mavlink
            for message_id in (m.MAVLINK_MSG_ID_HOME_POSITION, m.MAVLINK_MSG_ID_MISSION_CURRENT):
                request_message(link, system_id, message_id)
        return self._autopilots[system_id]

    def autopilot(self, system_id: int) -> int:
        """The vehicle's ``MAV_AUTOPILOT_*``, waiting for its heartbeat if needed."""
        if system_id not in self._autopilots:
            self.wait_for_vehicles([system_id])
        return self._autopilots[system_id]

    def _fix_stands_in(self, system_id: int) -> bool:
        """True unless the vehicle is ArduPilot, which has a fix long before its home (HOME_POSITION)."""
        state = self.tracker.state(system_id)
        autopilot = self._autopilots.get(system_id, state.autopilot if state is not None else None)
        return autopilot != ARDUPILOT

    def vehicle_home(self, system_id: int) -> ReportedHome:
        """The vehicle's own home: its HOME_POSITION (asked for) or, not ArduPilot, its first position fix.

        Waits at most ``protocol.home_timeout_s``, saying every few seconds what it waits for.

        Raises:
            HomeUnknownError: Neither arrived in time (naming the vehicle and what it said).
        """
        return wait_ready(self.link(system_id), self.tracker, self._homes, system_id,
                          timeout_s=self.config.protocol.home_timeout_s, protocol=self.config.protocol,
                          need_fix=False, fix_stands_in=self._fix_stands_in(system_id))

    def wait_ready(self, system_id: int, timeout_s: float, position_rate_hz: float = 0.0,
                   cancel: threading.Event | None = None) -> ReportedHome:
        """Wait until the vehicle can be flown: a position fix and its home, both heard from now on.

        The home is refused beyond ``max_home_offset_m`` from ``[home]`` (0: not checked). Every few
        seconds the wait says what it waits for and what the vehicle said (STATUSTEXT). Setting
        ``cancel`` stops the wait (:class:`BridgeError`).

        Raises:
            HomeUnknownError: Not ready within ``timeout_s`` (naming what was missing).
            HomeMismatchError: Naming both positions and the distance.
        """
        reported = wait_ready(self.link(system_id), self.tracker, self._homes, system_id, timeout_s=timeout_s,
                              protocol=self.config.protocol, fix_stands_in=self._fix_stands_in(system_id),
                              fresh=True, position_rate_hz=position_rate_hz, cancel=cancel)
        if self.config.max_home_offset_m > 0:
            check_home_offset(system_id, self.config.home, reported, self.config.max_home_offset_m)
        return reported

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
            self._configured(sid)
            self._build(sid, 0, self.config.home, points)

    def _build(
        self, system_id: int, autopilot: int, home: Home, points: Sequence[Sequence[float]]
    ) -> Mission:
        try:
            return build_mission(points, home, self.config.mission, self.config.geofence, autopilot)
        except ValueError as exc:
            raise type(exc)(f"vehicle {system_id}: {exc}") from None

    def _flying_mission(self, system_id: int) -> VehicleState | None:
        """The vehicle's state when it flies its mission (armed, AUTO, past item 0), else ``None``.

        Waits for its HEARTBEAT first (a state not heard yet is not "not flying"). Armed in AUTO,
        its mission item is asked for (``MAV_CMD_REQUEST_MESSAGE`` MISSION_CURRENT: ArduPilot does
        not stream it on a new link) once per handshake timeout, three times; still unknown, the
        vehicle is taken as flying (fail closed: its state then has ``mission_seq_current`` None).

        Raises:
            HeartbeatTimeoutError: The vehicle is silent.
        """
        protocol = self.config.protocol
        self._discover(system_id, protocol.heartbeat_timeout_s)
        deadline_s = time.monotonic() + protocol.handshake_timeout_s
        state = self.tracker.state(system_id)
        while state is None or state.armed is None:  # its heartbeat is not folded into the state yet
            if time.monotonic() >= deadline_s:
                return None
            time.sleep(0.02)
            state = self.tracker.state(system_id)
        if not state.armed or state.mode not in _AUTO_MODES:
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
            log.warning("vehicle %d: armed in %s and no MISSION_CURRENT after asking %d times: taken as "
                        "flying its mission", system_id, state.mode, _MISSION_CURRENT_ASKS)
            return state
        return state if state.mission_seq_current > 0 else None

    def _refuse_if_flying(self, system_id: int, operation: str, force: bool) -> VehicleState | None:
        """Raise :class:`MissionRunningError` when the vehicle flies its mission, unless ``force``."""
        state = self._flying_mission(system_id)
        if state is not None and not force:
            raise MissionRunningError(system_id, operation, str(state.mode), state.mission_seq_current)
        return state

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
        self,
        missions: Mapping[int, Mission | Sequence[MissionItem]],
        verify: bool = True,
        *,
        strict: bool = False,
        force: bool = False,
    ) -> dict[int, float]:
        """Upload ready-made missions as they are (no home check); returns each vehicle's seconds.

        Without ``verify`` every upload runs from the calling thread (see
        :func:`~bridge.mission_upload.upload_concurrently`) and the time is the upload's;
        with it, one thread per vehicle uploads, downloads and compares, and the time is both.

        Args:
            missions: Mission (or its items) per system id.
            verify: Download each mission back and compare it with what was sent.
            strict: Compare exactly (see :func:`~bridge.mission_compare.compare_missions`).
            force: Replace a mission the vehicle is flying (otherwise :class:`MissionRunningError`).

        Raises:
            KeyError: An unknown vehicle (before anything is sent).
            FleetError: With each failed vehicle's named exception; the others succeeded.
        """
        items = {sid: m.items if isinstance(m, Mission) else tuple(m) for sid, m in missions.items()}
        for sid in items:
            self._configured(sid)
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
            home = self._autopilots.get(sid) == ARDUPILOT
            self.client(sid).upload_verified(items[sid], strict=strict, vehicle_home=home)
            return time.monotonic() - start_s

        return self._each("upload", list(items), work)

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
            missions = {sid: delivery.mission for sid, delivery in exc.results.items()}
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
            self._configured(sid)
        config, protocol = self.config, self.config.protocol
        ask_home = config.home_source == "vehicle" or config.max_home_offset_m > 0

        def work(sid: int) -> Delivery:
            autopilot = self._discover(sid, protocol.heartbeat_timeout_s)
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
                ardupilot = autopilot == ARDUPILOT
                times = client.upload_verified(mission.items, strict=strict, vehicle_home=ardupilot)
                return Delivery(mission, reported, times.upload_s, times.verify_s)
            start_s = time.monotonic()
            client.upload(mission.items)
            return Delivery(mission, reported, time.monotonic() - start_s, None)

        return self._each("upload", list(builders), work)

    def download(self, system_ids: Sequence[int] | None = None) -> dict[int, Mission]:
        """Download the missions of some (default: all) vehicles concurrently."""

        def work(sid: int) -> Mission:
            items = self.client(sid).download()
            return Mission(home=self.config.home, items=items, autopilot=self._autopilots.get(sid, 0))

        return self._each("download", list(system_ids or self.system_ids), work)

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
                    exc.add_detail(_CLEAR_HINT)
                raise

        self._each("clear", list(system_ids or self.system_ids), work)

    def reposition(self, system_id: int, x_m: float, y_m: float, z_m: float, speed_m_s: float = -1.0) -> None:
        """Guided replanning: send one vehicle to an ENU point now (``MAV_CMD_DO_REPOSITION``)."""
        reposition(
            self.link(system_id),
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
