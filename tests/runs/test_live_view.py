"""``--live``: the SDK's WebSocket server during real runs, read by a Foxglove-protocol client on loopback."""

from __future__ import annotations

import logging
import threading

import numpy as np
import pytest
from foxglove_readback import conform, read_back
from foxglove_ws_client import LiveClient
from ports import free_tcp_port

from bridge.telemetry.schema import Qos, UavState
from typed_config import ConfigError
from uav_swarm.cli import main
from uav_swarm.runs.outputs.live_view import LiveView, live_view_option, parse_live_view
from uav_swarm.runs.outputs.recording import LIVE_BACKLOG_MESSAGES, SceneInfo, open_recorder

SMALL_TOML = """
n_uavs = 3
[task.scenario]
n_groups_min = 2
n_groups_max = 2
group_size_min = 20
group_size_max = 25
"""
OBSTACLES = np.array([[10.0, 10.0, 40.0, 10.0], [40.0, 10.0, 40.0, 30.0]])


def _simulate_argv(tmp_path, *extra: str) -> list[str]:
    config = tmp_path / "sim.toml"
    config.write_text(SMALL_TOML, encoding="utf-8")
    return ["simulate", "--out", str(tmp_path / "out"), "--config", str(config), "--planner", "expert",
            "--no-expert", "--no-telemetry", "--no-gif", "--quiet", *extra]


class _Run(threading.Thread):
    """``uav-swarm`` in a thread of the test (the server it starts is real; so is the run)."""

    def __init__(self, argv: list[str]) -> None:
        super().__init__(daemon=True)
        self.argv, self.code = argv, None

    def run(self) -> None:
        self.code = main(self.argv)


@pytest.mark.parametrize(("text", "field"), [("abc", "give PORT or HOST:PORT"), ("70000", "0..65535"),
                                             ("-1", "give PORT"), ("::1:80", "IPv6 host in brackets"),
                                             ("bad host:80", "neither an IP address nor a host name"),
                                             (":80", "neither an IP address")])
def test_a_bad_live_address_is_refused_naming_live(text, field):
    with pytest.raises(ConfigError, match=f"live = .*{field}"):
        parse_live_view(text)


def test_live_options():
    assert live_view_option(None) is None
    assert live_view_option("0.0.0.0:9000", 5) == LiveView("0.0.0.0", 9000, 5.0)
    assert not LiveView("0.0.0.0", 9000).is_loopback and LiveView("localhost", 1).is_loopback
    with pytest.raises(ConfigError, match="--live-wait-s 3.0: .*give --live"):
        live_view_option(None, 3.0)
    with pytest.raises(ConfigError, match="--speedup 2.0: .*give --live"):
        live_view_option(None, None, 2.0)
    with pytest.raises(ConfigError, match="--live-wait-s -1: give the seconds"):
        live_view_option("8765", -1)
    with pytest.raises(ConfigError, match="--speedup 0: give run seconds"):
        live_view_option("8765", 0, 0)
    with pytest.raises(ConfigError, match="--live '8765x': give PORT"):
        live_view_option("8765x")


def test_a_run_streamed_at_a_speed_keeps_its_pace(tmp_path):
    """``--speedup 4``: 2 s of run time take at least 0.5 s of wall-clock time (it waits on the clock)."""
    import time

    scene = SceneInfo(width_m=100.0, height_m=80.0, coverage_radius_m=30.0)
    qos = Qos(stamp_s=0.0, seq=0, source="sim", qos_s1=0.5, qos_s2=0.4, mean_throughput_mbps=2.0, n_users=1)
    with open_recorder(scene, live=LiveView("127.0.0.1", free_tcp_port(), speed=4.0)) as recorder:
        start_s = time.monotonic()
        for step in range(21):
            recorder.step(0.1 * step, [], qos, np.zeros((1, 2)), np.zeros(1, bool))
        assert time.monotonic() - start_s >= 2.0 / 4.0


@pytest.mark.parametrize("live", ["99999", "busy"])
def test_the_command_exits_2_before_any_output_on_a_bad_or_busy_live_port(tmp_path, capsys, live):
    import socket

    with socket.socket() as busy:
        busy.bind(("127.0.0.1", free_tcp_port()))
        busy.listen()
        port = str(busy.getsockname()[1]) if live == "busy" else live
        assert main(_simulate_argv(tmp_path, "--duration-s", "1", "--live", port,
                                   "--record", str(tmp_path / "run.mcap"))) == 2
    assert "uav-swarm simulate: --live " in capsys.readouterr().err
    assert not (tmp_path / "out").exists() and not (tmp_path / "run.mcap").exists()
    assert [p.name for p in tmp_path.iterdir()] == ["sim.toml"]  # no temporary recording left either


