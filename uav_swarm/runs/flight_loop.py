"""The live loop of ``uav-swarm fly``: launch, replan from measured positions, faults, the end.

:class:`Flight` runs the crowd world in real time (or ``speedup`` times faster) and, every
``replan_every_s`` of crowd time, plans from the vehicles' **measured** positions and sends each
live vehicle its new target while it flies (``MAV_CMD_DO_REPOSITION``, or a new mission flown in
AUTO), through the separation guard (:mod:`uav_swarm.runs.flight_safety`), which holds a vehicle
whose predicted track comes too close to another's. Every vehicle heard is first made ready (a
position fix and its home, each waited for on its own, :meth:`bridge.flight.fleet.Fleet.wait_ready`)
and checked (take-off positions, link-loss failsafe, return altitude) before any is armed; then
they take off one at a time (:mod:`bridge.flight.guided`); a vehicle silent for
``flight.link_timeout_s`` is lost and replanned around, and launched again when heard; a live
vehicle seen disarmed is left out. At the end every launch still running is cancelled and every
vehicle heard is sent RTL or LAND. States are published as each position arrives, plans and QoS as
they are made. :func:`uav_swarm.runs.fly.fly` opens the fleet and telemetry and writes the outputs.
"""

from __future__ import annotations

import logging
import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor, wait
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from bridge.errors import BridgeError
from bridge.flight.guided import end_flight, launch, set_mode
from bridge.flight.preflight import PreflightError
from uav_swarm.planning.planner import Planner, make_planner
from uav_swarm.runs.flight_safety import FlightSafety
from uav_swarm.runs.fly_config import FlyConfig
from uav_swarm.runs.outputs import RunOutputs
from uav_swarm.runs.radio_report import sharing_pairs, telemetry_fields
from uav_swarm.runs.records import QosTrace
from uav_swarm.world.comms import Association
from uav_swarm.world.crowd import CrowdSim
from uav_swarm.world.scenario import random_scenario
from uav_swarm.world.wifi_channels import plan_channels

if TYPE_CHECKING:
    from bridge.config import BridgeConfig
    from bridge.flight.fleet import Fleet
    from bridge.flight.vehicle_home import ReportedHome
    from bridge.link.vehicle_state import VehicleState
    from uav_swarm.runs.steering import OperatorTargets

__all__ = ["Flight"]

logger = logging.getLogger(__name__)

_HOME_M = 2.0  # a vehicle returning this close to its home (horizontally) is sent RTL
_TICK_S = 0.02  # longest sleep of the loop (wall clock)
_SILENT = ("not found", "lost")  # never heard, or silent since: taken back when heard


@dataclass
class _Vehicle:
    """A flight's vehicle; ``status``: waiting, launching, live, not found, lost, landed, failed, ended."""

    system_id: int
    uav_id: int
    status: str = "waiting"
    target_m: tuple[float, float, float] | None = None
    seq: int = 0
    in_auto: bool = False
    lost_at_s: float = 0.0
    job: Future | None = None
    guard_job: Future | None = None
    command_failures: int = 0
    launches: int = 0


