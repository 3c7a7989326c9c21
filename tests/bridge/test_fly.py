"""``uav-swarm fly`` end to end: the planner flies test vehicles over real MAVLink sockets on loopback.

Every vehicle is a simulated :class:`ArduCopter` (pymavlink, its own socket, a point mass) and the
telemetry goes through a real Zenoh session to a subscriber connected over ``tcp/127.0.0.1``.
"""

from __future__ import annotations

import base64
import json
import logging
import threading
import time

import numpy as np
import pytest
from lossy_relay import free_tcp_port, free_udp_port
from peer_fleet import bridge_toml, close_all, swift
from pymavlink.dialects.v20 import common as mavlink

from bridge.config import ProtocolConfig
from bridge.errors import CommandRejectedError
from bridge.flight.guided import FlightConfig, FlightError, launch
from bridge.geo import Home
from bridge.link.mavlink import MavlinkLink
from bridge.link.vehicle_state import VehicleStateTracker
from bridge.simulated.ardupilot import AUTO, FAILSAFE_ON, GUIDED, LAND, RTL, ArduCopter
from bridge.simulated.fleet import launch_home
from bridge.simulated.peer import endpoint_pair
from bridge.telemetry import SwarmSubscriber
from bridge.telemetry.config import TelemetryConfig
from bridge.telemetry.schema import Plan, Presence, Qos, UavState
from uav_swarm.cli import main
from uav_swarm.runs.fly import fly
from uav_swarm.runs.fly_config import load_fly_config
from uav_swarm.world.radio_config import RadioConfig

FAST = {"handshake_timeout_s": 0.3, "item_timeout_s": 0.1, "max_retries": 3}
LINK_TIMEOUT_S = 2.0  # a healthy vehicle's heartbeats can stall for a second on a busy machine


def _vehicles(n: int, transports: tuple[str, ...] = ("udpin",),
              options: dict[int, dict] | None = None) -> tuple[list, list[str]]:
    """``n`` flying vehicles on loopback (``options`` by system id), and the ground station's URLs."""
    vehicles, urls = [], []
    for i in range(n):
        transport = transports[i % len(transports)]
        port = free_tcp_port() if transport == "tcp" else free_udp_port()
        vehicle_url, gcs_url = endpoint_pair(transport, port)
        chosen = (options or {}).get(i + 1, {})
        params = FAILSAFE_ON | swift("ardupilot", chosen.pop("speed_m_s", 12.0))  # failsafe set
        prepared = {"home": launch_home(i), "params": params}  # apart, as a real launch
        vehicles.append(ArduCopter(vehicle_url, i + 1, **(prepared | chosen)))
        urls.append(gcs_url)
    return vehicles, urls



def _free_endpoint() -> str:
    return f"tcp/127.0.0.1:{free_tcp_port()}"



