"""``simulate --ros2``: a real rclpy node in another process sees the run and steers it, on loopback only.

The peer (``tests/ros2_peer.py``) and the run are separate processes in a ROS domain of their own; the
first test runs both under strace and checks every address they sent to.
"""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys
import time
from pathlib import Path

import pytest
import rclpy  # noqa: F401  (the ros2 extra: the test command installs it; missing, the tests fail)
from mcap.reader import make_reader
from ports import free_tcp_port
from ros2_run import domain_id, ros_env, start_peer
from traffic import destinations, off_loopback, strace_prefix

from bridge.telemetry import SwarmSubscriber
from bridge.telemetry.config import TelemetryConfig
from bridge.telemetry.schema import Plan, Qos, UavState

DT_NS = 100_000_000  # the crowd's 0.1 s step
SMALL = """
planner = "expert"
compare_expert = false
static_reference = false
gif = false
[task]
warmup_min_s = 1.0
warmup_max_s = 2.0
[task.scenario]
n_groups_min = 2
n_groups_max = 3
group_size_min = 35
group_size_max = 45
[task.radio]
propagation = "paper"  # the markers' coverage discs are the paper's radio's (simulate's default: 802.11)
"""


def _config(path: Path, swarm: str, endpoint: str, **top) -> Path:
    lines = [f"{k} = {json.dumps(v)}" for k, v in top.items()]
    path.write_text("\n".join(lines) + SMALL + f'[telemetry]\nswarm = "{swarm}"\nlisten = ["{endpoint}"]\n'
                    '[ros2]\nspeed = 4.0\nwait_for_subscriber_s = 120.0\n')
    return path


def _simulate(config: Path, out: Path, env: dict[str, str], trace: Path | None = None, *extra: str
              ) -> subprocess.CompletedProcess:
    command = [sys.executable, "-m", "uav_swarm", "simulate", "--config", str(config), "--out", str(out),
               "--ros2", "--quiet", *extra]
    return subprocess.run((strace_prefix(trace) if trace else []) + command, env=env, capture_output=True,
                          text=True, timeout=600)


def _mcap_json(path: Path, topic: str) -> list[dict]:
    with path.open("rb") as f:
        return [json.loads(m.data) for _, c, m in make_reader(f).iter_messages() if c.topic == topic]


