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
from uav_swarm.runs.flight_launch import FlightLaunch
from uav_swarm.runs.flight_vehicles import TICK_S, FlightVehicle

__all__ = ["FlightEnd"]

logger = logging.getLogger(__name__)

_HOME_M = 3.0  # a vehicle returning this close to its home (horizontally) is sent RTL


class FlightEnd(FlightLaunch):
    """A flight's end (launches and links: :class:`~uav_swarm.runs.flight_launch.FlightLaunch`)."""

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
        """Staggered returns: every live vehicle flies home through the guard, and RTL once over it.

        A vehicle sent RTL climbs to its return layer and lands where it is, an obstacle the guard keeps
        the others away from; until none is left or ``guard.return_timeout_s`` has passed.
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
                over = (state is not None and state.x_m is not None and state.y_m is not None
                        and np.hypot(state.x_m - home[0], state.y_m - home[1]) <= _HOME_M)
                idle = all(job is None or job.done() for job in (vehicle.job, vehicle.guard_job))
                if over and idle:  # its RTL after its last guard point, never before
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