def test_ten_vehicles_fly_with_one_lost_and_taken_back(tmp_path):
    """60 s of crowd time: every vehicle launched, one killed mid-flight and restarted, all sent RTL."""
    options = {1: {"prearm_s": 15.0}} | {i: {"speed_m_s": 25.0} for i in range(2, 11)}  # past the checks
    vehicles, urls = _vehicles(10, ("udpin", "udpout", "tcp"), options)
    endpoint = _free_endpoint()
    config = load_fly_config(None, {
        "bridge_config": str(bridge_toml(tmp_path / "bridge.toml", urls, FAST)),
        "duration_s": 68.0, "speedup": 4.0,
        "flight": {"link_timeout_s": LINK_TIMEOUT_S, "ready_timeout_s": 10.0, "arm_retry_s": 0.5},
        "telemetry": {"swarm": "flytest", "listen": [endpoint]}})
    received: list = []
    watch = TelemetryConfig(swarm="flytest", listen=(), connect=(endpoint,))
    killed, killed_tcp = 4, 3  # over udpin and over TCP (the ground station reconnects)
    outcome: dict = {}
    try:
        with SwarmSubscriber(watch, callback=received.append, presence=True):
            runner = threading.Thread(target=lambda: outcome.update(result=fly(config, tmp_path / "out")))
            runner.start()
            deadline = time.monotonic() + 60.0  # one take-off at a time
            while time.monotonic() < deadline and not any(
                    isinstance(m, Plan) and m.seq >= 3 for m in received):
                time.sleep(0.05)
            for sid in (killed, killed_tcp):
                vehicles[sid - 1].close()  # killed in flight
            time.sleep(2 * LINK_TIMEOUT_S)  # silent twice the link timeout: lost however slow the machine
            for sid in (killed, killed_tcp):
                vehicles[sid - 1] = ArduCopter(vehicles[sid - 1].url, sid, home=launch_home(sid - 1),
                                               params=FAILSAFE_ON | swift("ardupilot", 25.0))
            runner.join(timeout=300.0)  # bounded by the run itself (duration, ready and launch timeouts)
            assert not runner.is_alive()
            time.sleep(0.5)
        result = outcome["result"]
        summary = result.summary
        statuses = {v["system_id"]: v for v in summary["vehicles"]}
        assert all(v["status"] == "ended" for v in statuses.values())
        assert all(v["launches"] == (2 if sid in (killed, killed_tcp) else 1) for sid, v in statuses.items())
        kinds = [(e["event"], e.get("system_id")) for e in summary["events"]]
        for sid in (killed, killed_tcp):
            assert kinds.index(("lost", sid)) < kinds.index(("heard_again", sid)) < len(kinds) - 1
            assert ("live", sid) in kinds[kinds.index(("heard_again", sid)):]
        for vehicle in vehicles:  # every vehicle was told RTL and is returning or home
            assert vehicle.custom_mode == RTL
            assert GUIDED in vehicle.modes
        assert vehicles[0].commands.count(mavlink.MAV_CMD_COMPONENT_ARM_DISARM) >= 2  # refused, then armed

        states = [m for m in received if isinstance(m, UavState)]
        plans = [m for m in received if isinstance(m, Plan)]
        assert {s.uav_id for s in states} == set(range(10))
        assert all(s.source == "vehicle" and s.position_wgs84 is not None for s in states)
        assert any(s.target_enu_m is not None for s in states)
        sizes = [len(p.targets) for p in plans]
        assert 10 in sizes and 8 in sizes
        first_short = sizes.index(8)
        assert {killed - 1, killed_tcp - 1}.isdisjoint(plans[first_short].targets_by_uav())  # without them
        assert 10 in sizes[first_short:]  # and with them again once they were back
        targets = [t for p in plans for t in p.targets_by_uav().values()]
        assert all(-20.0 <= t[0] <= 300.0 and -20.0 <= t[1] <= 300.0 and t[2] == 10.0 for t in targets)
        presence = [m.alive for m in received if isinstance(m, Presence) and m.uav_id == killed - 1]
        assert False in presence and True in presence[presence.index(False):]  # token withdrawn, then back
        qos = [m for m in received if isinstance(m, Qos)]
        assert qos and all(0.0 <= q.qos_s2 <= q.qos_s1 <= 1.0 for q in qos)
        assert summary["mean_qos_s1"] > 0.0  # measured positions over the crowd
        service = summary["service"]  # the figures simulate reports, for the flight
        assert 0.0 < service["static_reference_qos"] <= 1.0 and service["flown_over_static"] is not None
        assert service["metres_per_uav_minute"] > 0.0 and service["target_jumps_per_replan"] >= 0.0
        out = tmp_path / "out"
        assert {"qos.png", "timeseries.csv", "track.csv", "summary.json"} <= {p.name for p in out.iterdir()}
        track = (out / "track.csv").read_text().splitlines()
        assert track[0].startswith("time_s,uav_id,system_id,status,x_m,y_m,z_m")
        assert any(",lost," in row for row in track)
    finally:
        close_all(vehicles)


def test_mission_mode_flies_each_target_in_auto_and_lands(tmp_path):
    vehicles, urls = _vehicles(2, ("udpin",), {i: {"speed_m_s": 25.0} for i in (1, 2)})
    config = tmp_path / "fly.toml"  # the paper's radio needs both vehicles (802.11: one serves the crowd)
    config.write_text('[task.radio]\npropagation = "paper"\n', encoding="utf-8")
    try:
        argv = ["fly", "--bridge-config", str(bridge_toml(tmp_path / "bridge.toml", urls, FAST)), "--out",
                str(tmp_path / "out"), "--mode", "mission", "--end", "land", "--duration-s", "8",
                "--speedup", "2", "--no-telemetry", "--config", str(config)]
        assert main(argv) == 0
        for vehicle in vehicles:
            assert vehicle.uploads >= 1 and AUTO in vehicle.modes and vehicle.custom_mode == LAND
            assert vehicle.mission[-1].command == mavlink.MAV_CMD_NAV_LOITER_UNLIM
            assert vehicle.mission[-1].z == 10.0  # the cruise altitude, no descent after take-off
    finally:
        close_all(vehicles)


