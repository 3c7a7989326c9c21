"""``simulate --record``: the MCAP file read back with the ``mcap`` reader equals the run.

Foxglove's messages are decoded with protobuf's own decoder from the descriptors in the file and
checked against Foxglove's published JSON Schemas (``tests/foxglove_readback.py``); the project's
JSON channels against the JSON Schema the file declares for them.
"""

from __future__ import annotations

import base64
import json

import jsonschema
import numpy as np
import pytest
from foxglove_readback import PUBLISHED, conform, read_back

from bridge.geo import Home
from bridge.telemetry.schema import Qos, UavState
from conftest import SMALL_PAPER_TASK
from typed_config import ConfigError
from uav_swarm.cli import main
from uav_swarm.runs.outputs.recording import RUN_METADATA, SceneInfo, open_recorder
from uav_swarm.runs.simulate import simulate
from uav_swarm.runs.simulate_config import SimulateConfig

N_UAVS, REPLAN_EVERY, RECORD_EVERY = 3, 7, 2
SCHEMA_OF = {"/scene": "foxglove.SceneUpdate", "/pedestrians": "foxglove.PointCloud",
             "/tf": "foxglove.FrameTransforms", "/plan": "uav_swarm.Plan",
             "/plan/targets": "foxglove.PosesInFrame", "/qos": "uav_swarm.Qos"}
SCHEMA_OF |= {f"/uav/{i}/state": "uav_swarm.UavState" for i in range(N_UAVS)}
SCHEMA_OF |= {f"/uav/{i}/location": "foxglove.LocationFix" for i in range(N_UAVS)}


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """A 3 s expert run of 3 UAVs, recorded every 2nd step, replanning every 7th."""
    out = tmp_path_factory.mktemp("simulate")
    config = SimulateConfig.from_dict({
        "duration_s": 3.0, "n_uavs": N_UAVS, "planner": "expert", "compare_expert": False, "gif": False,
        "publish_telemetry": False, "replan_every": REPLAN_EVERY, "telemetry_every": RECORD_EVERY,
        "task": SMALL_PAPER_TASK})
    result = simulate(config, out / "outputs", progress=False, record=out / "replay" / "run.mcap")
    return config, result, read_back(out / "replay" / "run.mcap")


def test_foxglove_channels_conform_to_the_published_schemas(recorded):
    _, _, data = recorded
    topics = data["topics"]
    assert {topic: t["schema"] for topic, t in topics.items()} == SCHEMA_OF
    checked = 0
    for topic, t in topics.items():
        if not t["schema"].startswith("foxglove."):
            continue
        assert t["schema"] in PUBLISHED
        assert (t["encoding"], t["schema_encoding"]) == ("protobuf", "protobuf"), topic
        for message in t["messages"]:
            assert conform(message, t["schema"]) == [], topic
            checked += 1
    assert checked == sum(len(t["messages"]) for t in topics.values() if t["schema"].startswith("foxglove."))
    assert checked > 0


def test_a_message_off_the_published_schema_is_caught():
    scene = {"deletions": [], "entities": [{"id": "uavs", "frame_id": "map", "colour": "blue"}]}
    assert any("colour: not in the published schema" in w for w in conform(scene, "foxglove.SceneUpdate"))
    fix = {"timestamp": {"sec": 0, "nsec": 0}, "frame_id": "uav_0", "latitude": "47.1", "longitude": 8.5,
           "altitude": 0.0, "position_covariance": [0.0] * 9, "position_covariance_type": 0}
    assert any("is not of type 'number'" in w for w in conform(fix, "foxglove.LocationFix"))


def test_telemetry_channels_carry_the_zenoh_payloads_as_json(recorded):
    _, result, data = recorded
    for topic, t in data["topics"].items():
        if t["schema"].startswith("uav_swarm."):
            assert (t["encoding"], t["schema_encoding"]) == ("json", "jsonschema"), topic
            json_schema = json.loads(t["schema_data"])
            assert json_schema["title"] == t["schema"]
            for message in t["messages"]:
                jsonschema.validate(message, json_schema)
    assert result.summary["recording"].endswith("run.mcap")
    run_info = data["metadata"][RUN_METADATA]
    assert run_info["command"] == "simulate" and json.loads(run_info["config"])["seed"] == 0


