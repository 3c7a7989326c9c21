"""The end of a live flight: launches cancelled, staggered returns through the guard, RTL or LAND.

:class:`FlightEnd` cancels every launch still running, flies the live vehicles home through the guard
when the end action is RTL (each sent RTL once over its home), and sends every vehicle heard the end
action; a vehicle whose end action is not acknowledged is named.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from bridge.errors import BridgeError
from bridge.flight.guided import end_flight
from uav_swarm.runs.flight.launch import FlightLaunch
from uav_swarm.runs.flight.vehicles import TICK_S, FlightVehicle
from uav_swarm.world.guard.reach import segment_distances_m

__all__ = ["FlightEnd"]

logger = logging.getLogger(__name__)

_HOME_M = 3.0  # a vehicle returning this close to its home (horizontally) is sent RTL


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
        """Staggered returns: every live vehicle flies home through the guard, sent RTL once its way is clear.

        A vehicle sent RTL climbs where it is to its own return layer (above every cruise layer, the
        layers apart), flies home at it and lands: an obstacle the guard keeps the others away from, with
        the column over its home. It is sent RTL once over its home, or sooner where that way is clear
        (:meth:`_rtl_clear`); until none is left or ``guard.return_timeout_s`` has passed.
        """
        homes, deadline_s = self.safety.homes_m, time.monotonic() + self.config.guard.return_timeout_s
        self.flight_status.enter("return", self.config.guard.return_timeout_s)
        flying = [v for v in self.vehicles if v.status == "live" and v.system_id in homes]
        for vehicle in flying:
            vehicle.target_m = (*homes[vehicle.system_id], self.safety.cruise_alt_m[vehicle.system_id])
        while time.monotonic() < deadline_s and any(v.status == "live" for v in flying):
            self._guard_if_due()
            for vehicle in (v for v in flying if v.status == "live"):
                state, home = self._state(vehicle), homes[vehicle.system_id]
                if state is None or state.x_m is None or state.y_m is None:
                    continue
                here = (float(state.x_m), float(state.y_m))
                over = np.hypot(here[0] - home[0], here[1] - home[1]) <= _HOME_M
                idle = all(job is None or job.done() for job in (vehicle.job, vehicle.guard_job))
                if (over or self._rtl_clear(vehicle, here)) and idle:  # after its last guard point
                    vehicle.status = "ending"
                    vehicle.job = self._pool.submit(self._end_one, vehicle, "rtl")
            self.flight_status.tick()
            time.sleep(TICK_S)
        away = [v.system_id for v in flying if v.status == "live"]
        if away:
            logger.warning("%s still away from home after [guard] return_timeout_s = %g s: sent RTL at once",
                           ", ".join(f"vehicle {sid}" for sid in away), self.config.guard.return_timeout_s)
        self.flight_status.wait([(v.system_id, v.job) for v in flying], "the answer to its RTL")
        for vehicle in (v for v in flying if v.status == "ending"):  # its RTL failed: sent again below
            vehicle.status = "live"

    def _rtl_clear(self, vehicle: FlightVehicle, here_m: tuple[float, float]) -> bool:
        """Whether ``vehicle`` may be sent RTL from ``here_m``: where its autopilot takes it keeps clear.

        Its RTL climbs over ``here_m`` (inside its certified disc), flies at its own return layer to its
        home and descends there. That way (the segment from ``here_m`` to its home) keeps the minimum
        (with the guard's margin) horizontally from the way of every vehicle already returning under RTL
        (whichever of the two is higher crosses the other's climb or descent), and its home keeps it from
        the certified disc of every vehicle still flying under the guard (it descends through their
        layer). A vehicle of unknown position in the air keeps every way closed.
        """
        guard = self.safety.guard
        need_m, homes = guard.need_m, self.safety.homes_m
        mine = np.array([here_m, homes[vehicle.system_id]], dtype=np.float64)
        for other in self.vehicles:
            if other is vehicle:
                continue
            state = self._state(other)
            if state is None or state.armed is False:
                continue
            if state.x_m is None or state.y_m is None:
                return False
            row = self.safety.uav_of(other.system_id)
            if other.status in ("ending", "ended"):
                if other.system_id not in homes:
                    return False
                theirs = np.array([(state.x_m, state.y_m), homes[other.system_id]], dtype=np.float64)
                if float(segment_distances_m(mine[0], mine[1], theirs[0], theirs[1])) < need_m:
                    return False
            elif guard.fleet.joined(row) or guard.fleet.is_obstacle(row):
                gap = float(np.hypot(*(guard.fleet.centre_m(row) - mine[1]))) - guard.fleet.radius_m(row)
                if not gap >= need_m:
                    return False
            elif np.hypot(state.x_m - mine[1][0], state.y_m - mine[1][1]) < need_m:
                return False
        return True