def test_absent_vehicle_is_named_and_the_others_fly_until_stopped(tmp_path, caplog):
    """Vehicle 3 never answers, vehicle 2 is disarmed in flight (a pilot taking over), then a stop."""
    vehicles, urls = _vehicles(2, ("udpin",))
    urls.append(f"udpin:127.0.0.1:{free_udp_port()}")  # vehicle 3 never answers
    config = load_fly_config(None, {
        "bridge_config": str(bridge_toml(tmp_path / "bridge.toml", urls, FAST)), "duration_s": 600.0,
        "publish_telemetry": False, "flight": {"ready_timeout_s": 2.0, "end_action": "land"}})
    stop = threading.Event()
    caplog.set_level(logging.INFO)

    def said(start: str) -> bool:
        return any(r.getMessage().startswith(start) for r in list(caplog.records))

    def pilot_then_stop() -> None:  # once fly has both airborne: a pilot takes vehicle 2, then a Ctrl-C
        deadline = time.monotonic() + 120.0
        while time.monotonic() < deadline and not all(said(f"vehicle {sid}: airborne") for sid in (1, 2)):
            time.sleep(0.05)
        time.sleep(1.0)
        vehicles[1].armed = False
        while time.monotonic() < deadline and not said("vehicle 2 disarmed in flight"):
            time.sleep(0.05)
        stop.set()  # as Ctrl-C or SIGTERM would

    try:
        threading.Thread(target=pilot_then_stop, daemon=True).start()
        result = fly(config, tmp_path / "out", stop_event=stop)
        statuses = {v["system_id"]: v["status"] for v in result.summary["vehicles"]}
        assert statuses == {1: "ended", 2: "landed", 3: "not found"}
        outcomes = {v["system_id"]: v["outcome"] for v in result.summary["vehicles"]}
        assert outcomes == {1: "ended (LAND sent)", 2: "landed (disarmed in flight)",
                            3: "not launched (never heard)"}
        assert "vehicle 3 not found: no heartbeat" in caplog.text
        assert "vehicle 2 disarmed in flight" in caplog.text
        assert vehicles[0].custom_mode == LAND and not vehicles[1].armed
        assert vehicles[1].commands.count(mavlink.MAV_CMD_COMPONENT_ARM_DISARM) == 1  # never re-armed
        assert result.summary["duration_s"] < 600.0
    finally:
        close_all(vehicles)


def test_fly_says_what_it_waits_for_and_ends_with_outcomes_closest_pair_in_flight_and_qos(tmp_path, capsys,
                                                                                           caplog):
    """Vehicle 4 never answers, vehicle 2's pre-arm checks refuse it for a while: the status lines name each
    wait, in the flight's order; the end table says vehicle 4 was not launched, the closest pair in flight
    and the flown QoS against the static reference."""
    vehicles, urls = _vehicles(3, ("udpin",), {2: {"prearm_s": 16.0}})
    urls.append(f"udpin:127.0.0.1:{free_udp_port()}")  # vehicle 4 never answers
    config = tmp_path / "fly.toml"
    config.write_text("status_every_s = 0.5\n[flight]\narm_retry_s = 0.5\n", encoding="utf-8")
    caplog.set_level(logging.INFO)
    try:
        argv = ["fly", "--bridge-config", str(bridge_toml(tmp_path / "bridge.toml", urls, FAST)), "--out",
                str(tmp_path / "out"), "--config", str(config), "--planner", "expert", "--duration-s", "4",
                "--speedup", "2", "--no-telemetry", "--wait-ready-s", "4"]
        assert main(argv) == 0
    finally:
        close_all(vehicles)
    lines = [r.getMessage() for r in caplog.records if r.name == "uav_swarm.runs.flight.status"]

    def first(text: str) -> int:
        return next(i for i, line in enumerate(lines) if text in line)

    heartbeats = first("vehicle 4 not heard yet (its heartbeat)")
    assert lines[heartbeats].startswith("waiting for heartbeats (")
    arming = first("vehicle 2 arming (its column clear)")
    assert lines[arming].startswith("launching (")
    climbing = first("vehicle 2 climbing (")
    flying = first("crowd time")
    assert lines[flying].startswith("flying (")
    assert heartbeats < arming < climbing < flying
    assert not [r for r in caplog.records if r.getMessage().endswith("(separation guard)")]  # holds: summed
    out = capsys.readouterr().out
    assert "vehicle 4 (uav 3): not launched (never heard)" in out
    for sid in (1, 2, 3):
        assert f"vehicle {sid} (uav {sid - 1}): ended (RTL sent), 1 launch, " in out
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    separation, service = summary["separation"], summary["service"]
    assert [v["launched"] for v in summary["vehicles"]] == [True, True, True, False]
    assert separation["closest_in_flight_m"] >= separation["closest_m"]  # on the ground: their 10 m spacing
    assert f"closest pair in flight {separation['closest_in_flight_m']:.1f} m" in out
    assert (f"mean QoS S1 {service['flown_qos']:.3f} against {service['static_reference_qos']:.3f} for the "
            "static reference") in out
    assert sum(h["holds"] for v in summary["vehicles"] for h in v["holds"]) == separation["holds"]