def test_message_counts_and_log_times_equal_the_run(recorded):
    config, result, data = recorded
    run, topics, dt_s = result.runs["expert"], data["topics"], config.dt_s
    recorded_steps = np.arange(0, config.n_steps, RECORD_EVERY)
    step_ns = np.round((recorded_steps + 1) * dt_s * 1e9).astype(np.int64)
    replans = np.arange(0, config.n_steps, REPLAN_EVERY)
    assert len(replans) == run.latency_ms.size
    plan_ns = np.round(replans * dt_s * 1e9).astype(np.int64)
    expected = {"/scene": len(step_ns) + 1, "/plan": len(plan_ns), "/plan/targets": len(plan_ns)}
    for topic in SCHEMA_OF:
        assert len(topics[topic]["messages"]) == expected.get(topic, len(step_ns)), topic
    for topic in ("/qos", "/tf", "/pedestrians", *(f"/uav/{i}/state" for i in range(N_UAVS))):
        assert topics[topic]["log_ns"] == step_ns.tolist(), topic
        assert topics[topic]["publish_ns"] == step_ns.tolist(), topic
    assert topics["/scene"]["log_ns"] == [0, *step_ns.tolist()]
    assert topics["/plan"]["log_ns"] == topics["/plan/targets"]["log_ns"] == plan_ns.tolist()
    counts = data["summary"].statistics.channel_message_counts  # the file's own index agrees
    by_topic = {c.topic: counts[c.id] for c in data["summary"].channels.values()}
    assert by_topic == {topic: len(t["messages"]) for topic, t in topics.items()}
    assert data["summary"].statistics.message_end_time == step_ns[-1]