def test_a_ros2_peer_sees_every_pose_plan_and_qos_of_simulate_and_nothing_leaves_loopback(tmp_path):
    n_uavs, duration_s = 3, 4.0
    n_steps = round(duration_s / 0.1)
    domain, endpoint = domain_id(), f"tcp/127.0.0.1:{free_tcp_port()}"
    config = _config(tmp_path / "sim.toml", "rostest", endpoint, n_uavs=n_uavs, duration_s=duration_s,
                     replan_every=10, wait_for_subscriber_s=120.0)
    env = ros_env(domain)
    peer = start_peer({"namespace": "/uav_swarm/rostest", "n_uavs": n_uavs, "late_after_poses": 10,
                       "timeout_s": 300.0}, tmp_path / "peer.json", env, tmp_path / "peer.strace")
    zenoh: list = []
    watch = TelemetryConfig(swarm="rostest", listen=(), connect=(endpoint,))
    try:
        with SwarmSubscriber(watch, callback=zenoh.append):
            run = _simulate(config, tmp_path / "out", env, tmp_path / "run.strace", "--record",
                            str(tmp_path / "out" / "run.mcap"))
        assert run.returncode == 0, run.stderr[-3000:]
        assert peer.wait(timeout=300) == 0
    finally:
        peer.kill()
    got = json.loads((tmp_path / "peer.json").read_text())

    # every UAV's pose at every published step (10 Hz of simulated time), in map, no gap
    states = {(s.uav_id, s.seq): s for s in zenoh if isinstance(s, UavState)}
    for uav_id in range(n_uavs):
        poses = got["poses"][str(uav_id)]
        assert [p[0] for p in poses] == [(k + 1) * DT_NS for k in range(n_steps)], uav_id
        assert {p[1] for p in poses} == {"map"}
        for k, (_, _, x, y, z) in enumerate(poses):  # the very numbers Zenoh carried
            assert (x, y, z) == states[uav_id, k].position_enu_m
    assert got["clock"] == sorted(got["clock"]) and got["clock"][-1] == n_steps * DT_NS
    # the swarm in one message a step: pose i is UAV i's, the same as its own topic's
    assert [stamp_ns for stamp_ns, _, _ in got["swarm"]] == [(k + 1) * DT_NS for k in range(n_steps)]
    for k, (_, frame, positions) in enumerate(got["swarm"]):
        assert frame == "map" and positions == [got["poses"][str(i)][k][2:] for i in range(n_uavs)]

    # the plans: over ROS 2, Zenoh and in the recording, the same targets
    zenoh_plans = {p.seq: p for p in zenoh if isinstance(p, Plan)}
    recorded_plans = {p["seq"]: p for p in _mcap_json(tmp_path / "out" / "run.mcap", "/plan")}
    assert len(got["plans"]) == len(got["plan_info"]) == n_steps // 10
    assert len(zenoh_plans) == len(recorded_plans) == n_steps // 10
    for (stamp_ns, frame, poses), info in zip(got["plans"], got["plan_info"], strict=True):
        seq = int(info["values"]["seq"])
        assert frame == "map" and stamp_ns == info["stamp_ns"] == seq * 10 * DT_NS
        assert info["values"]["uav_ids"] == ",".join(map(str, range(n_uavs)))
        assert [tuple(p) for p in poses] == [t.target_enu_m for t in zenoh_plans[seq].targets]
        assert [tuple(p) for p in poses] == [tuple(t["target_enu_m"]) for t in recorded_plans[seq]["targets"]]
        assert float(info["values"]["latency_ms"]) == zenoh_plans[seq].latency_ms

    # the QoS: equal to Zenoh's and to the run's timeseries.csv
    zenoh_qos = {q.seq: q for q in zenoh if isinstance(q, Qos)}
    with (tmp_path / "out" / "timeseries.csv").open() as f:
        rows = {round(float(r["time_s"]) * 10): r for r in csv.DictReader(f)}
    assert len(got["qos"]) == n_steps
    for status in got["qos"]:
        values, seq = status["values"], int(status["values"]["seq"])
        assert status["stamp_ns"] == (seq + 1) * DT_NS
        for key in ("qos_s1", "qos_s2", "mean_throughput_mbps"):
            assert float(values[key]) == getattr(zenoh_qos[seq], key)
            assert float(values[key]) == pytest.approx(float(rows[seq + 1][key]), abs=1e-6)
        assert values["association"] == "paper (no admission control)"

    # the radio per UAV only (one status each): its users add up to the served ones, their rates to the mean's
    assert got["radio"], "no radio message arrived"
    qos_by_stamp = {status["stamp_ns"]: status["values"] for status in got["qos"]}
    for radio in got["radio"]:
        assert [s["name"] for s in radio] == [f"uav_{i}/radio" for i in range(n_uavs)]
        figures = qos_by_stamp[radio[0]["stamp_ns"]]
        n_users = int(figures["n_users"])
        assert sum(int(s["values"]["users"]) for s in radio) == round(float(figures["qos_s1"]) * n_users)
        assert sum(float(s["values"]["throughput_mbps"]) for s in radio) == pytest.approx(
            float(figures["mean_throughput_mbps"]) * n_users)

    # the crowd: one point per user, served exactly where the QoS says (S1 is the served share)
    assert got["crowd"], "no PointCloud2 arrived"
    qos_at = {status["stamp_ns"]: status["values"] for status in got["qos"]}
    for cloud in got["crowd"]:
        n_users = int(qos_at[cloud["stamp_ns"]]["n_users"])
        assert cloud["frame_id"] == "map" and cloud["width"] == n_users and cloud["point_step"] == 16
        assert cloud["fields"] == [["x", 0, 7], ["y", 4, 7], ["z", 8, 7], ["served", 12, 7]]  # FLOAT32
        assert cloud["n_bytes"] == 16 * n_users and cloud["z"] == [0.0] and set(cloud["served"]) <= {0.0, 1.0}
        assert sum(cloud["served"]) / n_users == pytest.approx(float(qos_at[cloud["stamp_ns"]]["qos_s1"]))

    # markers are valid messages: a DELETEALL, then three per UAV
    assert got["markers"], "no MarkerArray arrived"
    for markers in got["markers"]:
        assert markers[0]["action"] == 3 and all(m["action"] == 0 for m in markers[1:])
        by_ns: dict[str, list] = {}
        for m in markers[1:]:
            by_ns.setdefault(m["ns"], []).append(m)
            assert m["frame_id"] == "map" and 0.0 < m["color"][3] <= 1.0
            assert math.isclose(sum(q * q for q in m["orientation"]), 1.0)
            assert all(s > 0 for s in m["scale"][:2])
        assert [len(by_ns[ns]) for ns in ("uavs", "coverage", "separation")] == [n_uavs] * 3
        assert {m["scale"][0] for m in by_ns["coverage"]} == {60.0}  # 2 x the 30 m coverage radius
        assert {m["scale"][0] for m in by_ns["separation"]} == {5.0}  # uav.min_separation_m
        assert {m["type"] for m in by_ns["coverage"] + by_ns["separation"]} == {3}  # CYLINDER

    # a subscriber that joined after the scene was published still got it (transient local)
    for scene in (got["scene"], got["late_scene"]):
        assert len(scene) == 1
        area = next(m for m in scene[0] if m["ns"] == "area")
        corners = [[0, 0], [200, 0], [200, 200], [0, 200], [0, 0]]
        assert area["type"] == 4 and [p[:2] for p in area["points"]] == corners

    # no socket of the run or of the peer sent anything off 127.0.0.1
    for trace in (tmp_path / "run.strace", tmp_path / "peer.strace"):
        addresses, calls = destinations(trace)
        assert calls > 0 and addresses <= {"127.0.0.1", "::1"}, (trace.name, addresses)
        assert off_loopback(trace) == [], trace.name  # no DNS query either