def test_a_vehicle_far_from_the_configured_home_is_never_armed(tmp_path, caplog):
    far = Home(lat_deg=Home().lat_deg + 0.05)  # about 5.6 km North
    vehicles, urls = _vehicles(2, ("udpin",), {2: {"home": far}})
    config = load_fly_config(None, {
        "bridge_config": str(bridge_toml(tmp_path / "bridge.toml", urls, FAST)), "duration_s": 4.0,
        "speedup": 2.0, "publish_telemetry": False})
    try:
        result = fly(config, tmp_path / "out")
        statuses = {v["system_id"]: v["status"] for v in result.summary["vehicles"]}
        assert statuses == {1: "ended", 2: "failed"}
        second = result.summary["vehicles"][1]
        assert not second["launched"] and second["outcome"].startswith("not launched (HomeMismatchError: ")
        assert "HomeMismatchError" in caplog.text and "max_home_offset_m = 100" in caplog.text
        assert not vehicles[1].armed and mavlink.MAV_CMD_COMPONENT_ARM_DISARM not in vehicles[1].commands
    finally:
        close_all(vehicles)


def test_a_stop_during_the_launch_cancels_it_before_any_take_off(tmp_path):
    vehicles, urls = _vehicles(2, ("udpin",), {1: {"prearm_s": 60.0}, 2: {"prearm_s": 60.0}})
    config = load_fly_config(None, {
        "bridge_config": str(bridge_toml(tmp_path / "bridge.toml", urls, FAST)), "publish_telemetry": False,
        "flight": {"arm_retry_s": 0.2}})
    stop = threading.Event()
    try:
        threading.Timer(1.5, stop.set).start()
        started = time.monotonic()
        result = fly(config, tmp_path / "out", stop_event=stop)
        assert time.monotonic() - started < 10.0  # not the 60 s arming timeout
        time.sleep(0.5)
        for vehicle in vehicles:
            assert not vehicle.armed and vehicle.enu[2] == 0.0
            assert mavlink.MAV_CMD_NAV_TAKEOFF not in vehicle.commands
        assert "mean_qos_s1" not in result.summary or result.summary["duration_s"] < 1.0
    finally:
        close_all(vehicles)


def test_bad_configuration_exits_2_before_anything_is_sent(tmp_path, capsys):
    vehicles, urls = _vehicles(1)
    try:
        toml = bridge_toml(tmp_path / "bridge.toml", urls, FAST)
        toml.write_text(toml.read_text().replace("x_max_m = 300.0", "x_max_m = 50.0"))
        out = str(tmp_path / "out")
        assert main(["fly", "--bridge-config", str(toml), "--out", out, "--no-telemetry"]) == 2
        err = capsys.readouterr().err
        assert "the crowd area's corner" in err and "GeofenceError" not in err
        assert main(["fly", "--out", str(tmp_path / "out")]) == 2
        assert "no vehicles to fly" in capsys.readouterr().err
        assert main(["fly", "--bridge-config", str(toml), "--speedup", "0", "--no-telemetry"]) == 2
        assert "speedup" in capsys.readouterr().err
        assert main(["fly", "--bridge-config", str(toml), "--wait-ready-s", "0", "--no-telemetry"]) == 2
        assert "argument --wait-ready-s: 0 is out of range" in capsys.readouterr().err
        time.sleep(0.3)
        assert vehicles[0].commands == [] and not vehicles[0].armed
        assert not (tmp_path / "out").exists()
    finally:
        close_all(vehicles)


