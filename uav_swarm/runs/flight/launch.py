"""The launch of a live flight's vehicles, and their loss and return over the flight.

:class:`FlightLaunch` makes every vehicle heard ready (a position fix and its home, each waited for on
its own, :meth:`bridge.flight.fleet.Fleet.wait_ready`) and checks them (take-off positions, link-loss
failsafe, return altitude) before any is armed; then they take off together, each from a clear column
(:mod:`bridge.flight.guided`), watched by the guard from their take-off on. A vehicle silent for
``flight.link_timeout_s`` is lost and replanned around, and launched again (checked first) when heard;
a live vehicle seen disarmed is left out.
"""

from __future__ import annotations

import logging
import math
import time
from typing import TYPE_CHECKING

from bridge.errors import BridgeError
from bridge.flight.guided import launch
from bridge.flight.preflight import PreflightError
from uav_swarm.runs.flight.step import FlightStep
from uav_swarm.runs.flight.vehicles import SILENT, TICK_S, FlightVehicle

if TYPE_CHECKING:
    from bridge.flight.vehicle_home import ReportedHome

__all__ = ["FlightLaunch"]

logger = logging.getLogger(__name__)

SILENCE_REPORT_S = 3.0
"""After this long without a vehicle's heartbeat, the silent vehicles are named (with why, if known)."""