def test_simulate_streams_the_scene_the_crowd_and_the_qos_to_a_live_client(tmp_path):
    """A real ``simulate --live --record``: what the client receives is what the file holds."""
    port, path = free_tcp_port(), tmp_path / "run.mcap"
    run = _Run(_simulate_argv(tmp_path, "--duration-s", "3", "--live", f"127.0.0.1:{port}",
                              "--live-wait-s", "600", "--record", str(path)))
    run.start()
    client = LiveClient(port)
    try:
        assert client.ws.subprotocol == "foxglove.sdk.v1"  # the protocol v1 of the Foxglove SDK's server
        assert client.server_info["op"] == "serverInfo" and client.server_info["name"] == "uav-swarm simulate"
        client.wait_for(["/scene", "/pedestrians", "/qos"])  # advertised before the first step
        assert client.channels["/scene"]["schemaName"] == "foxglove.SceneUpdate"
        client.subscribe(["/pedestrians", "/qos"])
        client.subscribe(["/scene"])  # the run starts on this one: the other two are in place by then
        received = client.messages()
    finally:
        client.close()
    run.join(timeout=600)
    assert run.code == 0
    by_topic: dict[str, list] = {}
    for topic, log_ns, message in received:
        by_topic.setdefault(topic, []).append((log_ns, message))
    recorded = read_back(path)["topics"]
    assert len(recorded["/qos"]["messages"]) == 30
    for topic in ("/scene", "/pedestrians", "/qos"):
        # the live view streams at most 25 steps per wall-clock second (the file keeps every one), and
        # what is still queued when the server stops is not sent: the client gets recorded messages,
        # in order, each equal to the file's at its log time
        in_file = dict(zip(recorded[topic]["log_ns"], recorded[topic]["messages"], strict=True))
        live = by_topic[topic]
        assert live and [ns for ns, _ in live] == sorted({ns for ns, _ in live}), topic
        assert all(in_file[ns] == message for ns, message in live), topic
    first = {e["id"] for e in by_topic["/scene"][0][1]["entities"]}
    assert first == {"area", "obstacles"}
    assert all(conform(m, "foxglove.PointCloud") == [] for _, m in by_topic["/pedestrians"])


def test_a_client_that_comes_late_gets_the_static_scene_at_once_and_its_leaving_is_logged(tmp_path, caplog):
    port, path = free_tcp_port(), tmp_path / "run.mcap"
    scene = SceneInfo(width_m=100.0, height_m=80.0, coverage_radius_m=30.0)
    state = UavState(stamp_s=0.0, seq=0, source="sim", uav_id=0, position_enu_m=(50.0, 40.0, 30.0),
                     velocity_enu_m_s=(0.0, 0.0, 0.0), target_enu_m=(60.0, 40.0, 30.0))
    qos = Qos(stamp_s=0.0, seq=0, source="sim", qos_s1=0.5, qos_s2=0.4, mean_throughput_mbps=2.0, n_users=2)
    caplog.set_level(logging.INFO, logger="uav_swarm.runs")
    with open_recorder(scene, record=path, live=LiveView("127.0.0.1", port)) as recorder:
        recorder.static_scene(OBSTACLES)
        for step in range(1, 6):  # the run goes on: five steps before anyone watches
            recorder.step(0.1 * step, [state], qos, np.array([[10.0, 20.0], [90.0, 70.0]]), np.array([1, 0]))
        client = LiveClient(port)
        client.wait_for(["/scene"])
        client.subscribe(["/scene"])
        topic, log_ns, message = client.next_message()
        client.close()
    assert topic == "/scene" and log_ns == 500_000_000  # re-sent at the run's time, not at 0
    entities = {e["id"]: e for e in message["entities"]}
    assert set(entities) == {"area", "obstacles"}
    walls = [(p["x"], p["y"]) for p in entities["obstacles"]["lines"][0]["points"]]
    np.testing.assert_array_equal(np.reshape(walls, (-1, 4)), OBSTACLES)
    assert conform(message, "foxglove.SceneUpdate") == []
    in_file = read_back(path)["topics"]["/scene"]["messages"]
    assert recorder.counts["/scene"] == 6 == len(in_file)  # the re-send went to the live client only
    logs = caplog.text
    assert f"live view on ws://127.0.0.1:{port}" in logs and "subscribed (first topic /scene)" in logs
    assert "left (disconnected, or unsubscribed from every topic)" in logs


def test_a_client_that_stops_reading_does_not_stall_the_command(tmp_path):
    """``simulate --live``: a client subscribes to everything, then reads nothing until the run has ended."""
    port, path = free_tcp_port(), tmp_path / "run.mcap"
    run = _Run(_simulate_argv(tmp_path, "--duration-s", "30", "--live", f"127.0.0.1:{port}",
                              "--live-wait-s", "600", "--record", str(path)))
    run.start()
    client = LiveClient(port, receive_buffer_bytes=4096)
    try:
        client.wait_for(["/scene", "/pedestrians", "/qos", "/tf", "/plan"])
        client.subscribe(["/pedestrians", "/qos", "/tf", "/plan", "/plan/targets"])
        client.subscribe(["/scene"])
        run.join(timeout=600)  # meanwhile the client reads nothing
        assert run.code == 0 and path.exists()
        received = client.messages(timeout_s=60)
    finally:
        client.close()
    recorded = read_back(path)["topics"]["/qos"]
    by_time = dict(zip(recorded["log_ns"], recorded["messages"], strict=True))
    qos = [(ns, message) for topic, ns, message in received if topic == "/qos"]
    assert [ns for ns, _ in qos] == sorted(ns for ns, _ in qos)  # what it got, it got in order and whole
    assert all(by_time[ns] == message for ns, message in qos)