def test_a_ros2_peer_steers_two_uavs_of_simulate_and_bad_targets_are_refused(tmp_path):
    n_uavs = 4
    domain, endpoint = domain_id(), f"tcp/127.0.0.1:{free_tcp_port()}"
    config = _config(tmp_path / "sim.toml", "steer", endpoint, n_uavs=n_uavs, duration_s=40.0,
                     replan_every=10, publish_telemetry=False)
    env = ros_env(domain)
    targets = {0: (30.0, 30.0, 10.0), 1: (170.0, 170.0, 10.0)}
    actions = [{"kind": "target", "uav": 0, "xyz": targets[0]},
               {"kind": "target", "uav": 1, "xyz": targets[1]},
               {"kind": "target", "uav": 2, "xyz": (5000.0, 50.0, 10.0)},  # outside the geofence
               {"kind": "target", "uav": 3, "xyz": (31.0, 32.0, 10.0)},  # 2.2 m from UAV 0's target
               {"kind": "target", "uav": 2, "xyz": (30.0, 30.0, 10.0), "frame_id": "base_link"},
               {"kind": "target", "uav": 2, "xyz": (100.0, 180.0, 10.0)},
               {"kind": "release", "uav": 2}, {"kind": "release", "uav": 3}]
    peer = start_peer({"namespace": "/uav_swarm/steer", "n_uavs": n_uavs, "actions": actions,
                       "timeout_s": 300.0}, tmp_path / "peer.json", env)
    try:
        run = _simulate(config, tmp_path / "out", env)
        assert run.returncode == 0, run.stderr[-3000:]
        assert peer.wait(timeout=300) == 0
    finally:
        peer.kill()
    got = json.loads((tmp_path / "peer.json").read_text())
    statuses = [(s["values"]["uav_id"], s["level"], s["message"]) for s in got["statuses"]]
    assert [(uav, level) for uav, level, _ in statuses] == [("0", 0), ("1", 0), ("2", 2), ("3", 2), ("2", 2),
                                                            ("2", 0), ("2", 0)], statuses
    assert "geofence" in statuses[2][2] and "x_m = 5000.00" in statuses[2][2]
    assert "uav.min_separation_m = 5 m" in statuses[3][2] and "UAV 0" in statuses[3][2]
    assert "frame_id = 'base_link'" in statuses[4][2]
    assert statuses[6][2] == "released"
    assert got["releases"] == [{"uav": 2, "success": True, "message": "back to the planner"},
                               {"uav": 3, "success": False, "message": "no operator target was held"}]
    last_plan = got["plans"][-1][2]
    for uav_id, target in targets.items():  # flown to the operator's target, which the plan shows
        x, y = got["poses"][str(uav_id)][-1][2:4]
        assert math.hypot(x - target[0], y - target[1]) <= 2.0, (uav_id, x, y)
        assert tuple(last_plan[uav_id]) == target and tuple(got["targets"][str(uav_id)][-1][2:]) == target
    for uav_id in (2, 3):  # the planner's: never the refused targets, and released back to the plan
        assert tuple(got["targets"][str(uav_id)][-1][2:]) == tuple(last_plan[uav_id])
        flown = got["targets"][str(uav_id)]
        assert all(math.hypot(t[2] - 31.0, t[3] - 32.0) > 0.5 and t[2] < 1000 for t in flown)


