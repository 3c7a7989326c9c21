"""The live loop of ``uav-swarm fly``: launch, replan from measured positions, faults, the end.

:class:`Flight` runs the crowd world in real time (or ``speedup`` times faster) and, every
``replan_every_s`` of crowd time, plans from the vehicles' **measured** positions and sends each
live vehicle its new target while it flies (``MAV_CMD_DO_REPOSITION``, or a new mission flown in
AUTO), through the separation guard (:mod:`uav_swarm.runs.flight.safety`), which holds a vehicle
whose predicted track comes too close to another's. Every vehicle heard is first made ready (a
position fix and its home, each waited for on its own, :meth:`bridge.flight.fleet.Fleet.wait_ready`)
and checked (take-off positions, link-loss failsafe, return altitude) before any is armed; then
they take off together, each from a clear column (:mod:`bridge.flight.guided`); a vehicle silent for
``flight.link_timeout_s`` is lost and replanned around, and launched again when heard; a live
vehicle seen disarmed is left out. At the end every launch still running is cancelled and every
vehicle heard is sent RTL or LAND. States are published as each position arrives, plans and QoS as
they are made. :func:`uav_swarm.runs.fly.fly` opens the fleet and telemetry and writes the outputs.

The parts, one concept each: the vehicle table (:mod:`~uav_swarm.runs.flight.vehicles`), the
planning and guard step (:mod:`~uav_swarm.runs.flight.step`), the launch and the links
(:mod:`~uav_swarm.runs.flight.launch`), the end and the returns (:mod:`~uav_swarm.runs.flight.end`);
this module builds them and runs the loop, recording the QoS and the track.
"""

from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor
from typing import TYPE_CHECKING, Any

import msgspec
import numpy as np

from uav_swarm.planning.planner import Planner
from uav_swarm.runs.flight.end import FlightEnd
from uav_swarm.runs.flight.safety import FlightSafety
from uav_swarm.runs.flight.status import FlightStatus
from uav_swarm.runs.flight.vehicles import TICK_S, FlightVehicle
from uav_swarm.runs.fly_config import FlyConfig
from uav_swarm.runs.outputs.fanout import RunOutputs
from uav_swarm.runs.outputs.radio_report import sharing_pairs, telemetry_fields
from uav_swarm.runs.outputs.records import QosTrace
from uav_swarm.world.comms import Association
from uav_swarm.world.crowd import CrowdSim
from uav_swarm.world.scenario import random_scenario
from uav_swarm.world.wifi.channels import plan_channels

if TYPE_CHECKING:
    from bridge.config import BridgeConfig
    from bridge.flight.fleet import Fleet
    from uav_swarm.runs.steering import OperatorTargets

__all__ = ["Flight"]


class Flight(FlightEnd):
    """One live flight of the vehicles of ``bridge`` under the planner (see the module docstring).

    Args:
        config: The flight's settings.
        bridge: The bridge config (:func:`load_flight_bridge`).
        fleet: The open fleet of ``bridge``'s vehicles.
        outputs: The flight's sinks (:mod:`uav_swarm.runs.outputs.fanout`, states on arrival): each vehicle's
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
        self.vehicles = [FlightVehicle(v.system_id, uav_id) for uav_id, v in enumerate(bridge.vehicles[:n])]
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
        self._loop_end: tuple[float, float] | None = None
        rng = np.random.default_rng(config.seed)
        self.scenario = random_scenario(rng, config.task.scenario)
        self.crowd = CrowdSim(self.scenario, config.task.crowd, rng)
        self._association = Association(config.task.radio)
        self._channels: dict[int, int] = {}
        """Each vehicle's channel by id (802.11 radio), planned as the vehicles fly."""
        """The users' association over the flight (admission control keeps incumbents on their UAV)."""
        self.safety = FlightSafety(config, bridge, fleet, self._stop,
                                   lambda kind, sid, detail: self._event(kind, self._by_sid.get(sid), detail))
        self.flight_status = FlightStatus(self, config.status_every_s)
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
            # 802.11: each UAV's channel, airtime and stations; the users' median SINR, co-channel pairs
            wifi_uavs, wifi_qos = telemetry_fields(cov, pairs)
            qos = Qos(stamp_s=time.time(), seq=seq, source="vehicle", qos_s1=rows[-1][0], qos_s2=rows[-1][1],
                      mean_throughput_mbps=rows[-1][2], n_users=int(users.shape[0]), **wifi_qos)
            rows_ids = np.asarray(ids, np.int64)  # the association's rows are the live vehicles': their ids
            served_by = np.where(cov.association >= 0, rows_ids[np.maximum(cov.association, 0)], -1) \
                if len(ids) else np.full(len(cov.association), -1)
            self._record_step(qos, users, cov, seq, dict(zip(ids, wifi_uavs, strict=True)), served_by)
        for vehicle in self.vehicles:
            state = self._state(vehicle)
            if state is None or state.x_m is None:
                continue
            target = vehicle.target_m or (None, None, None)
            track.append({"time_s": self._clock_s, "uav_id": vehicle.uav_id, "system_id": vehicle.system_id,
                          "status": vehicle.status, "x_m": state.x_m, "y_m": state.y_m, "z_m": state.z_m,
                          "target_x_m": target[0], "target_y_m": target[1], "target_z_m": target[2],
                          "wifi_channel": self._channels.get(vehicle.uav_id)})

    def _record_step(self, qos: Any, users: np.ndarray, cov: Any, seq: int, wifi: dict[int, dict[str, Any]],
                     served_by: np.ndarray) -> None:
        """Record each heard vehicle's state (with or without a position fix), the scene and the QoS.

        ``wifi``: the 802.11 fields of each live vehicle's state by UAV id (its channel, airtime and
        stations; empty under the paper's radio); ``served_by``: each user's UAV id (-1: none). With them
        the recording and ROS 2 show each UAV's channel and whom it serves, as ``simulate``'s do.
        """
        from bridge.telemetry.schema import state_from_vehicle

        heard = [(v, self._state(v)) for v in self.vehicles]
        made = [state_from_vehicle(state, seq, uav_id=v.uav_id, target_enu_m=v.target_m)
                for v, state in heard if state is not None]
        states = [msgspec.structs.replace(s, **wifi.get(s.uav_id, {})) for s in made if s is not None]
        self.outputs.step(self._clock_s, states, qos, users, cov.covered, association=served_by,
                          throughput_mbps=cov.throughput_mbps)

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
        self.flight_status.enter("flight")
        self.outputs.static_scene(self.scenario.obstacles)
        steered = 0
        while step < n_steps and not self._stop.is_set():
            self._guard_if_due()
            self.flight_status.tick(lambda: f"crowd time {self._clock_s:.0f} s of {cfg.duration_s:g} s"
                                    + (f", QoS S1 {rows[-1][0]:.3f}" if rows else ""))
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
            self._stop.wait(min(TICK_S, max(0.0, wake_s - time.monotonic())))
        self._loop_end = (self._clock_s, time.monotonic())  # the return's events go on from here
        name = self._planner(max(1, len(ids) or len(self.vehicles))).name
        values = np.array(rows, dtype=np.float64).reshape(-1, 3)
        trace = QosTrace(planner_name=name, times_s=np.array(times), qos_s1=values[:, 0], qos_s2=values[:, 1],
                         throughput_mbps=values[:, 2])
        return trace, track
