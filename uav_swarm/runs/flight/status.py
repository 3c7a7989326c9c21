"""What a live flight tells its user as it goes: status lines, the guard's holds per vehicle, the end report.

- :class:`FlightStatus`: while ``fly`` waits (for heartbeats, for each vehicle's position fix and home,
  for the pre-flight checks, in the take-off gate, for the returns home and the end action's answers)
  and while it flies, a status line every ``status_every_s`` (5 s by default) naming what it waits for,
  vehicle by vehicle; a line that would say nothing new (its clock aside) is left out, and said again
  only after 30 s. The lines are driven by the flight's own loop (each turn asks :meth:`~FlightStatus.tick`
  whether one is due), not by a timer thread a busy machine could starve: the main thread never
  blocks longer than one loop turn without asking.
- the separation guard's holds of each vehicle by reason (held for which vehicle, a stale position,
  found outside its disc; :class:`~uav_swarm.runs.flight.holds.HoldRecord`): how many and how long
  (wall-clock seconds). Each status line sums those of its period; ``summary.json`` and the end table
  hold the totals; each hold stays an event ``guard_hold`` of ``summary.json``.
- the cycles of holds the guard found (vehicles each held by the next; :mod:`uav_swarm.world.guard.deadlock`):
  ``cycles of holds (each goes round after 2 s held): 2 -> 3 -> 2``.
- :func:`end_report`: the lines ``fly`` prints at the end, from its ``summary.json``: each vehicle's
  outcome (a vehicle never armed is "not launched", never "ended") with its holds, the closest pair in
  flight (both vehicles airborne), and the flown QoS against the static reference.
"""

from __future__ import annotations

import contextlib
import logging
import math
import re
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import Future, wait
from typing import TYPE_CHECKING, Any

from uav_swarm.runs.flight.holds import Reason, holds_text, reason_text, short_text

if TYPE_CHECKING:
    from bridge.link.vehicle_state import VehicleState
    from uav_swarm.runs.flight.vehicles import FlightVehicle, FlightVehicles

__all__ = ["FlightStatus", "end_report"]

logger = logging.getLogger(__name__)

_TICK_S = 0.02  # the longest a wait of the main thread goes without asking for a line
_REPEAT_S = 30.0  # a line that says nothing new is said again only after this long (still waiting)
_ELAPSED = re.compile(r" \(\d+ s( of \d+ s)?\)")  # the clock of a line: "(5 s of 60 s)"


