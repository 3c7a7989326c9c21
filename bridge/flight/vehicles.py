"""The vehicles of a fleet: connections, discovery, homes, readiness, guided replanning, state.

Vehicles that share a connection string share one :class:`~bridge.link.mavlink.MavlinkLink`;
each vehicle's work runs in its own thread (:meth:`FleetVehicles.each`), so every vehicle
proceeds at once and one that cannot be reached, stays silent or fails is reported by name
(:class:`FleetError`) while every other one goes on. A connection that cannot be opened (a vehicle
not started yet refuses its TCP port) is tried again every second in the background, so a vehicle
started later is heard; :meth:`FleetVehicles.silence` says in one line why a vehicle is not heard.
The mission operations on top of this are :class:`bridge.flight.fleet.Fleet`'s.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

from bridge.autopilots import Conventions, conventions_for
from bridge.config import BridgeConfig, ProtocolConfig
from bridge.errors import BridgeError, VehicleUnreachableError
from bridge.flight.commands import reposition
from bridge.flight.readiness import request_message, wait_ready
from bridge.flight.vehicle_home import HomeWatcher, ReportedHome, check_home_offset
from bridge.link.mavlink import LinkReader, MavlinkLink, use_mavlink2
from bridge.link.signing import SigningKey, load_signing_key
from bridge.link.vehicle_state import VehicleState, VehicleStateTracker

__all__ = ["FleetVehicles", "FleetError"]

log = logging.getLogger(__name__)

T = TypeVar("T")

_REOPEN_PERIOD_S = 1.0
"""How often a connection that could not be opened is tried again."""


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




class FleetVehicles:
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
        self._links_lock = threading.Lock()
        self._closing = threading.Event()
        self._reopener: threading.Thread | None = None
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
                log.debug("%s; trying again every %.0f s", error, _REOPEN_PERIOD_S)
                self._link_errors[vehicle.system_id] = error
            else:
                self._link_of[vehicle.system_id] = self._links[vehicle.url]
        if failures:
            self._reopener = threading.Thread(target=self._reopen, args=(open_link, list(failures)),
                                              name="fleet link reopener", daemon=True)
            self._reopener.start()

    def _reopen(self, open_link: Callable[[str], MavlinkLink], urls: list[str]) -> None:
        """Try the connections that could not be opened again every second until each opens or we close."""
        while urls and not self._closing.wait(_REOPEN_PERIOD_S):
            for url in list(urls):
                try:
                    link = open_link(url)
                except OSError as exc:
                    log.debug("%s: still cannot connect: %s", url, exc)
                    continue
                urls.remove(url)
                with self._links_lock:
                    if self._closing.is_set():
                        link.close()
                        return
                    self._links[url] = link
                    ids = [v.system_id for v in self.config.vehicles if v.url == url]
                    for system_id in ids:
                        self._link_of[system_id] = link
                        self._link_errors.pop(system_id, None)
                log.info("connected to %s (vehicle %s)", url, ", ".join(map(str, ids)))

    def report_silent(self, system_ids: Sequence[int], waited_s: float, remaining_s: float) -> None:
        """Log why each of ``system_ids`` is not heard (one warning each), then one summary line."""
        if not system_ids:
            return
        for system_id in system_ids:
            log.warning("%s", self.silence(system_id))
        ids = ", ".join(map(str, system_ids))
        log.warning("%d of %d vehicles not heard after %.0f s (%s): waiting up to %.0f s more for them",
                    len(system_ids), len(self.config.vehicles), waited_s, ids, max(0.0, remaining_s))

    def silence(self, system_id: int) -> str:
        """Why a vehicle that has not been heard is silent, in one line naming it and its connection.

        Examples: ``vehicle 3: cannot connect to tcp:127.0.0.1:5780: [Errno 111] Connection refused: is
        it running?``; ``vehicle 2: no heartbeat on udpin:127.0.0.1:14550``.
        """
        error = self._link_errors.get(system_id)
        if error is not None:
            return f"{error}: is it running?"
        url = next(v.url for v in self.config.vehicles if v.system_id == system_id)
        return f"vehicle {system_id}: no heartbeat on {url}"

    @property
    def system_ids(self) -> tuple[int, ...]:
        """The configured vehicles' system ids (reachable or not)."""
        return tuple(v.system_id for v in self.config.vehicles)

    def close(self) -> None:
        """Close every connection."""
        self._closing.set()
        if self._reopener is not None:
            self._reopener.join(timeout=2 * _REOPEN_PERIOD_S)
        self._pool.shutdown(wait=True)
        with self._links_lock:
            for link in self._links.values():
                link.close()
            self._links.clear()
        self._reader.close()

    def __enter__(self) -> FleetVehicles:
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

    def configured(self, system_id: int) -> None:
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
        return self.each("discovery", ids, lambda sid: self.discover(sid, timeout_s))

    def discover(self, system_id: int, timeout_s: float) -> int:
        """The vehicle's ``MAV_AUTOPILOT_*`` from its first HEARTBEAT, waiting at most ``timeout_s``.

        On that first heartbeat the vehicle is asked once for the messages the mission commands'
        decisions depend on, HOME_POSITION and MISSION_CURRENT
        (:func:`~bridge.flight.readiness.request_message`: ArduPilot streams neither on a new link
        until asked).
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

    def conventions(self, system_id: int) -> Conventions:
        """The vehicle's autopilot conventions, from its HEARTBEAT (``GENERIC`` while unheard)."""
        state = self.tracker.state(system_id)
        heard = state.autopilot if state is not None else None
        return conventions_for(self._autopilots.get(system_id, heard))

    def _fix_stands_in(self, system_id: int) -> bool:
        """True unless the vehicle is ArduPilot, which has a fix long before its home (HOME_POSITION)."""
        return self.conventions(system_id).fix_stands_in

    def home_alt_m(self, system_id: int) -> float | None:
        """The vehicle's own home altitude above mean sea level: its HOME_POSITION, else from its position.

        Its last GLOBAL_POSITION_INT gives it too (altitude less the height above its home); ``None``
        when neither was heard.
        """
        home = self._homes.home(system_id)
        if home is not None:
            return home.alt_m
        state = self.tracker.state(system_id)
        if state is None or state.alt_m is None or state.relative_alt_m is None:
            return None
        return state.alt_m - state.relative_alt_m

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

    def each(self, operation: str, system_ids: Sequence[int], work: Callable[[int], T]) -> dict[int, T]:
        """Run ``work(system_id)`` for every vehicle at once (one thread each); the results by system id.

        Raises:
            FleetError: ``errors`` holds each vehicle's :class:`BridgeError`, ``results`` the others'.
        """
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

    def reposition(self, system_id: int, x_m: float, y_m: float, z_m: float, speed_m_s: float = -1.0,
                   protocol: ProtocolConfig | None = None) -> None:
        """Guided replanning: send one vehicle to an ENU point now (``MAV_CMD_DO_REPOSITION``).

        ``z_m`` is the height above the vehicle's own home; the altitude frame is its autopilot's
        (:func:`~bridge.flight.commands.reposition`). ``protocol`` replaces the config's timing for this
        command (a separation guard sends one copy and bounds its answer).
        """
        reposition(
            self.link(system_id),
            system_id,
            self.config.home,
            self.config.geofence,
            x_m,
            y_m,
            z_m,
            speed_m_s=speed_m_s,
            protocol=protocol or self.config.protocol,
            conventions=self.conventions(system_id),
            home_alt_m=self.home_alt_m(system_id),
        )

    def states(self) -> dict[int, VehicleState]:
        """Latest state of every vehicle heard so far, by system id.

        To be told of every update instead, ``fleet.tracker.add_listener(callback)``.
        """
        return self.tracker.states()
