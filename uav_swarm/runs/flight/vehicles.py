"""A live flight's vehicle table: each vehicle's record and status, and what the flight's parts share.

:class:`FlightVehicle` is one vehicle of ``uav-swarm fly`` with its status (waiting, launching, live,
not found, lost, landed, failed, ending, ended), its current target and its running jobs;
:class:`FlightVehicles` is the state the flight's parts (:mod:`~uav_swarm.runs.flight.step`,
:mod:`~uav_swarm.runs.flight.launch`, :mod:`~uav_swarm.runs.flight.end`, and
:class:`uav_swarm.runs.flight.loop.Flight`, which builds it) share: the table, the events, the
vehicles' measured states as they arrive and the per-vehicle summary.

>>> vehicle = FlightVehicle(system_id=3, uav_id=0)
>>> vehicle.status, vehicle.target_m, vehicle.launches
('waiting', None, 0)
>>> "lost" in SILENT
True
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from bridge.config import BridgeConfig
    from bridge.flight.fleet import Fleet
    from bridge.link.vehicle_state import VehicleState
    from uav_swarm.planning.planner import Planner
    from uav_swarm.runs.flight.safety import FlightSafety
    from uav_swarm.runs.fly_config import FlyConfig
    from uav_swarm.runs.outputs.fanout import RunOutputs
    from uav_swarm.runs.steering import OperatorTargets
    from uav_swarm.world.crowd import CrowdSim
    from uav_swarm.world.scenario import Scenario

__all__ = ["SILENT", "TICK_S", "FlightVehicle", "FlightVehicles", "outcome"]

logger = logging.getLogger(__name__)

TICK_S = 0.02  # longest sleep of the loop (wall clock)
SILENT = ("not found", "lost")  # never heard, or silent since: taken back when heard


@dataclass
class FlightVehicle:
    """A flight's vehicle; ``status``: waiting, launching, live, not found, lost, landed, failed, ended."""

    system_id: int
    uav_id: int
    status: str = "waiting"
    target_m: tuple[float, float, float] | None = None
    seq: int = 0
    in_auto: bool = False
    lost_at_s: float = 0.0
    job: Future[None] | None = None
    guard_job: Future[None] | None = None
    command_failures: int = 0
    launches: int = 0


class FlightVehicles:
    """The vehicle table and the state the flight's parts share.

    Every attribute is set by :class:`~uav_swarm.runs.flight.loop.Flight`, which builds the flight.
    """

    config: FlyConfig
    bridge: BridgeConfig
    fleet: Fleet
    outputs: RunOutputs
    steering: OperatorTargets | None
    vehicles: list[FlightVehicle]
    safety: FlightSafety
    flight_status: Any  # the flight's FlightStatus (uav_swarm.runs.flight.status, which imports this module)
    scenario: Scenario
    crowd: CrowdSim
    events: list[dict[str, Any]]
    plans: list[dict[int, tuple[float, float]]]
    crowd_samples: list[tuple[float, np.ndarray, np.ndarray]]
    _by_sid: dict[int, FlightVehicle]
    _stop: threading.Event
    _lock: threading.Lock
    _pool: ThreadPoolExecutor
    _planners: dict[int, Planner]
    _clock_s: float
    _loop_end: tuple[float, float] | None
    """The flight's clock and ``time.monotonic()`` when the loop ended (None while it runs)."""
    _refused: bool
    _next_guard_s: float

    def _event(self, kind: str, vehicle: FlightVehicle | None, detail: str = "") -> None:
        record = {"time_s": round(self._event_clock_s(), 3), "event": kind, "detail": detail}
        if vehicle is not None:
            record |= {"system_id": vehicle.system_id, "uav_id": vehicle.uav_id}
        with self._lock:
            self.events.append(record)

    def _event_clock_s(self) -> float:
        """The flight's clock; after the loop (the return), it goes on at the loop's pace (``speedup``)."""
        if self._loop_end is None:
            return self._clock_s
        clock_s, ended_s = self._loop_end
        return clock_s + (time.monotonic() - ended_s) * self.config.speedup

    def _state(self, vehicle: FlightVehicle) -> VehicleState | None:
        return self.fleet.tracker.state(vehicle.system_id)

    def _heard_within(self, vehicle: FlightVehicle, seconds: float) -> bool:
        state = self._state(vehicle)
        return (state is not None and state.heartbeat_time_s is not None
                and time.time() - state.heartbeat_time_s <= seconds)

    def _live(self) -> list[tuple[FlightVehicle, VehicleState]]:
        live = []
        for vehicle in self.vehicles:
            state = self._state(vehicle)
            if vehicle.status == "live" and state is not None and state.x_m is not None:
                live.append((vehicle, state))
        return live

    def _on_state(self, state: VehicleState) -> None:
        """Publish a vehicle's state as each position arrives (on the link's reader thread)."""
        from bridge.telemetry.schema import state_from_vehicle

        vehicle = self._by_sid.get(state.system_id)
        if (not self.outputs.live or vehicle is None or vehicle.status in ("waiting", *SILENT)
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
        """Per-vehicle outcome, the events and the separation record.

        Each vehicle: its status, whether it was launched (seen armed; else its outcome is "not
        launched", whatever it was sent at the end), its outcome in words, launches, command failures
        and the guard's holds by reason (:class:`uav_swarm.runs.flight.holds.HoldRecord`).
        """
        status = self.flight_status
        holds = self.safety.holds.to_dict(time.time())
        waits = status.waits_at_end or {}
        events, action = list(self.events), self.config.flight.end_action
        vehicles = []
        for v in self.vehicles:
            launched = v.system_id in status.launched
            vehicles.append({
                "system_id": v.system_id, "uav_id": v.uav_id, "status": v.status, "launched": launched,
                "outcome": outcome(v, launched, events, action, waits.get(v.system_id, "")),
                "launches": v.launches, "command_failures": v.command_failures,
                "holds": holds.get(v.system_id, [])})
        return self.safety.summary() | {"vehicles": vehicles, "events": events}


def outcome(vehicle: FlightVehicle, launched: bool, events: Sequence[Mapping[str, Any]], end_action: str,
            waited: str = "") -> str:
    """A vehicle's outcome in words: ``"not launched (...)"`` when it was never armed, else its status.

    >>> outcome(FlightVehicle(4, 3, status="not found"), False, [], "rtl")
    'not launched (never heard)'
    >>> outcome(FlightVehicle(1, 0, status="ended"), True, [], "rtl")
    'ended (RTL sent)'
    """
    sid = vehicle.system_id
    failed = [e["detail"] for e in events if e.get("system_id") == sid and e["event"] == "launch_failed"]
    if not launched:
        if vehicle.status == "not found":
            why = "never heard"
        elif failed:
            why = failed[-1]
        elif waited:
            why = f"the flight ended before its take-off: {waited}"
        else:
            why = "never armed"
        return f"not launched ({why})"
    if vehicle.status == "ended":
        return f"ended ({end_action.upper()} sent)"
    if vehicle.status == "landed":
        return "landed (disarmed in flight)"
    if vehicle.status == "failed" and failed:
        return f"failed ({failed[-1]})"
    if vehicle.status in ("lost", "not found"):
        return "lost (no heartbeat at the end)"
    return vehicle.status