def test_the_strace_reading_sees_multicast_and_other_hosts(tmp_path):
    trace = tmp_path / "trace"
    trace.write_text(
        '7 sendmsg(12, {msg_name={sa_family=AF_INET, sin_port=htons(7400), '
        'sin_addr=inet_addr("239.255.0.1")}}, 0) = 60\n'
        '7 connect(5, {sa_family=AF_INET6, sin6_port=htons(80), '
        'inet_pton(AF_INET6, "2001:db8::1", &sin6_addr)}, 28) = 0\n'
        '7 sendto(4, "x", 1, 0, {sa_family=AF_INET, sin_port=htons(9), '
        'sin_addr=inet_addr("127.0.0.1")}, 16) = 1\n'
        '7 bind(3, {sa_family=AF_INET, sin_port=htons(0), sin_addr=inet_addr("192.0.2.2")}, 16) = 0\n')
    assert destinations(trace) == ({"239.255.0.1", "2001:db8::1", "127.0.0.1"}, 3)


def test_telemetry_ros2_republishes_a_swarm_flown_elsewhere(tmp_path):
    from bridge.telemetry import SwarmPublisher
    from bridge.telemetry.schema import PlanTarget

    domain, endpoint = domain_id(), f"tcp/127.0.0.1:{free_tcp_port()}"
    env = ros_env(domain)
    peer = start_peer({"namespace": "/uav_swarm/elsewhere", "n_uavs": 2, "timeout_s": 300.0},
                      tmp_path / "peer.json", env)
    sent: dict[int, tuple] = {}  # by stamp, nanoseconds
    try:
        with SwarmPublisher(TelemetryConfig(swarm="elsewhere", listen=(endpoint,))) as publisher:
            republisher = subprocess.Popen(
                [sys.executable, "-m", "uav_swarm", "telemetry", "ros2", "--swarm", "elsewhere", "--connect",
                 endpoint, "--n-uavs", "2", "--count", "300",
                 "--wait-for-subscriber-s", "120"], env=env, stderr=subprocess.PIPE, text=True)
            seq = 0
            while republisher.poll() is None:  # until it has republished its 300 messages
                stamp_s = 1_700_000_000.0 + seq * 0.25
                position = (float(seq), 2.0 * seq, 10.0)
                sent[round(stamp_s * 1e9)] = position
                publisher.publish_state(UavState(stamp_s=stamp_s, seq=seq, source="vehicle", uav_id=seq % 2,
                                                 position_enu_m=position, velocity_enu_m_s=(1.0, 0.0, 0.0),
                                                 target_enu_m=(50.0, 60.0, 10.0)))
                publisher.publish_plan(Plan(stamp_s=stamp_s, seq=seq, source="vehicle", planner="expert",
                                            targets=(PlanTarget(uav_id=1, target_enu_m=(50.0, 60.0, 10.0)),)))
                publisher.publish_qos(Qos(stamp_s=stamp_s, seq=seq, source="vehicle", qos_s1=0.5, qos_s2=0.25,
                                          mean_throughput_mbps=3.0, n_users=4))
                seq += 1
                time.sleep(0.02)
            assert republisher.wait() == 0, republisher.stderr.read()
        assert peer.wait(timeout=120) == 0
    finally:
        peer.kill()
    got = json.loads((tmp_path / "peer.json").read_text())
    poses = got["poses"]["0"] + got["poses"]["1"]
    assert poses and got["plans"] and got["qos"]
    for stamp_ns, frame, *position in poses:  # each at the stamp its payload was produced with
        assert frame == "map" and tuple(position) == sent[stamp_ns]
    assert got["plans"][-1][2] == [[50.0, 60.0, 10.0]] and got["plan_info"][-1]["values"]["uav_ids"] == "1"
    assert float(got["qos"][-1]["values"]["qos_s2"]) == 0.25


