"""The planning and guard step of a live flight: plan from measured positions, send through the guard.

:class:`FlightStep` plans from the live vehicles' **measured** positions (one planner per number of
live vehicles), puts the operator's targets in place of the planner's where they steer, and hands each
target to the separation guard (:mod:`uav_swarm.runs.flight.safety`); every ``1 / guard.rate_hz``
wall-clock seconds the guard decides on the measured positions and each point it gives goes to its
vehicle at once, on its own job (``MAV_CMD_DO_REPOSITION``, or a new mission flown in AUTO).
"""

from __future__ import annotations

import logging
import time
from typing import TYPE_CHECKING

import numpy as np

from bridge.errors import BridgeError
from bridge.flight.guided import set_mode
from uav_swarm.planning.planner import Planner, make_planner
from uav_swarm.runs.flight.vehicles import FlightVehicle, FlightVehicles

if TYPE_CHECKING:
    from bridge.link.vehicle_state import VehicleState

__all__ = ["FlightStep"]

logger = logging.getLogger(__name__)


class FlightStep(FlightVehicles):
    """A flight's planning step and guard tick (the vehicle table: :class:`FlightVehicles`)."""

    # -- planning ------------------------------------------------------------------------------
    def _planner(self, n: int) -> Planner:
        if n not in self._planners:
            cfg = self.config
            self._planners[n] = make_planner(cfg.planner, n, cfg.task, checkpoint=cfg.checkpoint or None,
                                             config=cfg.planning, uav_config=cfg.uav)
        return self._planners[n]

    def _replan(self, seq: int, previous_ids: tuple[int, ...]) -> tuple[int, ...]:
        live = self._live()
        ids = tuple(v.system_id for v, _ in live)
        if not live:
            return ids
        planner = self._planner(len(live))
        if ids != previous_ids:
            planner.reset()
        positions = np.array([(s.x_m, s.y_m) for _, s in live])
        result = planner.plan(self.crowd.positions_m, positions, self.crowd.velocities_m_s)
        targets = [(float(x), float(y), self.safety.cruise_alt_m[v.system_id])
                   for (v, _), (x, y) in zip(live, result.targets_m, strict=True)]
        self.plans.append({v.uav_id: (t[0], t[1]) for (v, _), t in zip(live, targets, strict=True)})
        targets = self._steered(live, targets)
        if self.outputs.active:
            from bridge.telemetry.schema import Plan, PlanTarget

            self.outputs.plan(self._clock_s, Plan(
                stamp_s=time.time(), seq=seq, source="vehicle", planner=planner.name,
                latency_ms=float(result.latency_ms), targets=tuple(
                    PlanTarget(uav_id=v.uav_id, target_enu_m=t)
                    for (v, _), t in zip(live, targets, strict=True))))
        self._send(live, targets)
        return ids

    def _steered(self, live: list[tuple[FlightVehicle, VehicleState]],
                 targets: list[tuple[float, float, float]]) -> list[tuple[float, float, float]]:
        """The planner's targets with the operator's in place and kept clear (told to the operator)."""
        if self.steering is None:
            return targets
        planned = {v.uav_id: (t[0], t[1]) for (v, _), t in zip(live, targets, strict=True)}
        self.steering.planned(planned)
        steered = self.steering.apply(planned)
        cruise_m = self.safety.cruise_alt_m
        return [t if steered[v.uav_id] == planned[v.uav_id] else (*steered[v.uav_id], cruise_m[v.system_id])
                for (v, _), t in zip(live, targets, strict=True)]

    def _steer(self) -> None:
        """Operator targets changed: send each live vehicle the operator's target, or its planned one back."""
        live = self._live()
        planned = self.plans[-1] if self.plans else {}
        here = [planned.get(v.uav_id, (float(s.x_m or 0.0), float(s.y_m or 0.0))) for v, s in live]
        targets = self._steered(live, [(x, y, self.safety.cruise_alt_m[v.system_id])
                                       for (v, _), (x, y) in zip(live, here, strict=True)])
        self._send(live, targets)

    def _send(self, live: list[tuple[FlightVehicle, VehicleState]], targets: list[tuple[float, float, float]]
              ) -> None:
        """Each live vehicle's new target, flown through the separation guard (:meth:`_guard_tick`)."""
        for (vehicle, _), target in zip(live, targets, strict=True):
            vehicle.target_m = target  # sent through the guard (_guard_tick)

    # -- separation guard ----------------------------------------------------------------------
    def _guard_if_due(self) -> None:
        """A guard decision every ``1 / guard.rate_hz`` wall-clock seconds (the vehicles fly in real time)."""
        if time.monotonic() >= self._next_guard_s:
            self._next_guard_s = time.monotonic() + 1.0 / self.config.guard.rate_hz
            self._guard_tick()

    def _guard_tick(self) -> None:
        """The guard's decisions on the measured positions; each point it gives is sent to its vehicle.

        A guard point goes out at once on its own job (one copy, answered within ``[guard]
        command_delay_s``), never behind another command to that vehicle: while one is being sent the
        vehicle is ``busy`` and the guard sends it nothing new (it keeps flying to a point it can stop at).
        """
        flying, busy, returning, grounded = [], [], [], []
        for vehicle in self.vehicles:
            state = self._state(vehicle)
            if state is not None and state.armed is False and vehicle.status not in ("live", "launching"):
                grounded.append(vehicle.system_id)  # on the ground: out of the guard
            if state is None or state.x_m is None:
                continue  # unheard or without a fix: the guard keeps its disc
            if vehicle.status in ("ending", "ended") and state.armed:  # flying home, landing: an obstacle
                returning.append(vehicle.system_id)
            if vehicle.status in ("live", "launching") or vehicle.system_id in returning:
                goal = vehicle.target_m[:2] if vehicle.status == "live" and vehicle.target_m else None
                flying.append((vehicle.system_id, state, goal, vehicle.status == "live"))
            if vehicle.guard_job is not None and not vehicle.guard_job.done():
                busy.append(vehicle.system_id)
        for sid, decision in self.safety.decide(flying, self._clock_s, time.time(), busy, returning,
                                                grounded):
            vehicle = self._by_sid[sid]
            if decision.point_m is None or vehicle.status != "live":
                continue
            point = (*decision.point_m, self.safety.cruise_alt_m[sid])
            vehicle.guard_job = self._pool.submit(self._send_point, vehicle, point, decision.seq,
                                                  decision.state)

    def _send_point(self, vehicle: FlightVehicle, target: tuple[float, float, float], seq: int,
                    state: str) -> None:
        """Send one guard point (one copy) and tell the guard whether it was acknowledged in its bound."""
        sid = vehicle.system_id
        guard = self.config.guard
        protocol = self.bridge.protocol.replace(max_retries=0, handshake_timeout_s=guard.command_delay_s)
        try:
            if self.config.mode == "guided" or state != "free":  # a stop is a guided reposition
                self.fleet.reposition(sid, *target, speed_m_s=self.config.uav.max_speed_m_s,  # the planner's
                                      protocol=protocol)
                vehicle.in_auto = False
            else:
                self._fly_mission(vehicle, target)
        except BridgeError as exc:
            vehicle.command_failures += 1
            self.safety.unacknowledged(sid, seq, time.time())
            logger.warning("vehicle %d: point (%.1f, %.1f, %.1f) not acknowledged: %s: %s", sid, *target,
                           type(exc).__name__, exc)
            self._event("command_failed", vehicle, f"{type(exc).__name__}: {exc}")
            return
        self.safety.acknowledged(sid, seq, time.time())

    def _fly_mission(self, vehicle: FlightVehicle, target: tuple[float, float, float]) -> None:
        from pymavlink.dialects.v20.common import MAV_CMD_NAV_WAYPOINT as NAV_WAYPOINT

        from bridge.missions.items import build_mission

        sid = vehicle.system_id
        conventions = self.fleet.conventions(sid)
        alt_m = self.safety.cruise_alt_m[sid]
        shape = self.bridge.mission.replace(takeoff_alt_m=alt_m, cruise_alt_m=alt_m,
                                            speed_m_s=self.config.uav.max_speed_m_s)  # the planner's speed
        mission = build_mission([target], self.bridge.home, shape, self.bridge.geofence,
                                conventions.autopilot)
        client = self.fleet.client(sid)
        client.upload(mission.items)
        first_waypoint = next(i.seq for i in mission.items if i.command == NAV_WAYPOINT and i.seq > 0)
        client.set_current(first_waypoint)
        if not vehicle.in_auto:
            set_mode(self.fleet.link(sid), sid, conventions.mission_mode, self.bridge.protocol)
            vehicle.in_auto = True
