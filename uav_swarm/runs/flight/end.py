"""The end of a live flight: launches cancelled, staggered returns through the guard, RTL or LAND.

:class:`FlightEnd` cancels every launch still running, flies the live vehicles home through the guard
when the end action is RTL (each sent RTL once over its home), and sends every vehicle heard the end
action; a vehicle whose end action is not acknowledged is named.
"""

from __future__ import annotations

import logging
import time
from typing import TYPE_CHECKING

import numpy as np

from bridge.errors import BridgeError
from bridge.flight.guided import end_flight
from bridge.flight.preflight import set_return_altitude
from uav_swarm.runs.flight.launch import FlightLaunch
from uav_swarm.runs.flight.vehicles import SILENT, TICK_S, FlightVehicle
from uav_swarm.world.guard.failsafe import FailsafeFlight, crossing_order, flights_apart

if TYPE_CHECKING:
    from bridge.link.vehicle_state import VehicleState

__all__ = ["FlightEnd"]

logger = logging.getLogger(__name__)

class FlightEnd(FlightLaunch):
    """A flight's end (launches and links: :class:`~uav_swarm.runs.flight.launch.FlightLaunch`)."""

    # -- end -----------------------------------------------------------------------------------
    def _end_all(self) -> None:
        """Send every vehicle heard (and not landed) the end action; failures are named.

        Launches still running are cancelled first (they stop between two steps), so no vehicle
        takes off after its end action. With RTL the live vehicles first fly home through the guard
        (:meth:`_return_home`); the others, and any still away after ``guard.return_timeout_s``, are
        sent it at once (their return altitudes are layers apart).
        """
        action, status = self.config.flight.end_action, self.flight_status
        status.enter("end")
        self._stop.set()
        status.wait([(v.system_id, job) for v in self.vehicles for job in (v.job, v.guard_job)],
                    "its launch or last point to stop")
        if self._refused:  # refused before any vehicle was armed: nothing to end
            return
        if action == "rtl":
            self._return_home()
            status.enter("end")
        heard = []
        for vehicle in self.vehicles:
            state = self._state(vehicle)
            if state is None or vehicle.status in ("landed", "ended"):
                continue
            if state.armed is False:  # on the ground: nothing to end (an RTL would be refused)
                if vehicle.status != "live":
                    self._event("not_launched", vehicle, vehicle.status)
                    logger.warning("vehicle %d was not launched (%s)", vehicle.system_id, vehicle.status)
                continue
            heard.append(vehicle)
        jobs = [(v.system_id, self._pool.submit(self._end_one, v, action)) for v in heard]
        status.wait(jobs, f"the answer to its {action.upper()}")
        for _, job in jobs:
            job.result()

    def _end_one(self, vehicle: FlightVehicle, action: str) -> None:
        try:
            sid = vehicle.system_id
            end_flight(self.fleet.link(sid), sid, action, self.bridge.protocol)  # type: ignore[arg-type]
        except BridgeError as exc:
            logger.warning("vehicle %d: %s not acknowledged: %s: %s", vehicle.system_id, action.upper(),
                           type(exc).__name__, exc)
            self._event("end_failed", vehicle, f"{type(exc).__name__}: {exc}")
            return
        vehicle.status = "ended"
        self._event(action, vehicle)

    def _return_home(self) -> None:
        """Returns planned home with their layers: each live vehicle is sent RTL once its flight is apart.

        The live vehicles' return layers are first ordered by crossing (:meth:`_order_layers`). A vehicle
        sent RTL climbs where it is to its own return layer (above every cruise layer, the layers apart),
        flies home at it and lands; until it may be sent (:meth:`_rtl_clear`) it flies home through the
        guard. After ``guard.return_timeout_s`` the vehicles still away are sent RTL by the same rule, in
        turn as the others land; one still refused after as long again is sent RTL anyway, named.
        """
        guard, homes = self.config.guard, self.safety.homes_m
        deadline_s = time.monotonic() + guard.return_timeout_s
        self.flight_status.enter("return", guard.return_timeout_s)
        flying = [v for v in self.vehicles if v.status == "live" and v.system_id in homes]
        for vehicle in flying:
            vehicle.target_m = (*homes[vehicle.system_id], self.safety.cruise_alt_m[vehicle.system_id])
        self._order_layers(flying)
        late = False
        while any(v.status == "live" for v in flying):
            if not late and time.monotonic() >= deadline_s:
                late = True
                away = ", ".join(f"vehicle {v.system_id}" for v in flying if v.status == "live")
                logger.warning("%s still away from home after [guard] return_timeout_s = %g s: each sent RTL "
                               "once its return is apart from the others'", away, guard.return_timeout_s)
            if time.monotonic() >= deadline_s + guard.return_timeout_s:
                break
            self._guard_if_due()
            for vehicle in (v for v in flying if v.status == "live"):
                state = self._state(vehicle)
                if state is None or state.x_m is None or state.y_m is None:
                    continue
                idle = all(job is None or job.done() for job in (vehicle.job, vehicle.guard_job))
                if idle and self._rtl_clear(vehicle):  # after its last guard point
                    self.safety.rtl_waits.pop(vehicle.system_id, None)
                    vehicle.status = "ending"
                    vehicle.job = self._pool.submit(self._end_one, vehicle, "rtl")
            self.flight_status.tick()
            time.sleep(TICK_S)
        for vehicle in (v for v in flying if v.status == "live"):
            logger.warning("vehicle %d: sent RTL without a return apart from the others' (%s) after twice "
                           "[guard] return_timeout_s", vehicle.system_id,
                           self.safety.rtl_waits.get(vehicle.system_id, "no position"))
        self.flight_status.wait([(v.system_id, v.job) for v in flying], "the answer to its RTL")
        for vehicle in (v for v in flying if v.status == "ending"):  # its RTL failed: sent again below
            vehicle.status = "live"

    def _order_layers(self, flying: list[FlightVehicle]) -> None:
        """The live vehicles' return layers by crossing order, set on each vehicle and read back.

        A vehicle whose way home passes over another's climb or descent column flies above it
        (:func:`~uav_swarm.world.guard.failsafe.crossing_order`); the layers the live vehicles hold are
        given out again in that order. With a cycle the layers stay; a vehicle whose layer cannot be set
        keeps the one it holds (both: its RTL waits until its flight is apart).
        """
        flights = {v.system_id: self._failsafe_flight(v) for v in flying}
        known = [(sid, f) for sid, f in flights.items() if f is not None]
        order = crossing_order([f for _, f in known], self.safety.guard.need_m)
        if order is None:
            logger.info("return layers kept: the ways home cross in a cycle; each RTL waits for its turn")
            return
        layers = sorted(self.safety.return_alt_m[sid] for sid, _ in known)
        wanted = {known[k][0]: layer for k, layer in zip(order, layers, strict=True)}
        jobs = [(sid, self._pool.submit(self._set_layer, sid, alt_m)) for sid, alt_m in wanted.items()
                if alt_m != self.safety.return_alt_m[sid]]
        self.flight_status.wait(jobs, "its return layer set")
        for _, job in jobs:
            job.result()

    def _set_layer(self, system_id: int, alt_m: float) -> None:
        try:
            held_m = set_return_altitude(self.fleet.link(system_id), system_id,
                                         self.fleet.conventions(system_id), alt_m, self.bridge.protocol)
        except BridgeError as exc:
            logger.warning("vehicle %d: return layer %g m not set (%s): it keeps %g m", system_id, alt_m, exc,
                           self.safety.return_alt_m[system_id])
            return
        self.safety.return_alt_m[system_id] = held_m
        self._event("return_layer", self._by_sid[system_id], f"{held_m:g} m")

    def _failsafe_flight(self, vehicle: FlightVehicle) -> FailsafeFlight | None:
        """Where ``vehicle``'s RTL or failsafe may take it: its disc (or position), home and layer."""
        sid, guard = vehicle.system_id, self.config.guard
        home = self.safety.homes_m.get(sid)
        if home is None:
            return None
        row, fleet = self.safety.uav_of(sid), self.safety.guard.fleet
        errors_m = guard.position_error_m + guard.tracking_error_m
        if fleet.joined(row) or fleet.is_obstacle(row):
            centre, radius_m = fleet.centre_m(row), fleet.radius_m(row)
        else:
            state = self._state(vehicle)
            if state is None or state.x_m is None or state.y_m is None:
                return None
            centre, radius_m = np.array([state.x_m, state.y_m]), errors_m
        return FailsafeFlight((float(centre[0]), float(centre[1])), float(radius_m), home, errors_m,
                              self.safety.return_alt_m[sid])

    def _rtl_clear(self, vehicle: FlightVehicle) -> bool:
        """Whether ``vehicle`` may be sent RTL now: its failsafe flight keeps clear of every other vehicle.

        Its RTL climbs inside its certified disc to its own return layer, flies home at it and descends
        there (:class:`~uav_swarm.world.guard.failsafe.FailsafeFlight`). That flight must be apart
        (:func:`~uav_swarm.world.guard.failsafe.flights_apart`) from the flight of every vehicle already
        in RTL and the possible failsafe flight of every silent one (lost while armed: it may climb where
        it is at any time), and its home must keep the minimum (with the guard's margin) from the
        certified disc of every vehicle still flying under the guard (it descends through their layer).
        A vehicle of unknown position in the air keeps every way closed. Why it waits is kept in
        ``safety.rtl_waits`` for the status line.
        """
        need_m, homes, sid = self.safety.guard.need_m, self.safety.homes_m, vehicle.system_id
        mine = self._failsafe_flight(vehicle)
        for other in self.vehicles:
            state = self._state(other)
            if other is vehicle or state is None or state.armed is False:
                continue
            why = self._rtl_blocked_by(mine, other, state, need_m, homes[sid])
            if why:
                self.safety.rtl_waits[sid] = f"its RTL waits for vehicle {other.system_id} ({why})"
                return False
        return mine is not None

    def _rtl_blocked_by(self, mine: FailsafeFlight | None, other: FlightVehicle, state: VehicleState,
                        need_m: float, home_m: tuple[float, float]) -> str:
        """Why ``other`` keeps an RTL flying ``mine`` from being sent ("" when it does not)."""
        if mine is None or state.x_m is None or state.y_m is None:
            return "its position unknown"
        row, fleet = self.safety.uav_of(other.system_id), self.safety.guard.fleet
        if other.status in ("ending", "ended") or other.status in SILENT:
            theirs = self._failsafe_flight(other)
            if theirs is None or not flights_apart(mine, theirs, need_m):
                return "silent: its failsafe may cross" if other.status in SILENT else "its return crosses"
        elif fleet.joined(row) or fleet.is_obstacle(row):
            gap = float(np.hypot(*(fleet.centre_m(row) - np.asarray(home_m)))) - fleet.radius_m(row)
            if not gap >= need_m:
                return "it flies near our home"
        elif np.hypot(state.x_m - home_m[0], state.y_m - home_m[1]) < need_m:
            return "it is near our home"
        return ""