def test_recorded_values_equal_the_run(recorded):
    config, result, data = recorded
    run, topics = result.runs["expert"], data["topics"]
    qos = topics["/qos"]["messages"]
    kept = slice(0, None, RECORD_EVERY)
    np.testing.assert_array_equal([q["qos_s1"] for q in qos], run.qos_s1[kept])
    np.testing.assert_array_equal([q["qos_s2"] for q in qos], run.qos_s2[kept])
    np.testing.assert_array_equal([q["mean_throughput_mbps"] for q in qos], run.throughput_mbps[kept])
    assert [p["latency_ms"] for p in topics["/plan"]["messages"]] == run.latency_ms.tolist()
    last_poses = topics["/plan/targets"]["messages"][-1]["poses"]
    last_targets = [(p["position"]["x"], p["position"]["y"]) for p in last_poses]
    np.testing.assert_array_equal(last_targets, run.final_targets_m)
    cloud = topics["/pedestrians"]["messages"][-1]
    points = np.frombuffer(base64.b64decode(cloud["data"]), "<f4").reshape(-1, cloud["point_stride"] // 4)
    assert [f["type"] for f in cloud["fields"]] == [7] * 4  # foxglove.NumericType FLOAT32
    assert len(points) == run.n_pedestrians
    assert [f["name"] for f in cloud["fields"]] == ["x", "y", "z", "covered"]
    if (config.n_steps - 1) % RECORD_EVERY == 0:  # the last step is recorded: the crowd at the end
        np.testing.assert_allclose(points[:, :2], run.final_pedestrians_m, atol=1e-4)
    np.testing.assert_allclose(points[:, 3].mean(), qos[-1]["qos_s1"], atol=1e-6)  # covered share = S1
    static = {e["id"]: e for e in topics["/scene"]["messages"][0]["entities"]}
    lines = static["obstacles"]["lines"]
    walls = [(p["x"], p["y"]) for p in lines[0]["points"]] if lines else []
    np.testing.assert_allclose(np.reshape(walls, (-1, 4)), run.obstacles_m)
    for uav_id in range(N_UAVS):
        state = topics[f"/uav/{uav_id}/state"]["messages"][-1]
        swarm = topics["/scene"]["messages"][-1]["entities"][0]
        assert swarm["id"] == "uavs"
        position = swarm["spheres"][uav_id]["pose"]["position"]
        assert [position["x"], position["y"], position["z"]] == state["position_enu_m"]
        fix = topics[f"/uav/{uav_id}/location"]["messages"][-1]
        assert fix["frame_id"] == f"uav_{uav_id}" and 47.0 < fix["latitude"] < 48.0  # the default home


def test_a_vehicle_without_a_fix_is_recorded_on_its_state_channel_only(tmp_path):
    path = tmp_path / "flight.mcap"
    header = {"stamp_s": 1.0, "seq": 0, "source": "vehicle"}
    states = [UavState(**header, uav_id=0, position_enu_m=(10.0, 20.0, 30.0),
                       velocity_enu_m_s=(0.0, 0.0, 0.0), target_enu_m=(50.0, 60.0, 30.0)),
              UavState(**header, uav_id=1, fix=False, position_enu_m=None, velocity_enu_m_s=None)]
    qos = Qos(**header, qos_s1=0.5, qos_s2=0.0, mean_throughput_mbps=1.0, n_users=2)
    scene = SceneInfo(width_m=100.0, height_m=100.0, coverage_radius_m=30.0, home=Home())
    with open_recorder(scene, record=path) as rec:
        rec.step(0.5, states, qos, np.array([[10.0, 20.0], [90.0, 90.0]]), np.array([True, False]))
    topics = read_back(path)["topics"]
    assert "/uav/1/location" not in topics and topics["/uav/1/state"]["messages"][0]["fix"] is False
    assert len(topics["/uav/0/location"]["messages"]) == 1
    frames = topics["/tf"]["messages"][0]["transforms"]
    assert [f["child_frame_id"] for f in frames] == ["uav_0"]
    entities = {e["id"]: e for e in topics["/scene"]["messages"][0]["entities"]}
    assert len(entities["uavs"]["spheres"]) == len(entities["coverage"]["cylinders"]) == 1
    leg = entities["targets"]["lines"][0]["points"]
    assert [(p["x"], p["y"]) for p in leg] == [(10.0, 20.0), (50.0, 60.0)]


def test_a_run_that_fails_leaves_no_file(tmp_path):
    path = tmp_path / "run.mcap"
    qos = Qos(stamp_s=0.0, seq=0, source="sim", qos_s1=0.5, qos_s2=0.5, mean_throughput_mbps=1.0, n_users=2)
    scene = SceneInfo(width_m=10.0, height_m=10.0, coverage_radius_m=5.0)
    with pytest.raises(RuntimeError, match="stopped"), open_recorder(scene, record=path) as rec:
        rec.qos(0.0, qos)
        raise RuntimeError("stopped")
    assert list(tmp_path.iterdir()) == []  # neither the file nor its temporary


def test_a_recording_path_that_is_not_mcap_is_refused_before_any_work(tmp_path):
    config = SimulateConfig.from_dict({"duration_s": 1.0, "n_uavs": 2, "planner": "expert", "gif": False,
                                       "compare_expert": False, "publish_telemetry": False})
    with pytest.raises(ConfigError, match="record = .*run.csv.*mcap"):
        simulate(config, tmp_path / "out", progress=False, record=tmp_path / "run.csv")
    assert list(tmp_path.iterdir()) == []


def test_the_command_records_with_record(tmp_path, capsys):
    path = tmp_path / "run.mcap"
    argv = ["simulate", "--out", str(tmp_path / "out"), "--planner", "expert", "--no-expert",
            "--no-telemetry", "--no-gif", "--quiet", "--duration-s", "1", "--n-uavs", "2",
            "--record", str(path)]
    assert main(argv) == 0
    assert f"recorded the expert planner's run in {path}" in capsys.readouterr().out
    topics = read_back(path)["topics"]
    assert len(topics["/qos"]["messages"]) == 10 and len(topics["/uav/1/state"]["messages"]) == 10


def test_the_telemetry_channels_carry_what_zenoh_carries(tmp_path):
    """A run that publishes over Zenoh (loopback) and records: each state, plan and QoS equal in both."""
    import time

    import msgspec
    from ports import free_tcp_port

    from bridge.telemetry import SwarmSubscriber
    from bridge.telemetry.config import TelemetryConfig
    from bridge.telemetry.schema import Payload

    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    config = SimulateConfig.from_dict({
        "duration_s": 2.0, "n_uavs": 2, "planner": "expert", "compare_expert": False, "gif": False,
        "publish_telemetry": True, "wait_for_subscriber_s": 60.0, "task": SMALL_PAPER_TASK,
        "telemetry": {"swarm": "rectest", "listen": [endpoint], "multicast_scouting": False}})
    received: list = []
    watch = TelemetryConfig(swarm="rectest", listen=(), connect=(endpoint,), multicast_scouting=False)
    path = tmp_path / "run.mcap"
    with SwarmSubscriber(watch, callback=received.append, presence=False):
        simulate(config, tmp_path / "out", progress=False, record=path)
        deadline = time.monotonic() + 30.0  # the last QoS is on its way
        while time.monotonic() < deadline and not any(isinstance(m, Qos) and m.seq == 19 for m in received):
            time.sleep(0.05)
    recorded = {}
    for t in read_back(path)["topics"].values():
        if t["schema"].startswith("uav_swarm."):
            for message in t["messages"]:
                payload = msgspec.convert(message, Payload)
                recorded[(type(payload).__name__, getattr(payload, "uav_id", None), payload.seq)] = payload
    assert received and all(
        recorded[(type(m).__name__, getattr(m, "uav_id", None), m.seq)] == m for m in received)
    states = [m for m in received if isinstance(m, UavState)]
    assert states and all(m.position_wgs84 is not None for m in states)  # filled from the home, in both