class FlightStatus:
    """The status lines of one flight (module docstring), asked for by its main thread.

    Args:
        flight: The flight's vehicle table (:class:`uav_swarm.runs.flight.loop.Flight`).
        every_s: Wall-clock seconds between two lines.
        clock: The wall clock the lines are paced by (``time.monotonic``).
    """

    def __init__(self, flight: FlightVehicles, every_s: float,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self._flight = flight
        self.every_s = float(every_s)
        self._clock = clock
        self.phase = "heartbeat"
        self._phase_start_s = clock()
        self._limit_s: float | None = None
        self._next_s = self._phase_start_s + self.every_s
        self._stage: dict[int, str] = {}
        self._last_holds: dict[tuple[int, Reason], tuple[int, float]] = {}
        self._seen_cycles = 0
        self._detail = ""
        self._said, self._said_s = "", -math.inf  # the last line without its clock, and when it was said
        self._pending: set[int] = set()
        self._pending_what = ""
        self.launched: set[int] = set()
        """System ids seen armed since their launch began: launched (the others are "not launched")."""
        self.waits_at_end: dict[int, str] | None = None
        """What each vehicle still waited for when the flight began to end (None before)."""
        self.lines: list[str] = []
        """Every status line, in order."""

    # -- phases and the clock -------------------------------------------------------------------
    def enter(self, phase: str, limit_s: float | None = None) -> None:
        """The flight enters ``phase`` (heartbeat, ready, preflight, launch, flight, return, end)."""
        if phase in ("return", "end") and self.waits_at_end is None:
            self.waits_at_end = {v.system_id: self._wait_of(v) for v in self._flight.vehicles}
        self.phase, self._limit_s, self._phase_start_s = phase, limit_s, self._clock()
        self._flight.safety.phase = phase

    def tick(self, detail: Callable[[], str] | None = None) -> str | None:
        """One turn of the main thread: note who is armed, and log a status line when one is due (the line).

        ``detail()`` adds what only the caller knows (the crowd time and QoS of the loop).
        """
        self._note_armed()
        now_s = self._clock()
        if now_s < self._next_s:
            return None
        self._next_s = now_s + self.every_s
        self._detail = detail() if detail is not None else ""
        line = self.line(now_s)
        said = _ELAPSED.sub("", line)
        if said == self._said and now_s < self._said_s + _REPEAT_S:
            return None  # nothing changed since the last line: no line, until _REPEAT_S have passed
        self._said, self._said_s = said, now_s
        self.lines.append(line)
        logger.info("%s", line)
        return line

    def wait(self, jobs: Sequence[tuple[int, Future[Any] | None]], what: str) -> None:
        """Wait on the main thread for the vehicles' jobs (``(system_id, job)``), a status line when due.

        The line names the vehicles whose jobs still run, waiting for ``what``.
        """
        pending = [(sid, job) for sid, job in jobs if job is not None and not job.done()]
        self._pending_what = what
        try:
            while pending:
                self._pending = {sid for sid, _ in pending}
                self.tick()
                wait([job for _, job in pending], timeout=_TICK_S)
                pending = [(sid, job) for sid, job in pending if not job.done()]
        finally:
            self._pending = set()

    def gate(self, system_id: int, gate: Callable[[], contextlib.AbstractContextManager[None]]
             ) -> Callable[[], contextlib.AbstractContextManager[None]]:
        """``gate`` (a vehicle's take-off gate) watched: its column to clear, then its take-off and climb."""
        @contextlib.contextmanager
        def watched() -> Iterator[None]:
            self._stage[system_id] = "column"
            try:
                with gate():
                    self._stage[system_id] = "take-off"
                    yield
            finally:
                self._stage.pop(system_id, None)
        return watched

    def _note_armed(self) -> None:
        for vehicle in self._flight.vehicles:
            if vehicle.system_id in self.launched or vehicle.status in ("waiting", "not found"):
                continue
            state = self._flight._state(vehicle)
            if state is not None and state.armed:
                self.launched.add(vehicle.system_id)

    # -- the line -------------------------------------------------------------------------------
    def line(self, now_s: float) -> str:
        """The status line now: the phase, what each vehicle waits for, the holds since the last line."""
        elapsed_s = now_s - self._phase_start_s
        of = f" of {self._limit_s:.0f} s" if self._limit_s is not None else ""
        heads = {"heartbeat": "waiting for heartbeats", "ready": "waiting until the vehicles are ready",
                 "preflight": "pre-flight checks", "launch": "launching", "flight": "flying",
                 "return": "returning home", "end": "ending"}
        head = f"{heads.get(self.phase, self.phase)} ({elapsed_s:.0f} s{of})"
        if self._detail:
            head += f", {self._detail}"
        waits = [f"vehicle {v.system_id} {w}" for v in self._flight.vehicles if (w := self._wait_of(v))]
        counts = self._counts()
        parts = [head + (": " + "; ".join(waits) if waits else "")]
        if counts:
            parts.append(counts)
        held = self._holds_since_last(time.time())
        if held:
            parts.append(f"held in the last {self.every_s:g} s: {held}")
        cycles = self._cycles_since_last()
        if cycles:
            parts.append(cycles)
        return "; ".join(parts)

    def _cycles_since_last(self) -> str:
        """The cycles of holds the guard found since the last line."""
        found = self._flight.safety.guard.fleet.deadlocks
        new, self._seen_cycles = found[self._seen_cycles:], len(found)
        if not new:
            return ""
        sid_of = {self._flight.safety.uav_of(v.system_id): v.system_id for v in self._flight.vehicles}
        texts = sorted({" -> ".join(str(sid_of.get(r, r)) for r in (*cycle, cycle[0])) for _, cycle in new})
        after_s = self._flight.config.guard.sidestep_after_s
        return f"cycles of holds (each goes round after {after_s:g} s held): {', '.join(texts)}"

    def _counts(self) -> str:
        by: dict[str, list[int]] = {}
        for vehicle in self._flight.vehicles:
            by.setdefault(vehicle.status, []).append(vehicle.system_id)
        order = ("live", "launching", "ending", "ended", "landed", "lost", "not found", "failed", "waiting")
        return ", ".join(f"{len(by[s])} {s}" for s in order if s in by)

    def _holds_since_last(self, now_s: float) -> str:
        """Each vehicle held since the last line: seconds held and for what (``vehicle 2 4.8 s (for 3)``)."""
        totals = self._flight.safety.holds.totals(now_s)
        by: dict[int, list[tuple[float, Reason]]] = {}
        for (sid, reason), (n, s) in totals.items():
            n0, s0 = self._last_holds.get((sid, reason), (0, 0.0))
            if n > n0 or s - s0 >= 0.05:
                by.setdefault(sid, []).append((s - s0, reason))
        self._last_holds = totals
        parts = []
        for sid, held in sorted(by.items()):
            reasons = [r for _, r in sorted(held, key=lambda h: -h[0])]
            blockers = [str(b) for state, b in reasons if state == "held" and b is not None]
            named = (["for " + ", ".join(blockers)] if blockers else []) + [
                short_text(r) for r in reasons if r[0] != "held"]
            parts.append(f"vehicle {sid} {sum(h for h, _ in held):.1f} s ({'; '.join(named) or 'held'})")
        return ", ".join(parts)

    def _wait_of(self, vehicle: FlightVehicle) -> str:
        """What one vehicle waits for now, in words ("" for nothing)."""
        flight = self._flight
        state = flight._state(vehicle)
        status = vehicle.status
        if vehicle.system_id in self._pending:
            if self.phase == "ready":
                return "its position fix and home" if state is None or not state.has_fix else "its home"
            return self._pending_what
        if status == "waiting":
            heard = flight._heard_within(vehicle, flight.config.flight.link_timeout_s)
            return "" if heard else "not heard yet (its heartbeat)"
        if status in ("not found", "lost"):
            return "not heard (its heartbeat)"
        if status == "launching":
            return self._launch_wait(vehicle, state)
        if status == "live" and self.phase == "return":
            return self._return_wait(vehicle, state)
        if status == "ending":
            return "the answer to its RTL"
        return ""

    def _launch_wait(self, vehicle: FlightVehicle, state: VehicleState | None) -> str:
        sid = vehicle.system_id
        stage = self._stage.get(sid)
        if stage == "take-off":
            if state is None or not state.armed:
                return "arming (its column clear)"
            alt_m = self._flight.safety.cruise_alt_m[sid]
            height = "?" if state.relative_alt_m is None else f"{state.relative_alt_m:.1f}"
            return f"climbing ({height} of {alt_m:g} m)"
        if stage == "column":
            return self._gate_wait(vehicle)
        if state is None or not state.has_fix:
            return "its position fix"
        return "its guided mode"

    def _gate_wait(self, vehicle: FlightVehicle) -> str:
        safety = self._flight.safety
        blockers = safety.column_blockers(vehicle.system_id)
        if not blockers:
            return "its column clear, about to take off"
        near = ", ".join(f"vehicle {s} {d:.1f} m" for s, d in blockers)
        return (f"waits for its column to clear: {near} from its home ({safety.launch_spacing_m:g} m needed, "
                "the launch spacing)")

    def _return_wait(self, vehicle: FlightVehicle, state: VehicleState | None) -> str:
        home = self._flight.safety.homes_m.get(vehicle.system_id)
        if home is None or state is None or state.x_m is None or state.y_m is None:
            return "returning home (no position)"
        away = f"{math.hypot(state.x_m - home[0], state.y_m - home[1]):.1f} m from home"
        hold = self._flight.safety.holds.holding(vehicle.system_id)
        waits = self._flight.safety.rtl_waits.get(vehicle.system_id)
        if hold is None:
            return away if waits is None else f"{away}, {waits}"
        (state_held, blocker), since_s = hold
        text = reason_text((state_held, blocker))
        other = self._flight._by_sid.get(blocker) if blocker is not None else None
        if other is not None and other.status in ("ending", "ended"):
            text += " (landing in RTL)"
        held_s = time.time() - since_s
        return f"{away}, {text}" + (f" for {held_s:.0f} s" if held_s >= 1.0 else "")


# -- the end report ---------------------------------------------------------------------------------
def end_report(summary: Mapping[str, Any]) -> list[str]:
    """The lines ``fly`` prints at the end, from its ``summary.json``.

    Each vehicle's outcome, launches, command failures and holds; the separation (the closest pair in
    flight, conflicts, time below the minimum, holds); the flown QoS against the static reference.
    """
    lines = []
    sid_of = {v["uav_id"]: v["system_id"] for v in summary["vehicles"]}
    for v in summary["vehicles"]:
        line = f"vehicle {v['system_id']} (uav {v['uav_id']}): {v.get('outcome', v['status'])}"
        if v.get("launched", True):
            line += (f", {v['launches']} launch{'es' if v['launches'] != 1 else ''}, "
                     f"{v['command_failures']} command failure{'s' if v['command_failures'] != 1 else ''}; "
                     f"{holds_text(v.get('holds', []))}")
        lines.append(line)
    sep = summary.get("separation")
    if sep is not None:
        if sep.get("closest_in_flight_m") is None:
            closest = "no two vehicles in flight at once"
        else:
            first, second = (sid_of.get(u, u) for u in sep["closest_in_flight_pair"])
            when = {"launch": "during the launch", "return": "during the return", "end": "at the end"}.get(
                sep.get("closest_in_flight_phase", ""), f"at {sep['closest_in_flight_t_s']:.1f} s")
            closest = (f"closest pair in flight {sep['closest_in_flight_m']:.1f} m (vehicles {first} and "
                       f"{second} {when})")
        lines.append(f"separation (minimum {sep['min_separation_m']:g} m): {closest}, {sep['conflicts']} "
                     f"conflict{'s' if sep['conflicts'] != 1 else ''}, {sep['time_below_min_s']:.1f} s below "
                     f"the minimum, {sep['holds']} hold{'s' if sep['holds'] != 1 else ''} by the guard")
    if "mean_qos_s1" in summary:
        service = summary.get("service", {})
        strategy = summary.get("static_reference", {}).get("strategy", 1)
        other = 2 if strategy == 1 else 1
        flown = service.get("flown_qos", summary[f"mean_qos_s{strategy}"])
        static, ratio = service.get("static_reference_qos"), service.get("flown_over_static")
        qos = f"mean QoS S{strategy} {flown:.3f}"
        if static is not None:
            qos += f" against {static:.3f} for the static reference"
            qos += f" ({100 * ratio:.0f} % of it)" if ratio is not None else ""
        lines.append(f"{summary['duration_s']:.0f} s flown with {summary['planner']}: {qos}; S{other} "
                     f"{summary[f'mean_qos_s{other}']:.3f}, mean throughput "
                     f"{summary['mean_throughput_mbps']:.2f} Mbps ({summary['association']})")
        if static is not None:
            lines.append("the static reference is the expert's placement of each instant's crowd judged as "
                         "if the vehicles were already there: no flight, no guard")
    return lines
