"""``fly``'s status lines, paced by the flight's own loop; the guard's holds summed per vehicle and reason.

A real :class:`~uav_swarm.runs.flight.loop.Flight` over a fleet of loopback endpoints nobody answers (its
vehicles are never heard), its real take-off gate and separation record; only the clock the lines are paced
by is the test's, so the lines are judged by their content and order, not by how fast this machine is.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from concurrent.futures import Future

import numpy as np
import pytest

from bridge.config import BridgeConfig
from bridge.flight.fleet import Fleet
from bridge.flight.guided import FlightError
from bridge.link.vehicle_state import VehicleState
from bridge.simulated.fleet import fleet_bridge_config
from typed_config import load_toml
from uav_swarm.runs.flight.holds import HoldRecord, holds_text
from uav_swarm.runs.flight.loop import Flight
from uav_swarm.runs.flight.status import FlightStatus, end_report
from uav_swarm.runs.fly_config import load_fly_config
from uav_swarm.world.guard import Bounds


class Clock:
    """The clock the status lines are paced by, set by the test."""

    def __init__(self) -> None:
        self.now_s = 0.0

    def __call__(self) -> float:
        return self.now_s


@pytest.fixture
def flight(tmp_path) -> Iterator[Flight]:
    """A flight of three vehicles on loopback endpoints that nobody answers."""
    path = tmp_path / "bridge.toml"
    path.write_text(fleet_bridge_config(3), encoding="utf-8")
    config = load_fly_config(None, {"bridge_config": str(path), "publish_telemetry": False})
    bridge = load_toml(BridgeConfig, path)
    with Fleet(bridge) as fleet:
        flight = Flight(config, bridge, fleet, planner=None)
        yield flight
        flight.stop()


def test_a_line_is_due_every_period_of_the_loop_clock_and_names_what_each_vehicle_waits_for(flight):
    clock = Clock()
    status = FlightStatus(flight, 5.0, clock=clock)
    status.enter("heartbeat", limit_s=60.0)
    lines = []
    for t_s in range(13):  # the loop turns once a second
        clock.now_s = float(t_s)
        lines.append(status.tick())
    due = [(t_s, line) for t_s, line in enumerate(lines) if line is not None]
    assert [t_s for t_s, _ in due] == [5]  # at 10 s nothing changed: no second line
    assert due[0][1] == ("waiting for heartbeats (5 s of 60 s): vehicle 1 not heard yet (its heartbeat); "
                         "vehicle 2 not heard yet (its heartbeat); vehicle 3 not heard yet (its heartbeat); "
                         "3 waiting")
    clock.now_s = 40.0  # a loop starved for 28 s: one line when it turns again (30 s after the last)
    assert status.tick() is not None
    clock.now_s = 41.0
    assert status.tick() is None
    clock.now_s = 46.0
    assert status.tick() is None  # the same again, 6 s later: not said
    status.enter("ready", limit_s=60.0)  # something changed: said at the next period
    clock.now_s = 52.0
    assert status.tick().startswith("waiting until the vehicles are ready (")
    assert status.lines == [line for line in lines if line is not None] + status.lines[-2:]


def test_a_wait_of_the_main_thread_still_says_what_it_waits_for(flight):
    """A job the main thread waits for (the pre-flight checks): a line each period, naming the vehicles."""
    job: Future[None] = Future()
    calls = []

    def clock() -> float:  # each call one second later; the job is done at 12 s
        calls.append(None)
        if len(calls) >= 12 and not job.done():
            job.set_result(None)
        return float(len(calls))

    status = FlightStatus(flight, 5.0, clock=clock)
    status.enter("preflight")
    status.wait([(1, job), (2, job)], "its pre-flight check (parameters)")
    assert len(status.lines) == 1  # at 6 s of the clock; at 11 s nothing changed: no second line
    assert status.lines[0].startswith("pre-flight checks (")
    assert ("vehicle 1 its pre-flight check (parameters); vehicle 2 its pre-flight check (parameters); "
            "vehicle 3 not heard yet (its heartbeat)") in status.lines[0]


def test_the_take_off_gate_names_what_blocks_a_column(flight):
    status = flight.flight_status
    safety = flight.safety
    safety.homes_m.update({1: (0.0, 0.0), 2: (10.0, 0.0), 3: (20.0, 0.0)})
    for vehicle in flight.vehicles:
        vehicle.status = "launching"
    status.enter("launch")
    # vehicle 1 hovers 2 m from vehicle 2's home: vehicle 2's column is not clear, vehicle 3's (8 m) is
    hovering = VehicleState(system_id=1, armed=True, x_m=12.0, y_m=0.0, z_m=10.0, relative_alt_m=10.0,
                            lat_deg=0.0, lon_deg=0.0, position_time_s=time.time())
    safety.decide([(1, hovering, None, False)], 0.0, time.time())
    release = threading.Event()

    def take_off(sid: int) -> None:
        try:
            with status.gate(sid, safety.takeoff_gate(sid))():
                release.wait(30.0)
        except FlightError:
            pass  # cancelled when the flight ends

    threads = [threading.Thread(target=take_off, args=(sid,), daemon=True) for sid in (2, 3)]
    for thread in threads:
        thread.start()
    assert _eventually(lambda: "vehicle 3 arming" in status.line(time.monotonic()))
    line = status.line(time.monotonic())
    assert "vehicle 3 arming (its column clear)" in line
    spacing_m = flight.safety.launch_spacing_m  # 8 m: the launch spacing
    assert (f"vehicle 2 waits for its column to clear: vehicle 1 2.0 m from its home ({spacing_m:g} m "
            "needed, the launch spacing)" in line)
    release.set()
    flight.stop()
    for thread in threads:
        thread.join(5.0)


def _eventually(condition, timeout_s: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.02)
    return condition()


def test_holds_are_counted_and_timed_per_vehicle_and_reason():
    holds = HoldRecord()
    holds.decided({1: ("held", 2), 2: None}, now_s=0.0)
    holds.decided({1: ("held", 2), 2: None}, now_s=1.0)
    holds.decided({1: ("held", 3), 2: ("stale", None)}, now_s=2.0)  # another blocker: another hold
    holds.decided({1: None}, now_s=2.5)  # vehicle 2 left out (landed): its hold ends
    holds.decided({1: ("held", 2)}, now_s=4.0)
    totals = holds.totals(now_s=5.0)  # vehicle 1's last hold still open: counted up to now
    assert totals == {(1, ("held", 2)): (2, 3.0), (1, ("held", 3)): (1, 0.5), (2, ("stale", None)): (1, 0.5)}
    assert holds.holding(1) == (("held", 2), 4.0) and holds.holding(2) is None
    assert holds_text(holds.to_dict(now_s=5.0)[1]) == (
        "held 3 times, 3.5 s in all: for vehicle 2 2 times 3.0 s, for vehicle 3 once 0.5 s")


def test_the_end_report_names_a_vehicle_never_launched_and_the_closest_pair_in_flight():
    summary = {
        "vehicles": [
            {"system_id": 1, "uav_id": 0, "status": "ended", "launched": True, "outcome": "ended (RTL sent)",
             "launches": 1, "command_failures": 0,
             "holds": [{"reason": "held", "for_vehicle": 2, "holds": 4, "held_s": 12.5}]},
            {"system_id": 2, "uav_id": 1, "status": "ended", "launched": True, "outcome": "ended (RTL sent)",
             "launches": 1, "command_failures": 1, "holds": []},
            {"system_id": 3, "uav_id": 2, "status": "ended", "launched": False,
             "outcome": "not launched (the flight ended before its take-off: waits its turn to take off)",
             "launches": 1, "command_failures": 0, "holds": []}],
        "separation": {"min_separation_m": 5.0, "closest_m": 6.0, "closest_pair": [0, 1], "closest_t_s": 0.0,
                       "closest_in_flight_m": 8.31, "closest_in_flight_pair": [0, 1],
                       "closest_in_flight_t_s": 12.0, "closest_in_flight_phase": "flight", "conflicts": 0,
                       "time_below_min_s": 0.0, "holds": 4},
        "duration_s": 30.0, "planner": "expert", "mean_qos_s1": 0.5, "mean_qos_s2": 0.25,
        "mean_throughput_mbps": 2.0, "association": "paper",
        "service": {"flown_qos": 0.5, "static_reference_qos": 0.8, "flown_over_static": 0.625},
        "static_reference": {"strategy": 1}}
    assert end_report(summary) == [
        "vehicle 1 (uav 0): ended (RTL sent), 1 launch, 0 command failures; held 4 times, 12.5 s in all: "
        "for vehicle 2 4 times 12.5 s",
        "vehicle 2 (uav 1): ended (RTL sent), 1 launch, 1 command failure; not held",
        "vehicle 3 (uav 2): not launched (the flight ended before its take-off: waits its turn to take off)",
        "separation (minimum 5 m): closest pair in flight 8.3 m (vehicles 1 and 2 at 12.0 s), 0 conflicts, "
        "0.0 s below the minimum, 4 holds by the guard",
        "30 s flown with expert: mean QoS S1 0.500 against 0.800 for the static reference (62 % of it); "
        "S2 0.250, mean throughput 2.00 Mbps (paper)",
        "the static reference is the expert's placement of each instant's crowd judged as if the vehicles "
        "were already there: no flight, no guard"]


def test_a_cycle_of_holds_found_by_the_flight_guard_is_named_in_the_next_line(flight):
    """Two vehicles of the flight's own guard swap head on: they hold each other, and the line says so."""
    fleet = flight.safety.guard.fleet
    rows = {sid: flight.safety.uav_of(sid) for sid in (2, 3)}
    position = {rows[2]: np.array([0.0, 0.0]), rows[3]: np.array([30.0, 1.0])}
    goals = np.full((3, 2), np.nan)
    goals[rows[2]], goals[rows[3]] = (30.0, 0.0), (0.0, 0.0)
    for row, p in position.items():
        fleet.join(row, p, Bounds(accel_m_s2=2.5, command_delay_s=0.5), now_s=0.0, radius_m=0.0)
    status = FlightStatus(flight, 5.0, clock=Clock())
    now_s = 0.0
    while not fleet.deadlocks and now_s < 30.0:
        for row, decision in enumerate(fleet.decide(goals, now_s)):
            if decision.point_m is not None:
                fleet.acknowledged(row, decision.seq, now_s)
                position[row] = np.array(decision.point_m)
        now_s += 0.5
        for row, p in position.items():
            fleet.measure(row, p, np.zeros(2), now_s, now_s)
    _, cycle = fleet.deadlocks[0]
    sid_of = {row: sid for sid, row in rows.items()}
    ids = [sid_of[row] for row in cycle]
    line = status.line(time.monotonic())
    after_s = flight.config.guard.sidestep_after_s
    cycle_text = f"{ids[0]} -> {ids[1]} -> {ids[0]}"
    assert f"cycles of holds (each goes round after {after_s:g} s held): {cycle_text}" in line
    assert "cycles of holds" not in status.line(time.monotonic())  # said once