def test_a_stalled_client_never_blocks_a_step_the_server_drops_its_oldest(caplog):
    """Far more than the kernel's buffers and the server's backlog can hold: every step returns, the client
    that reads nothing misses the oldest messages, and gets the newest when it reads again."""
    port, steps, n_users = free_tcp_port(), 1000, 2000
    rng = np.random.default_rng(0)
    state = UavState(stamp_s=0.0, seq=0, source="sim", uav_id=0, position_enu_m=(50.0, 40.0, 30.0),
                     velocity_enu_m_s=(0.0, 0.0, 0.0))
    qos = Qos(stamp_s=0.0, seq=0, source="sim", qos_s1=0.5, qos_s2=0.4, mean_throughput_mbps=2.0,
              n_users=n_users)
    scene = SceneInfo(width_m=100.0, height_m=80.0, coverage_radius_m=30.0)
    cloud_bytes = 16 * n_users
    # what can be on its way without the client reading: its socket's buffer (set, so not grown by the
    # kernel), the client library's queue of 16 frames, the server's backlog and its socket's buffer
    held = 2 * 4096 + (16 + LIVE_BACKLOG_MESSAGES) * cloud_bytes + _tcp_send_buffer_max()
    assert steps * cloud_bytes > 2 * held
    with open_recorder(scene, live=LiveView("127.0.0.1", port, max_rate_hz=None)) as recorder:  # every step
        client = LiveClient(port, receive_buffer_bytes=4096)
        client.wait_for(["/pedestrians"])
        client.subscribe(["/pedestrians"])
        client.subscribe(["/scene"])
        recorder.static_scene(OBSTACLES)
        users = rng.uniform(0.0, 80.0, (n_users, 2))
        for step in range(1, steps + 1):
            recorder.step(0.1 * step, [state], qos, users, np.zeros(n_users, bool))
        last_ns, received = round(0.1 * steps * 1e9), []
        while not received or received[-1] != last_ns:  # it reads again: the newest is still to come
            topic, log_ns, _ = client.next_message(timeout_s=120)
            if topic == "/pedestrians":
                received.append(log_ns)
        client.close()
    assert len(received) < steps and received == sorted(received)  # the oldest were dropped


def _tcp_send_buffer_max() -> int:
    """The largest send buffer the kernel grows a TCP socket to (Linux; 16 MiB assumed elsewhere)."""
    from pathlib import Path

    try:
        return int(Path("/proc/sys/net/ipv4/tcp_wmem").read_text().split()[2])
    except (OSError, ValueError, IndexError):
        return 16 * 2**20


def test_fly_refuses_a_bad_live_address_before_anything_is_sent(tmp_path, capsys):
    argv = ["fly", "--bridge-config", str(tmp_path / "none.toml"), "--out", str(tmp_path / "out"),
            "--live", "localhost:http"]
    assert main(argv) == 2
    assert "uav-swarm fly: --live 'localhost:http': give PORT or HOST:PORT" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_the_live_view_streams_at_most_its_rate_and_the_file_keeps_every_step(tmp_path):
    import time

    port, path, steps = free_tcp_port(), tmp_path / "run.mcap", 200
    scene = SceneInfo(width_m=100.0, height_m=80.0, coverage_radius_m=30.0)
    qos = Qos(stamp_s=0.0, seq=0, source="sim", qos_s1=0.5, qos_s2=0.4, mean_throughput_mbps=2.0, n_users=1)
    with open_recorder(scene, record=path, live=LiveView("127.0.0.1", port, max_rate_hz=25.0)) as recorder:
        recorder.static_scene(OBSTACLES)
        client = LiveClient(port)
        client.wait_for(["/qos", "/scene"])
        client.subscribe(["/qos"])
        client.subscribe(["/scene"])
        assert client.next_message()[0] == "/scene"  # re-sent on subscribing: /qos is subscribed by then
        start_s = time.monotonic()
        for step in range(1, steps + 1):
            recorder.step(0.1 * step, [], qos, np.zeros((1, 2)), np.zeros(1, bool))
        elapsed_s = time.monotonic() - start_s
        last = recorder.counts["/qos"]
    received = [ns for topic, ns, _ in client.messages(timeout_s=60) if topic == "/qos"]
    client.close()
    assert last == steps == len(read_back(path)["topics"]["/qos"]["messages"])
    assert len(received) <= 2 + elapsed_s * 25.0  # one step per 40 ms at most (and the first)
