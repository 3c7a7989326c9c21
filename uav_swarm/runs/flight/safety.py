"""The safety layer of a live flight: pre-flight checks, take-off turns, the guard and the separation record.

:class:`FlightSafety` is what :class:`uav_swarm.runs.flight.loop.Flight` asks before and while it flies:

- :meth:`FlightSafety.check_launch` (before any vehicle is armed): the take-off positions
  (:mod:`uav_swarm.runs.flight.launch_plan`) and, per vehicle, its link-loss failsafe, geofence and return
  altitude (:func:`bridge.flight.preflight.preflight`); a refusal names the vehicle and the field;
- :meth:`FlightSafety.check_relaunch`: the same for a vehicle taken back in flight (its home against
  the others' take-off positions);
- :meth:`FlightSafety.takeoff_gate`: its turn to arm and climb;
- :meth:`FlightSafety.decide` (``[guard] rate_hz`` times a second): the guard's decision for every
  airborne vehicle on its measured position and the time it was true (:mod:`uav_swarm.runs.flight.guard`),
  each new hold an event and recorded by reason (:class:`uav_swarm.runs.flight.holds.HoldRecord`,
  summed in the status lines and the end table, not logged one by one), each bound found broken (a
  stale position, a point not acknowledged, a vehicle outside its certified disc) an event
  ``guard_<kind>`` and counted, and the separation record
  (:class:`uav_swarm.world.separation.SeparationMonitor`, 3-D distances of the measured positions of the
  armed vehicles, and apart the closest pair in flight: both at least
  :data:`~uav_swarm.runs.flight.holds.AIRBORNE_M` above their homes, with the phase it was seen in);
- before arming, each vehicle's horizontal limits are read
  (:func:`bridge.flight.limits.read_horizontal_limits`) and the guard plans it with the smaller of
  those and ``[guard]``'s; one whose limits cannot be read is refused unless ``[guard] stated_limits``.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from bridge.flight.limits import read_horizontal_limits
from bridge.flight.params import ParamError
from bridge.flight.preflight import PreflightError, PreflightReport, preflight, warn_fences_off
from bridge.flight.vehicles import FleetError
from bridge.geo import geodetic_to_enu
from uav_swarm.runs.flight.guard import FlightGuard, GuardDecision
from uav_swarm.runs.flight.holds import AIRBORNE_M, HoldRecord, Reason
from uav_swarm.runs.flight.launch_plan import (
    TakeoffGate,
    check_launch_positions,
    grid_slots_m,
    return_altitudes_m,
)
from uav_swarm.runs.fly_config import FlyConfig
from uav_swarm.world.guard.failsafe import launch_spacing_m
from uav_swarm.world.separation import SeparationMonitor

if TYPE_CHECKING:
    from contextlib import AbstractContextManager

    from bridge.config import BridgeConfig
    from bridge.flight.fleet import Fleet
    from bridge.flight.vehicle_home import ReportedHome
    from bridge.link.vehicle_state import VehicleState

__all__ = ["FlightSafety"]

logger = logging.getLogger(__name__)

EventSink = Callable[[str, int, str], None]
"""``event(kind, system_id, detail)``: records a flight event."""


class FlightSafety:
    """Pre-flight checks, take-off turns, the guard and the separation record of one flight.

    Args:
        config: The flight's settings (``uav``, ``launch``, ``guard``, ``set_failsafe``).
        bridge: The bridge config (vehicles in order, our system id, home, protocol).
        fleet: The open fleet.
        cancel: Set when the flight ends.
        event: Records an event (kind, system id, detail).
    """

    def __init__(self, config: FlyConfig, bridge: BridgeConfig, fleet: Fleet, cancel: threading.Event,
                 event: EventSink) -> None:
        self.config = config
        self.bridge = bridge
        self.fleet = fleet
        self._event = event
        n = config.n_uavs or len(bridge.vehicles)
        ids = [v.system_id for v in bridge.vehicles[:n]]
        self._uav_of = {sid: k for k, sid in enumerate(ids)}
        self.cruise_alt_m = {sid: float(alt) for sid, alt in zip(ids, config.uav.altitudes_m(n), strict=True)}
        returns = return_altitudes_m(n, config.uav, config.guard.margin_m)
        self.return_alt_m = {sid: float(alt) for sid, alt in zip(ids, returns, strict=True)}
        self._slots = dict(zip(ids, grid_slots_m(config.launch, n), strict=True))
        self.homes_m: dict[int, tuple[float, float]] = {}
        self.reports: dict[int, PreflightReport] = {}
        layers = config.uav.altitudes_m(n) if config.uav.layer_step_m > 0 else None
        area = (config.task.scenario.width_m, config.task.scenario.height_m)
        self.guard = FlightGuard(config.guard, config.uav.min_separation_m, n, layers, area)
        self._seen_events = 0
        self.guard_events: dict[str, int] = {"position_stale": 0, "command_unacknowledged": 0,
                                             "outside_bounds": 0}
        self.monitor = SeparationMonitor(config.uav.min_separation_m)
        guard = config.guard
        self.launch_spacing_m = launch_spacing_m(config.uav.min_separation_m, margin_m=guard.margin_m,
                                                 tracking_error_m=guard.tracking_error_m,
                                                 position_error_m=guard.position_error_m)
        """Homes at least this far apart climb together; closer ones one at a time (the launch rule)."""
        self._gate = TakeoffGate(cancel, self._column_clear, self._near)
        self._airborne: dict[int, tuple[float, float]] = {}
        self._lock = threading.Lock()
        self.holds = HoldRecord()
        self.rtl_waits: dict[int, str] = {}
        """Why each live vehicle's RTL waits at the end (by system id), for the status line."""
        self.phase = "heartbeat"
        """The flight's phase (set by :class:`uav_swarm.runs.flight.status.FlightStatus`)."""
        self._closest_in_flight_phase: str | None = None

    # -- before arming --------------------------------------------------------------------------
    def home_m(self, reported: ReportedHome) -> tuple[float, float]:
        """A vehicle's home in the flight's East-North frame, metres."""
        home = reported.home
        x_m, y_m, _ = geodetic_to_enu(self.bridge.home, home.lat_deg, home.lon_deg, home.alt_m)
        return float(x_m), float(y_m)

    def check_launch(self, homes: Mapping[int, ReportedHome]) -> None:
        """Refuse take-off positions closer than the minimum, then check every vehicle's parameters.

        Raises:
            PreflightError: Positions too close (or off their grid slots), or a vehicle without a
                link-loss failsafe (without ``set_failsafe``); nothing was armed.
            ParamError: A parameter could not be read or set.
        """
        positions = {sid: self.home_m(reported) for sid, reported in homes.items()}
        check_launch_positions(positions, self.config.uav.min_separation_m, self.config.launch, self._slots,
                               self.launch_spacing_m)
        self._set_homes(positions)
        try:
            reports = self.fleet.each("pre-flight check", list(homes), self._check_parameters)
            warn_fences_off(list(reports.values()), self._fence_params(reports))
        except FleetError as exc:
            sid, error = min(exc.errors.items())
            if isinstance(error, PreflightError):
                raise error from None
            raise PreflightError(sid, f"pre-flight check failed ({type(error).__name__}: {error}); nothing "
                                      "was armed") from None

    def check_relaunch(self, system_id: int, reported: ReportedHome) -> None:
        """A vehicle taken back: its home against the others' take-off positions, then its parameters."""
        position = self.home_m(reported)
        others = {sid: home for sid, home in self.homes_m.items() if sid != system_id}
        check_launch_positions({**others, system_id: position}, self.config.uav.min_separation_m,
                               self.config.launch, self._slots, self.launch_spacing_m)
        self._set_homes({system_id: position})
        report = self._check_parameters(system_id)
        warn_fences_off([report], self._fence_params([system_id]))

    def _fence_params(self, system_ids: Iterable[int]) -> dict[int, str]:
        return {sid: self.fleet.conventions(sid).fence_param for sid in system_ids}

    def _set_homes(self, positions: Mapping[int, tuple[float, float]]) -> None:
        """The vehicles' homes, here and in the guard (where each one's RTL or failsafe lands it)."""
        self.homes_m.update(positions)
        for sid, position in positions.items():
            self.guard.homes_m[self._uav_of[sid]] = position

    def _check_parameters(self, system_id: int) -> PreflightReport:
        report = preflight(self.fleet.link(system_id), system_id, self.fleet.conventions(system_id),
                           gcs_system_id=self.bridge.source_system, rtl_alt_m=self.return_alt_m[system_id],
                           set_failsafe=self.config.set_failsafe, protocol=self.bridge.protocol)
        self.reports[system_id] = report
        if report.failsafe_set:
            self._event("failsafe_set", system_id, report.failsafe)
        self._read_limits(system_id)
        return report

    def _read_limits(self, system_id: int) -> None:
        """The vehicle's own horizontal limits into the guard; refused when unreadable and not stated."""
        guard = self.config.guard
        try:
            limits = read_horizontal_limits(self.fleet.link(system_id), system_id,
                                            self.fleet.conventions(system_id), self.bridge.protocol)
        except ParamError as exc:
            if not guard.stated_limits:
                raise PreflightError(system_id, f"its horizontal limits cannot be read ({exc}); state them "
                                                f"with [guard] stated_limits = true (accel_m_s2 = "
                                                f"{guard.accel_m_s2:g}) or fix the link; nothing was armed"
                                     ) from None
            self._event("guard_limits_stated", system_id, f"{exc}; flown with [guard] accel_m_s2 = "
                                                          f"{guard.accel_m_s2:g}")
            self.guard.set_limits(self._uav_of[system_id], None)
            return
        bounds = self.guard.set_limits(self._uav_of[system_id], limits)
        self._event("guard_limits", system_id, f"{limits.source}: {limits.speed_m_s:g} m/s, "
                                               f"{limits.accel_m_s2:g} m/s^2, {limits.jerk_m_s3:g} m/s^3; "
                                               f"planned with {bounds.accel_m_s2:g} m/s^2")

    # -- take-off -------------------------------------------------------------------------------
    def takeoff_gate(self, system_id: int) -> Callable[[], AbstractContextManager[None]]:
        """The vehicle's turn to arm, take off and climb (from a clear column)."""
        return self._gate.for_vehicle(system_id)

    def _near(self, system_id: int) -> list[int]:
        """The vehicles whose homes are closer to this one's than the launch spacing (they climb in turn)."""
        home = self.homes_m.get(system_id)
        if home is None:
            return []
        spacing_m = self.launch_spacing_m
        return [sid for sid, other in self.homes_m.items()
                if sid != system_id and np.hypot(other[0] - home[0], other[1] - home[1]) < spacing_m]

    @property
    def climbing(self) -> set[int]:
        """System ids arming, taking off or climbing now."""
        return set(self._gate.climbing)

    @property
    def climbs(self) -> list[tuple[int, float, float]]:
        """``(system_id, start, end)`` of each climb so far (monotonic seconds)."""
        return list(self._gate.climbs)

    def _column_clear(self, system_id: int) -> bool:
        """No airborne vehicle closer to its home than the launch spacing, and no climbing one.

        Homes that far apart always clear (a vehicle airborne over its own home leaves the next one's
        column clear); a vehicle waiting to climb is a disc the guard keeps the airborne ones off, by the
        minimum and the guard's margin between the two discs, farther than the launch spacing.
        """
        return not self.column_blockers(system_id)

    def column_blockers(self, system_id: int) -> list[tuple[int, float]]:
        """``(system_id, metres)`` of each airborne vehicle that keeps this one's column from clearing."""
        home = self.homes_m.get(system_id)
        if home is None:
            return []
        need_m = self.launch_spacing_m
        with self._lock:
            others = [(sid, p) for sid, p in self._airborne.items() if sid != system_id]
        gaps = [(sid, float(np.hypot(p[0] - home[0], p[1] - home[1]))) for sid, p in others]
        climbing = [(sid, float(np.hypot(self.homes_m[sid][0] - home[0], self.homes_m[sid][1] - home[1])))
                    for sid in self._near(system_id) if sid in self._gate.climbing]
        close = {sid: gap_m for sid, gap_m in gaps if gap_m < need_m}
        for sid, gap_m in climbing:  # a climbing neighbour named once, by the nearer of the two
            close[sid] = min(gap_m, close.get(sid, gap_m))
        return sorted(close.items())

    # -- in flight ------------------------------------------------------------------------------
    def decide(self, flying: Sequence[tuple[int, VehicleState, tuple[float, float] | None, bool]],
               clock_s: float, now_s: float, busy: Sequence[int] = (), returning: Sequence[int] = (),
               grounded: Sequence[int] = ()) -> list[tuple[int, GuardDecision]]:
        """The guard's decision for each vehicle in ``flying``, and one separation sample.

        Args:
            flying: ``(system_id, state, goal, steerable)`` of each vehicle with a position; ``goal``
                its planned (x, y) or None, ``steerable`` False while it climbs or lands.
            clock_s: The flight's clock (crowd time), for the separation record.
            now_s: Unix time (the clock of the positions' receipt times), seconds.
            busy: System ids whose previous guard command is still being sent.
            returning: System ids flying home under their autopilot (RTL).
            grounded: System ids known to be on the ground (disarmed): they leave the guard.
        """
        for sid in grounded:
            self.guard.forget(self._uav_of[sid])
        armed = [(sid, s) for sid, s, _, _ in flying if s.armed]
        with self._lock:
            self._airborne = {sid: (float(s.x_m or 0.0), float(s.y_m or 0.0)) for sid, s in armed}
        if armed:
            positions = np.array([(s.x_m, s.y_m, s.z_m) for _, s in armed], dtype=np.float64)
            airborne = [s.relative_alt_m is not None and s.relative_alt_m >= AIRBORNE_M for _, s in armed]
            before = self.monitor.closest_in_flight
            self.monitor.observe(clock_s, positions, [self._uav_of[sid] for sid, _ in armed], airborne)
            if self.monitor.closest_in_flight != before:
                self._closest_in_flight_phase = self.phase
        if not flying:
            self.holds.decided({}, now_s)
            return []
        measured = [(self._uav_of[sid], (float(s.x_m or 0.0), float(s.y_m or 0.0)),
                     (float(s.vx_m_s or 0.0), float(s.vy_m_s or 0.0)),
                     float(s.position_time_s or 0.0), goal, steer) for sid, s, goal, steer in flying]
        decisions = self.guard.decide(measured, now_s, [self._uav_of[sid] for sid in busy],
                                      [self._uav_of[sid] for sid in returning])
        self._report_events()
        reasons: dict[int, Reason | None] = {}
        for (sid, _, _, _), decision in zip(flying, decisions, strict=True):
            held = decision.state in ("held", "stale", "outside")
            reasons[sid] = (decision.state, self._sid_of(decision.blocker) if decision.blocker >= 0 else None
                            ) if held else None
        for sid in self.holds.decided(reasons, now_s):  # each new hold: an event, summed in the status lines
            self.monitor.count_holds(1)
            state, blocker = reasons[sid] or ("held", None)
            self._event("guard_hold", sid, f"{state} for vehicle {blocker}" if blocker is not None else state)
        return [(sid, decision) for (sid, _, _, _), decision in zip(flying, decisions, strict=True)]

    def uav_of(self, system_id: int) -> int:
        """The guard's row of a vehicle."""
        return self._uav_of[system_id]

    def _sid_of(self, row: int) -> int | None:
        return next((sid for sid, k in self._uav_of.items() if k == row), None)

    def _report_events(self) -> None:
        """Each bound the guard found broken since the last decision: an event, a warning and a count."""
        events = self.guard.fleet.events
        for _, row, kind in events[self._seen_events:]:
            sid = self._sid_of(row)
            self.guard_events[kind] = self.guard_events.get(kind, 0) + 1
            logger.warning("vehicle %s: %s (separation guard: outside its stated bounds)", sid, kind)
            self._event(f"guard_{kind}", sid if sid is not None else -1, kind)
        self._seen_events = len(events)

    def acknowledged(self, system_id: int, seq: int, now_s: float) -> None:
        """A guard point was acknowledged (Unix time)."""
        self.guard.acknowledged(self._uav_of[system_id], seq, now_s)

    def unacknowledged(self, system_id: int, seq: int, now_s: float) -> None:
        """A guard point got no acknowledgement within ``[guard] command_delay_s``."""
        self.guard.unacknowledged(self._uav_of[system_id], seq, now_s)
        self._report_events()

    def summary(self) -> dict[str, Any]:
        """The separation record, the launch positions and the pre-flight reports, for ``summary.json``."""
        separation = self.monitor.summary() | {"guard_events": dict(self.guard_events),
                                               "closest_in_flight_phase": self._closest_in_flight_phase}
        limits = {str(sid): self.guard.limits[k].to_dict() for sid, k in sorted(self._uav_of.items())
                  if k in self.guard.limits}
        return {"separation": separation, "guard_limits": limits,
                "launch_spacing_m": self.launch_spacing_m,
                "launch": {str(sid): {"x_m": round(x, 2), "y_m": round(y, 2),
                                      "return_alt_m": self.return_alt_m.get(sid)}
                           for sid, (x, y) in sorted(self.homes_m.items())},
                "preflight": [r.to_dict() for _, r in sorted(self.reports.items())]}