class Flight:
    """One live flight of the vehicles of ``bridge`` under the planner (see the module docstring).

    Args:
        config: The flight's settings.
        bridge: The bridge config (:func:`load_flight_bridge`).
        fleet: The open fleet of ``bridge``'s vehicles.
        outputs: The flight's sinks (:mod:`uav_swarm.runs.outputs`, states on arrival): each vehicle's
            state as it arrives, the plans, and every ``record_every_s`` the scene, the states and the QoS,
            at crowd time.
        planner: The planner for every vehicle of the flight, when already built (others are built
            when vehicles are lost).
        steering: Operator targets that replace the planner's for the UAVs they name, sent at once.
    """

    def __init__(self, config: FlyConfig, bridge: BridgeConfig, fleet: Fleet,
                 outputs: RunOutputs | None = None, planner: Planner | None = None,
                 steering: OperatorTargets | None = None) -> None:
        self.config = config
        self.outputs = outputs or RunOutputs(states_on_arrival=True)
        self.steering = steering
        self.bridge = bridge
        self.fleet = fleet
        n = config.n_uavs or len(bridge.vehicles)
        self.vehicles = [_Vehicle(v.system_id, uav_id) for uav_id, v in enumerate(bridge.vehicles[:n])]
        self._by_sid = {v.system_id: v for v in self.vehicles}
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._pool = ThreadPoolExecutor(max_workers=2 * len(self.vehicles), thread_name_prefix="flight")
        self._planners: dict[int, Planner] = {} if planner is None else {planner.n_uavs: planner}
        self.events: list[dict[str, Any]] = []
        self.plans: list[dict[int, tuple[float, float]]] = []
        """Each replan's targets by UAV id (for the target jumps of the summary)."""
        self.crowd_samples: list[tuple[float, np.ndarray, np.ndarray]] = []
        """``(time_s, positions, velocities)`` of the crowd every ``static_every_s`` (static reference)."""
        self._clock_s = 0.0
        rng = np.random.default_rng(config.seed)
        self.scenario = random_scenario(rng, config.task.scenario)
        self.crowd = CrowdSim(self.scenario, config.task.crowd, rng)
        self._association = Association(config.task.radio)
        self._channels: dict[int, int] = {}
        """Each vehicle's channel by id (802.11 radio), planned as the vehicles fly."""
        """The users' association over the flight (admission control keeps incumbents on their UAV)."""
        self.safety = FlightSafety(config, bridge, fleet, self._stop,
                                   lambda kind, sid, detail: self._event(kind, self._by_sid.get(sid), detail))
        self._refused = False
        self._next_guard_s = 0.0
        fleet.tracker.add_listener(self._on_state)

    # -- control -------------------------------------------------------------------------------
    def stop(self) -> None:
        """End the flight at the next loop turn (safe from a signal handler)."""
        self._stop.set()

    def run(self) -> tuple[QosTrace, list[dict[str, Any]]]:
        """Launch, fly the loop, end every vehicle; the QoS trace and the track records.

        Raises:
            BridgeError: No vehicle could be launched (every one named in the message).
        """
        try:
            self._launch_all()
            trace, track = self._loop()
        finally:
            self._end_all()
            self._pool.shutdown(wait=True)
        return trace, track

    def _event(self, kind: str, vehicle: _Vehicle | None, detail: str = "") -> None:
        record = {"time_s": round(self._clock_s, 3), "event": kind, "detail": detail}
        if vehicle is not None:
            record |= {"system_id": vehicle.system_id, "uav_id": vehicle.uav_id}
        with self._lock:
            self.events.append(record)

    def _state(self, vehicle: _Vehicle) -> VehicleState | None:
        return self.fleet.tracker.state(vehicle.system_id)

    def _heard_within(self, vehicle: _Vehicle, seconds: float) -> bool:
        state = self._state(vehicle)
        return (state is not None and state.heartbeat_time_s is not None
                and time.time() - state.heartbeat_time_s <= seconds)

    # -- launch --------------------------------------------------------------------------------
    def _start_launch(self, vehicle: _Vehicle, home: ReportedHome | None = None) -> None:
        vehicle.status = "launching"
        vehicle.launches += 1
        vehicle.in_auto = False
        vehicle.job = self._pool.submit(self._launch_one, vehicle, home)

    def _ready(self, vehicle: _Vehicle) -> ReportedHome:
        """A fix and its home (checked against [home]) before anything that moves it."""
        flight = self.config.flight
        return self.fleet.wait_ready(vehicle.system_id, flight.ready_timeout_s, flight.stream_rate_hz,
                                     cancel=self._stop)

    def _launch_one(self, vehicle: _Vehicle, home: ReportedHome | None = None) -> None:
        """Launch a checked vehicle (``home`` given), or check one taken back in flight first."""
        sid = vehicle.system_id
        autopilot = self.fleet.conventions(sid).autopilot  # from its HEARTBEAT
        try:
            if home is None:
                home = self._ready(vehicle)
                self.safety.check_relaunch(sid, home)
            launch(self.fleet.link(sid), self.fleet.tracker, sid, autopilot, self.safety.cruise_alt_m[sid],
                   self.config.flight, self.bridge.protocol, cancel=self._stop, home_alt_m=home.home.alt_m,
                   takeoff_gate=self.safety.takeoff_gate(sid))
        except BridgeError as exc:
            if vehicle.status in _SILENT or self._stop.is_set():  # taken back when heard / the flight ends
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
        flight = self.config.flight
        deadline_s = time.monotonic() + flight.ready_timeout_s
        while not self._stop.is_set() and time.monotonic() < deadline_s and not all(
                self._heard_within(v, flight.link_timeout_s) for v in self.vehicles):
            time.sleep(_TICK_S)
        heard = [v for v in self.vehicles if self._heard_within(v, flight.link_timeout_s)]
        jobs = {v.system_id: self._pool.submit(self._ready, v) for v in heard}
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
            try:
                self.safety.check_launch(homes)
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
        while not self._stop.is_set():
            for vehicle in self.vehicles:
                if vehicle.status == "waiting" and self._heard_within(vehicle, flight.link_timeout_s):
                    self._start_launch(vehicle)
            waiting = [v for v in self.vehicles if v.status == "waiting"]
            if waiting and time.monotonic() >= deadline_s:
                for vehicle in waiting:
                    vehicle.status, vehicle.lost_at_s = "not found", time.time()
                    logger.warning("vehicle %d not found: no heartbeat within %.0f s; flying without it "
                                   "until heard", vehicle.system_id, flight.ready_timeout_s)
                    self._event("absent", vehicle)
                waiting = []
            if not waiting and not any(v.status == "launching" for v in self.vehicles):
                break
            self._guard_if_due()  # the climbing vehicles are watched from their take-off on
            time.sleep(_TICK_S)
        if not self._stop.is_set() and not any(v.status == "live" for v in self.vehicles):
            failed = "; ".join(f"vehicle {v.system_id}: {v.status}" for v in self.vehicles)
            raise BridgeError(f"no vehicle could be launched ({failed}); see the warnings above")

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
            elif vehicle.status in _SILENT:
                if state is not None and (state.heartbeat_time_s or 0.0) > vehicle.lost_at_s:
                    logger.warning("vehicle %d heard again: taking it back", vehicle.system_id)
                    self._event("heard_again", vehicle)
                    self._start_launch(vehicle)

    # -- planning ------------------------------------------------------------------------------
    def _planner(self, n: int) -> Planner:
        if n not in self._planners:
            cfg = self.config
            self._planners[n] = make_planner(cfg.planner, n, cfg.task, checkpoint=cfg.checkpoint or None,
                                             config=cfg.planning, uav_config=cfg.uav)
        return self._planners[n]

    def _live(self) -> list[tuple[_Vehicle, VehicleState]]:
        live = []
        for vehicle in self.vehicles:
            state = self._state(vehicle)
            if vehicle.status == "live" and state is not None and state.x_m is not None:
                live.append((vehicle, state))
        return live

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

    def _steered(self, live: list[tuple[_Vehicle, VehicleState]], targets: list[tuple[float, float, float]]
                 ) -> list[tuple[float, float, float]]:
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

    def _send(self, live: list[tuple[_Vehicle, VehicleState]], targets: list[tuple[float, float, float]]
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
        flying, busy = [], []
        for vehicle in self.vehicles:
            state = self._state(vehicle)
            if state is None or state.x_m is None:
                continue
            returning = vehicle.status in ("ending", "ended") and state.armed  # landing: an obstacle
            if vehicle.status in ("live", "launching") or returning:
                goal = vehicle.target_m[:2] if vehicle.status == "live" and vehicle.target_m else None
                flying.append((vehicle.system_id, state, goal, vehicle.status == "live"))
            if vehicle.guard_job is not None and not vehicle.guard_job.done():
                busy.append(vehicle.system_id)
        for sid, decision in self.safety.decide(flying, self._clock_s, time.time(), busy):
            vehicle = self._by_sid[sid]
            if decision.point_m is None or vehicle.status != "live":
                continue
            point = (*decision.point_m, self.safety.cruise_alt_m[sid])
            vehicle.guard_job = self._pool.submit(self._send_point, vehicle, point, decision.seq,
                                                  decision.state)

    def _send_point(self, vehicle: _Vehicle, target: tuple[float, float, float], seq: int,
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

    def _fly_mission(self, vehicle: _Vehicle, target: tuple[float, float, float]) -> None:
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

    # -- loop ----------------------------------------------------------------------------------
    def _record(self, times: list[float], rows: list[tuple[float, float, float]],
                track: list[dict[str, Any]], seq: int) -> None:
        live = self._live()
        users = self.crowd.positions_m
        uavs = np.array([(s.x_m, s.y_m) for _, s in live]).reshape(-1, 2)
        heights = channels = None  # the paper's radio is 2-D; the 802.11 model takes heights and channels
        radio = self.config.task.radio
        if radio.propagation == "802.11" and live:
            heights = np.array([s.z_m if s.z_m is not None else self.safety.cruise_alt_m[v.system_id]
                                for v, s in live], dtype=np.float64)
            kept = np.array([self._channels.get(v.uav_id, -1) for v, _ in live])
            channels = plan_channels(uavs, radio, heights, kept)  # each vehicle keeps its channel while valid
            self._channels = {v.uav_id: int(c) for (v, _), c in zip(live, channels, strict=True)}
        ids = [vehicle.uav_id for vehicle, _ in live]
        cov = self._association.update(users, uavs, ids, heights, channels)
        times.append(self._clock_s)
        rows.append((float(cov.qos_s1), float(cov.qos_s2), float(cov.mean_throughput_mbps)))
        if self.outputs.active:
            from bridge.telemetry.schema import Qos

            pairs = None if channels is None or heights is None else \
                int(sharing_pairs(uavs, channels, radio, heights).sum())
            qos = Qos(stamp_s=time.time(), seq=seq, source="vehicle", qos_s1=rows[-1][0], qos_s2=rows[-1][1],
                      mean_throughput_mbps=rows[-1][2], n_users=int(users.shape[0]),
                      **telemetry_fields(cov, pairs)[1])  # 802.11: median SINR, co-channel pairs
            self._record_step(qos, users, cov.covered, seq)
        for vehicle in self.vehicles:
            state = self._state(vehicle)
            if state is None or state.x_m is None:
                continue
            target = vehicle.target_m or (None, None, None)
            track.append({"time_s": self._clock_s, "uav_id": vehicle.uav_id, "system_id": vehicle.system_id,
                          "status": vehicle.status, "x_m": state.x_m, "y_m": state.y_m, "z_m": state.z_m,
                          "target_x_m": target[0], "target_y_m": target[1], "target_z_m": target[2],
                          "wifi_channel": self._channels.get(vehicle.uav_id)})

    def _record_step(self, qos: Any, users: np.ndarray, covered: np.ndarray, seq: int) -> None:
        """Record each heard vehicle's state (with or without a position fix), the scene and the QoS."""
        from bridge.telemetry.schema import state_from_vehicle

        heard = [(v, self._state(v)) for v in self.vehicles]
        states = [state_from_vehicle(state, seq, uav_id=v.uav_id, target_enu_m=v.target_m)
                  for v, state in heard if state is not None]
        self.outputs.step(self._clock_s, [s for s in states if s is not None], qos, users, covered)

    def _loop(self) -> tuple[QosTrace, list[dict[str, Any]]]:
        cfg = self.config
        dt_s = cfg.task.crowd.dt_s
        steps_per_replan = max(1, round(cfg.replan_every_s / dt_s))
        steps_per_record = max(1, round(cfg.record_every_s / dt_s))
        steps_per_sample = max(1, round(cfg.static_every_s / dt_s))
        n_steps = max(1, round(cfg.duration_s / dt_s))
        times: list[float] = []
        rows: list[tuple[float, float, float]] = []
        track: list[dict[str, Any]] = []
        ids: tuple[int, ...] = ()
        start_s = time.monotonic()
        step = 0
        self._event("loop_started", None)
        self.outputs.static_scene(self.scenario.obstacles)
        steered = 0
        while step < n_steps and not self._stop.is_set():
            self._guard_if_due()
            due = min(n_steps, int((time.monotonic() - start_s) * cfg.speedup / dt_s) + 1)
            while step < due:
                self._check_links()
                if step % steps_per_replan == 0:
                    ids = self._replan(step // steps_per_replan, ids)
                    steered = self.steering.version if self.steering is not None else 0
                elif self.steering is not None and self.steering.version != steered:
                    steered = self.steering.version
                    self._steer()
                if step % steps_per_sample == 0:
                    self.crowd_samples.append((step * dt_s, np.array(self.crowd.positions_m),
                                               np.array(self.crowd.velocities_m_s)))
                self.crowd.step(1)
                step += 1
                self._clock_s = step * dt_s
                if step % steps_per_record == 0 or step == n_steps:
                    self._record(times, rows, track, step)
            wake_s = min(start_s + step * dt_s / cfg.speedup, self._next_guard_s)
            self._stop.wait(min(_TICK_S, max(0.0, wake_s - time.monotonic())))
        name = self._planner(max(1, len(ids) or len(self.vehicles))).name
        values = np.array(rows, dtype=np.float64).reshape(-1, 3)
        trace = QosTrace(planner_name=name, times_s=np.array(times), qos_s1=values[:, 0], qos_s2=values[:, 1],
                         throughput_mbps=values[:, 2])
        return trace, track

    # -- end -----------------------------------------------------------------------------------
    def _end_all(self) -> None:
        """Send every vehicle heard (and not landed) the end action; failures are named.

        Launches still running are cancelled first (they stop between two steps), so no vehicle
        takes off after its end action. With RTL the live vehicles first fly home through the guard
        (:meth:`_return_home`); the others, and any still away after ``guard.return_timeout_s``, are
        sent it at once (their return altitudes are layers apart).
        """
        action = self.config.flight.end_action
        self._stop.set()
        wait([job for v in self.vehicles for job in (v.job, v.guard_job) if job is not None])
        if self._refused:  # refused before any vehicle was armed: nothing to end
            return
        if action == "rtl":
            self._return_home()
        heard = [v for v in self.vehicles
                 if self._state(v) is not None and v.status not in ("landed", "ended")]
        for job in [self._pool.submit(self._end_one, v, action) for v in heard]:
            job.result()

    def _end_one(self, vehicle: _Vehicle, action: str) -> None:
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
            time.sleep(_TICK_S)
        wait([v.job for v in flying if v.job is not None])
        for vehicle in (v for v in flying if v.status == "ending"):  # its RTL failed: sent again below
            vehicle.status = "live"

    def _on_state(self, state: VehicleState) -> None:
        """Publish a vehicle's state as each position arrives (on the link's reader thread)."""
        from bridge.telemetry.schema import state_from_vehicle

        vehicle = self._by_sid.get(state.system_id)
        if (not self.outputs.live or vehicle is None or vehicle.status in ("waiting", *_SILENT)
                or state.position_time_s != state.updated_time_s):
            return
        payload = state_from_vehicle(state, vehicle.seq, uav_id=vehicle.uav_id, target_enu_m=vehicle.target_m)
        if payload is not None:
            vehicle.seq += 1
            try:
                self.outputs.state(payload)  # the token means "live": announced at launch
            except Exception as exc:  # a closing session must not break the reader thread
                logger.debug("vehicle %d: state not published: %s", state.system_id, exc)

    def summary(self) -> dict[str, Any]:
        """Per-vehicle outcome (status, launches, command failures), the events and the separation record."""
        return self.safety.summary() | {
            "vehicles": [{"system_id": v.system_id, "uav_id": v.uav_id, "status": v.status,
                          "launches": v.launches, "command_failures": v.command_failures}
                         for v in self.vehicles],
            "events": list(self.events),
        }