class FlightLaunch(FlightStep):
    """A flight's launches and links (planning and guard: :class:`~uav_swarm.runs.flight.step.FlightStep`)."""

    # -- launch --------------------------------------------------------------------------------
    def _start_launch(self, vehicle: FlightVehicle, home: ReportedHome | None = None) -> None:
        vehicle.status = "launching"
        vehicle.launches += 1
        vehicle.in_auto = False
        vehicle.job = self._pool.submit(self._launch_one, vehicle, home)

    def _ready(self, vehicle: FlightVehicle) -> ReportedHome:
        """A fix and its home (checked against [home]) before anything that moves it."""
        flight = self.config.flight
        return self.fleet.wait_ready(vehicle.system_id, flight.ready_timeout_s, flight.stream_rate_hz,
                                     cancel=self._stop)

    def _launch_one(self, vehicle: FlightVehicle, home: ReportedHome | None = None) -> None:
        """Launch a checked vehicle (``home`` given), or check one taken back in flight first."""
        sid = vehicle.system_id
        autopilot = self.fleet.conventions(sid).autopilot  # from its HEARTBEAT
        try:
            if home is None:
                home = self._ready(vehicle)
                self.safety.check_relaunch(sid, home)
            launch(self.fleet.link(sid), self.fleet.tracker, sid, autopilot, self.safety.cruise_alt_m[sid],
                   self.config.flight, self.bridge.protocol, cancel=self._stop, home_alt_m=home.home.alt_m,
                   takeoff_gate=self.flight_status.gate(sid, self.safety.takeoff_gate(sid)))
        except BridgeError as exc:
            if vehicle.status in SILENT or self._stop.is_set():  # taken back when heard / the flight ends
                return
            vehicle.status = "failed"
            logger.warning("vehicle %d not launched: %s: %s", vehicle.system_id, type(exc).__name__, exc)
            self._event("launch_failed", vehicle, f"{type(exc).__name__}: {exc}")
            return
        if vehicle.status == "launching":
            vehicle.status = "live"
            self.outputs.announce(vehicle.uav_id)
            self._event("live", vehicle)

    def _check_all(self) -> dict[int, ReportedHome]:
        """Every vehicle heard within the ready timeout made ready and checked, before any is armed.

        Raises:
            PreflightError: Take-off positions too close, or a vehicle without a link-loss failsafe.
        """
        flight, status = self.config.flight, self.flight_status
        start_s = time.monotonic()
        deadline_s = start_s + flight.ready_timeout_s
        status.enter("heartbeat", flight.ready_timeout_s)
        named = False  # the silent vehicles, named once after SILENCE_REPORT_S
        while not self._stop.is_set() and time.monotonic() < deadline_s and not all(
                self._heard_within(v, flight.link_timeout_s) for v in self.vehicles):
            status.tick()
            if not named and time.monotonic() - start_s >= SILENCE_REPORT_S:
                named = True
                silent = [v for v in self.vehicles if not self._heard_within(v, flight.link_timeout_s)]
                self.fleet.report_silent([v.system_id for v in silent], SILENCE_REPORT_S,
                                         deadline_s - time.monotonic())
            time.sleep(TICK_S)
        heard = [v for v in self.vehicles if self._heard_within(v, flight.link_timeout_s)]
        jobs = {v.system_id: self._pool.submit(self._ready, v) for v in heard}
        status.enter("ready", flight.ready_timeout_s)
        status.wait(list(jobs.items()), "its position fix and home")
        homes: dict[int, ReportedHome] = {}
        for vehicle in heard:
            try:
                homes[vehicle.system_id] = jobs[vehicle.system_id].result()
            except BridgeError as exc:
                if self._stop.is_set():
                    continue
                vehicle.status = "failed"
                logger.warning("vehicle %d not launched: %s: %s", vehicle.system_id, type(exc).__name__, exc)
                self._event("launch_failed", vehicle, f"{type(exc).__name__}: {exc}")
        if homes and not self._stop.is_set():
            status.enter("preflight")
            check = self._pool.submit(self.safety.check_launch, homes)
            status.wait([(sid, check) for sid in homes], "its pre-flight check (parameters)")
            try:
                check.result()
            except PreflightError:
                self._refused = True
                raise
        return homes

    def _launch_all(self) -> None:
        """Check every vehicle heard, then launch them; return when none is still waiting or launching."""
        flight = self.config.flight
        deadline_s = time.monotonic() + flight.ready_timeout_s
        for sid, home in self._check_all().items():
            self._start_launch(self._by_sid[sid], home)
        self.flight_status.enter("launch")
        while not self._stop.is_set():
            for vehicle in self.vehicles:
                if vehicle.status == "waiting" and self._heard_within(vehicle, flight.link_timeout_s):
                    self._start_launch(vehicle)
            waiting = [v for v in self.vehicles if v.status == "waiting"]
            if waiting and time.monotonic() >= deadline_s:
                flying = any(v.status in ("live", "launching") for v in self.vehicles)
                for vehicle in waiting:
                    vehicle.status, vehicle.lost_at_s = "not found", time.time()
                    if flying:  # else the error below names it
                        logger.warning("vehicle %d not found: no heartbeat within %.0f s; flying without "
                                       "it until heard", vehicle.system_id, flight.ready_timeout_s)
                    self._event("absent", vehicle)
                waiting = []
            if not waiting and not any(v.status == "launching" for v in self.vehicles):
                break
            self._clear_columns()
            self._guard_if_due()  # the climbing vehicles are watched from their take-off on
            self.flight_status.tick()
            time.sleep(TICK_S)
        if not self._stop.is_set() and not any(v.status == "live" for v in self.vehicles):
            by_status: dict[str, list[str]] = {}
            for v in self.vehicles:
                by_status.setdefault(v.status, []).append(str(v.system_id))
            failed = "; ".join(f"vehicle{'s' if len(ids) > 1 else ''} {', '.join(ids)}: {status}"
                               for status, ids in by_status.items())
            source = self.config.bridge_config or "the bridge config"
            hint = (f"none answered within --wait-ready-s ({self.config.flight.ready_timeout_s:g} s): start "
                    f"them first (SITL or real autopilots, or simulated ones in another terminal: uav-swarm "
                    f"vehicles --bridge-config {source}), or fly a fleet started here: uav-swarm fly "
                    "--simulated ardupilot" if all(v.status == "not found" for v in self.vehicles)
                    else "see the warnings above")
            raise BridgeError(f"no vehicle could be launched ({failed}); {hint}")

    def _clear_columns(self) -> None:
        """A live vehicle near the column of one still to climb is sent off it, beyond the launch spacing.

        Homes closer than the launch spacing climb one at a time: the vehicle up first is given a point
        (through the guard) at least ``1.5`` launch spacings from every home still to climb, the nearest
        such point to its home of 24 directions and three distances, so the next column clears.
        """
        homes, spacing_m = self.safety.homes_m, self.safety.launch_spacing_m
        climbing = self.safety.climbing
        pending = [homes[v.system_id] for v in self.vehicles
                   if v.status == "launching" and v.system_id in homes and v.system_id not in climbing]
        if not pending:
            return
        far_m = 1.5 * spacing_m
        for vehicle in self.vehicles:
            home = homes.get(vehicle.system_id)
            if vehicle.status != "live" or vehicle.target_m is not None or home is None:
                continue
            if all(math.dist(home, p) >= spacing_m for p in pending):
                continue
            candidates = [(home[0] + r * math.cos(a), home[1] + r * math.sin(a))
                          for r in (far_m, 2 * far_m, 3 * far_m)
                          for a in (k * math.pi / 12 for k in range(24))]
            free = [c for c in candidates if all(math.dist(c, p) >= far_m for p in pending)]
            if free:
                x, y = min(free, key=lambda c: math.dist(c, home))
                vehicle.target_m = (x, y, self.safety.cruise_alt_m[vehicle.system_id])

    # -- links ---------------------------------------------------------------------------------
    def _check_links(self) -> None:
        timeout_s = self.config.flight.link_timeout_s
        for vehicle in self.vehicles:
            state = self._state(vehicle)
            if vehicle.status == "live" and state is not None and state.armed is False:
                vehicle.status, vehicle.target_m = "landed", None
                self.outputs.retire(vehicle.uav_id)
                logger.warning("vehicle %d disarmed in flight (landed or taken over): left out of the plan",
                               vehicle.system_id)
                self._event("disarmed", vehicle)
            elif vehicle.status in ("live", "launching") and not self._heard_within(vehicle, timeout_s):
                vehicle.status, vehicle.lost_at_s = "lost", time.time()
                vehicle.target_m = None
                self.outputs.retire(vehicle.uav_id)
                logger.warning("vehicle %d lost: no heartbeat for %.1f s; replanning without it",
                               vehicle.system_id, timeout_s)
                self._event("lost", vehicle)
            elif vehicle.status in SILENT:
                if state is not None and (state.heartbeat_time_s or 0.0) > vehicle.lost_at_s:
                    logger.warning("vehicle %d heard again: taking it back", vehicle.system_id)
                    self._event("heard_again", vehicle)
                    self._start_launch(vehicle)