def _link_and_tracker(url: str) -> tuple[MavlinkLink, VehicleStateTracker]:
    link = MavlinkLink(url)
    tracker = VehicleStateTracker(Home())
    link.add_listener(tracker.update)
    return link, tracker


def test_launch_names_the_vehicle_when_arming_stays_refused():
    vehicles, urls = _vehicles(1, options={1: {"prearm_s": 60.0}})
    link, tracker = _link_and_tracker(urls[0])
    try:
        config = FlightConfig(arm_timeout_s=1.0, arm_retry_s=0.2, ready_timeout_s=5.0)
        with pytest.raises(FlightError, match=r"vehicle 1: arming refused for 1 s .*MAV_RESULT_FAILED"):
            launch(link, tracker, 1, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 10.0, config,
                   ProtocolConfig(**FAST))
        assert vehicles[0].commands.count(mavlink.MAV_CMD_COMPONENT_ARM_DISARM) >= 3
        assert not vehicles[0].armed
    finally:
        link.close()
        close_all(vehicles)


def test_launch_climbs_to_the_altitude_and_refused_commands_raise_by_name():
    vehicles, urls = _vehicles(1)
    link, tracker = _link_and_tracker(urls[0])
    try:
        protocol = ProtocolConfig(**FAST)
        launch(link, tracker, 1, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 12.0, FlightConfig(), protocol)
        state = tracker.state(1)
        assert state.armed and state.relative_alt_m >= 11.0 and vehicles[0].custom_mode == GUIDED
        assert vehicles[0].telemetry_period_s == pytest.approx(0.1)  # the position stream asked at 10 Hz
        from bridge.flight.guided import set_mode

        with pytest.raises(CommandRejectedError, match="vehicle 1 rejected MAV_CMD_DO_SET_MODE"):
            set_mode(link, 1, (99.0,), protocol)
    finally:
        link.close()
        close_all(vehicles)