def test_ros2_topics_lists_a_runs_topics_with_their_types_and_counts(tmp_path):
    n_uavs = 2
    config = _config(tmp_path / "sim.toml", "listed", f"tcp/127.0.0.1:{free_tcp_port()}", n_uavs=n_uavs,
                     duration_s=40.0, replan_every=10, publish_telemetry=False)
    env = ros_env(domain_id())
    run = subprocess.Popen([sys.executable, "-m", "uav_swarm", "simulate", "--config", str(config), "--out",
                            str(tmp_path / "out"), "--ros2", "--quiet"], env=env, stderr=subprocess.PIPE,
                           text=True)
    try:  # the run waits for a subscriber of its poses: the listing's
        listing = subprocess.run([sys.executable, "-m", "uav_swarm", "telemetry", "ros2-topics", "--swarm",
                                  "listed", "--duration-s", "2", "--wait-s", "300"], env=env,
                                 capture_output=True, text=True, timeout=600)
        assert run.wait(timeout=600) == 0, run.stderr.read()[-3000:]
    finally:
        run.kill()
    assert listing.returncode == 0, listing.stderr[-3000:]
    header, *rows = listing.stdout.strip().splitlines()
    assert header.split()[:2] == ["topic", "type"]
    table = {row.split()[0]: (row.split()[1], row.split()[2]) for row in rows}
    expected = {f"uav_{i}/{kind}": "geometry_msgs/msg/PoseStamped" for i in range(n_uavs)
                for kind in ("pose", "target", "operator_target")}
    diagnostics, markers = "diagnostic_msgs/msg/DiagnosticArray", "visualization_msgs/msg/MarkerArray"
    expected |= {"poses": "geometry_msgs/msg/PoseArray", "plan": "geometry_msgs/msg/PoseArray",
                 "plan/info": diagnostics, "qos": diagnostics, "radio": diagnostics,
                 "markers": markers, "crowd": "sensor_msgs/msg/PointCloud2", "scene": markers,
                 "operator/status": diagnostics}
    listed = {topic: kind for topic, (kind, _) in table.items()}
    clock = {"/clock": "rosgraph_msgs/msg/Clock"}
    assert listed == {f"/uav_swarm/listed/{t}": k for t, k in expected.items()} | clock
    counted = [f"/uav_swarm/listed/{t}" for t in ("poses", "uav_0/pose", "uav_1/pose", "qos")] + ["/clock"]
    for topic in counted:
        assert int(table[topic][1]) > 0, topic  # every published step while it counted