def test_a_recorded_flight_reads_back_equal_to_its_track_and_qos(tmp_path, capsys, caplog):
    """``fly --record --live``: each vehicle's states, the QoS and the plans at crowd time, as the outputs
    say; the live view listens on loopback meanwhile."""
    from foxglove_readback import conform, decode
    from mcap.reader import make_reader

    vehicles, urls = _vehicles(2, ("udpin",), {i: {"speed_m_s": 25.0} for i in (1, 2)})
    path = tmp_path / "replay" / "flight.mcap"
    try:
        argv = ["fly", "--bridge-config", str(bridge_toml(tmp_path / "bridge.toml", urls, FAST)), "--out",
                str(tmp_path / "out"), "--duration-s", "4", "--speedup", "2", "--no-telemetry",
                "--record", str(path), "--live", "127.0.0.1:0"]
        caplog.set_level(logging.INFO, logger="uav_swarm.runs.outputs.recording")
        assert main(argv) == 0
    finally:
        close_all(vehicles)
    assert f"recorded the flight in {path}" in capsys.readouterr().out
    assert "live view on ws://127.0.0.1:" in caplog.text
    topics: dict[str, list] = {}
    schemas: dict[str, str] = {}
    with path.open("rb") as stream:
        for schema, channel, message in make_reader(stream).iter_messages(log_time_order=True):
            topics.setdefault(channel.topic, []).append((message.log_time, decode(schema, message.data)))
            schemas[channel.topic] = schema.name
    uavs = {f"/uav/{i}/state": "uav_swarm.UavState" for i in (0, 1)}
    uavs |= {f"/uav/{i}/location": "foxglove.LocationFix" for i in (0, 1)}
    assert schemas == {"/scene": "foxglove.SceneUpdate", "/pedestrians": "foxglove.PointCloud",
                       "/tf": "foxglove.FrameTransforms", "/plan": "uav_swarm.Plan",
                       "/plan/targets": "foxglove.PosesInFrame", "/qos": "uav_swarm.Qos", **uavs}
    series = [line.split(",") for line in (tmp_path / "out" / "timeseries.csv").read_text().split()[1:]]
    qos = topics["/qos"]
    assert len(qos) == len(series) == 8  # every record_every_s = 0.5 s of the 4 s flown
    for (log_ns, message), row in zip(qos, series, strict=True):
        assert log_ns / 1e9 == pytest.approx(float(row[1]), abs=0.005)
        assert message["qos_s1"] == pytest.approx(float(row[2]), abs=1e-6)
    track = [line.split(",") for line in (tmp_path / "out" / "track.csv").read_text().split()[1:]]
    for uav_id in (0, 1):
        rows = [row for row in track if row[1] == str(uav_id)]
        states = topics[f"/uav/{uav_id}/state"]
        assert len(states) == len(rows) > 0
        assert [ns / 1e9 for ns, _ in states] == pytest.approx([float(row[0]) for row in rows], abs=0.0005)
        assert all(s["uav_id"] == uav_id and s["source"] == "vehicle" for _, s in states)
    plans = topics["/plan"]
    assert plans and all(log_ns % 1_000_000_000 == 0 for log_ns, _ in plans)  # every replan_every_s = 1 s
    assert [ns for ns, _ in topics["/plan/targets"]] == [ns for ns, _ in plans]
    assert len(topics["/scene"]) == len(qos) + 1  # the area and obstacles first, then the swarm each record
    for topic, name in schemas.items():  # Foxglove's types as Foxglove publishes them
        if name.startswith("foxglove."):
            assert all(conform(message, name) == [] for _, message in topics[topic]), topic
    # the 802.11 radio (fly's default), as simulate records it: each UAV's channel and whom it serves
    usable = RadioConfig(propagation="802.11").ieee80211.usable_channels
    channel_of = {(ns, s["uav_id"]): s.get("wifi_channel") for u in (0, 1)
                  for ns, s in topics[f"/uav/{u}/state"]}
    assert set(channel_of.values()) <= set(usable)  # every state has its channel
    clouds = dict(topics["/pedestrians"])
    for ns, update in topics["/scene"][1:]:
        entities = {e["id"]: e for e in update["entities"]}
        assert entities["coverage"].get("cylinders", []) == []  # no disc under 802.11
        assert [f["name"] for f in clouds[ns]["fields"]] == ["x", "y", "z", "covered", "uav"]
        points = np.frombuffer(base64.b64decode(clouds[ns]["data"]), "<f4").reshape(-1, 5)
        uav = points[:, 4]
        assert ((uav >= 0) == (points[:, 3] == 1)).all()  # a covered user is served by a UAV, named
        labels = [t["text"] for t in entities["channels"]["texts"]]
        assert labels == [f"UAV {u}, ch {channel_of[(ns, u)]}, {int((uav == u).sum())} users" for u in (0, 1)]
        assert len(entities["service"].get("lines", [])) == len({int(u) for u in uav} - {-1})


def test_the_802_11_radio_judges_a_flight_at_the_vehicles_heights_on_planned_channels(tmp_path):
    vehicles, urls = _vehicles(2, ("udpin",), {i: {"speed_m_s": 25.0} for i in (1, 2)})
    config = tmp_path / "fly.toml"
    config.write_text('[task]\nstrategy = 2\n[task.radio]\npropagation = "802.11"\n', encoding="utf-8")
    try:
        argv = ["fly", "--bridge-config", str(bridge_toml(tmp_path / "bridge.toml", urls, FAST)), "--out",
                str(tmp_path / "out"), "--config", str(config), "--planner", "expert", "--duration-s", "6",
                "--speedup", "2", "--no-telemetry"]
        assert main(argv) == 0
        summary = json.loads((tmp_path / "out" / "summary.json").read_text())
        assert summary["association"].startswith("802.11")
        assert summary["expert"] == "802.11 expert (strategy 2, the 802.11 radio with admission on rate)"
        assert 0.0 <= summary["mean_qos_s2"] <= summary["mean_qos_s1"] <= 1.0
        assert summary["service"]["static_reference_qos"] is not None
        rows = (tmp_path / "out" / "track.csv").read_text().splitlines()
        channel = rows[0].split(",").index("wifi_channel")
        usable = RadioConfig(propagation="802.11").ieee80211.usable_channels
        channels = {row.split(",")[channel] for row in rows[1:]} - {""}  # empty: not flying under the planner
        assert channels and {int(c) for c in channels} <= set(usable)
    finally:
        close_all(vehicles)
