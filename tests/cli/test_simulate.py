"""Tiny-budget runs of the main job (``uav-swarm simulate``) under tmp_path, telemetry on loopback."""

from __future__ import annotations

import json
import socket
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from ports import free_tcp_port, free_udp_port
from pymavlink.dialects.v20 import common as mavlink

from bridge.geo import Home
from bridge.missions.files import load_plan
from bridge.telemetry import SwarmSubscriber
from bridge.telemetry.config import TelemetryConfig
from bridge.telemetry.schema import Plan, Qos, UavState
from conftest import SMALL_PAPER_TASK, SMALL_WIFI_TASK
from uav_swarm.cli import main
from uav_swarm.runs.simulate import simulate
from uav_swarm.runs.simulate_config import SimulateConfig

SMALL_TOML = """
n_uavs = 3
replan_every = 10
gif_max_frames = 8
gif_width_px = 900

[task.scenario]
n_groups_min = 2
n_groups_max = 3
group_size_min = 35
group_size_max = 45

[task.radio]
propagation = "paper"   # the tiny network's radio (simulate's default is 802.11)
"""


@pytest.fixture()
def small_config(tmp_path):
    path = tmp_path / "sim.toml"
    path.write_text(SMALL_TOML, encoding="utf-8")
    return path


def tiny(checkpoint_path, **changes) -> SimulateConfig:
    base = {"duration_s": 3.0, "n_uavs": 3, "gif_max_frames": 6, "gif_width_px": 900,
            "publish_telemetry": False, "checkpoint": str(checkpoint_path), "task": SMALL_PAPER_TASK}
    return SimulateConfig.from_dict({**base, **changes})


def test_simulate_command_writes_the_figure_animation_summary_and_plans(tmp_path, small_config,
                                                                       tiny_checkpoint, capsys):
    out = tmp_path / "sim"
    argv = ["simulate", "--out", str(out), "--config", str(small_config),
            "--checkpoint", str(tiny_checkpoint), "--duration-s", "3", "--seed", "2",
            "--no-telemetry"]
    assert main(argv) == 0
    captured = capsys.readouterr()
    printed = captured.out
    assert "planner:" not in captured.err and "step/s" not in captured.err  # not a terminal: no progress bar
    assert f"wrote qos.png, timeseries.csv, scene.gif, summary.json, missions/ (3 files) in {out}" in printed
    assert "3 UAVs" in printed and "\nlearned " in printed and "\nexpert " in printed
    assert "learned / expert: QoS S1" in printed
    assert "learned network: " in printed and " engine, float32" in printed
    assert "\nexpert: search expert (strategy 1, the paper's radio without admission control)\n" in printed

    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["planners"]) == {"learned", "expert"} and summary["flown"] == "learned"
    for s in summary["planners"].values():
        for strategy in ("qos_s1", "qos_s2"):
            assert 0.0 <= s[f"min_{strategy}"] <= s[f"mean_{strategy}"] <= 1.0
        assert s["mean_throughput_mbps"] >= 0.0 and s["n_replans"] == 3 and s["n_pedestrians"] > 0
        assert 0.0 < s["median_latency_ms"] <= s["p95_latency_ms"]
    assert summary["planners"]["learned"]["planner"] == "cnn-peaks-hungarian"
    assert summary["checkpoint"].endswith("best.pt") and summary["expert"].startswith("search expert")
    assert summary["config"]["seed"] == 2 and summary["config"]["n_uavs"] == 3
    assert summary["ratios_learned_over_expert"]["expert_over_learned_median_latency"] > 0.0
    assert summary["inference_engine"] in ("onnxruntime", "torch-jit", "torch-eager")
    assert summary["peaks"]["source"] == "checkpoint (balanced point)"  # the tiny one has no mission point

    assert (out / "qos.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with Image.open(out / "scene.gif") as gif:
        n_frames = gif.n_frames
        assert 2 <= n_frames <= 8 and gif.size == (900, 504)  # at least 900 px wide, for people
    assert (out / "scene.gif").stat().st_size < 5e6 * n_frames / 100  # 5 MB for the default 100 frames
    rows = (out / "timeseries.csv").read_text().splitlines()
    assert rows[0].startswith("planner,time_s") and len(rows) == 1 + 2 * 30
    plans = sorted((out / "missions").glob("vehicle_*.plan"))
    assert [p.name for p in plans] == ["vehicle_1.plan", "vehicle_2.plan", "vehicle_3.plan"]
    mission = load_plan(plans[0])
    assert mission.items[-1].command == mavlink.MAV_CMD_NAV_LOITER_UNLIM and mission.home == Home()
    assert not list(out.glob(".*"))  # no temporary file left


def test_both_planners_face_the_same_crowd_and_the_results_are_sane(tmp_path, tiny_checkpoint):
    result = simulate(tiny(tiny_checkpoint, duration_s=2.0, replan_every=5, seed=4), tmp_path, progress=False)
    learned, expert = result.runs["learned"], result.runs["expert"]
    np.testing.assert_array_equal(learned.final_pedestrians_m, expert.final_pedestrians_m)
    for run in (learned, expert):
        assert run.qos_s1.shape == (20,) and run.latency_ms.shape == (4,)
        assert np.all((run.qos_s2 >= 0) & (run.qos_s2 <= run.qos_s1 + 1e-12) & (run.qos_s1 <= 1))
        targets = run.final_targets_m
        assert len({tuple(t) for t in targets.round(6)}) == 3  # distinct targets
    assert 2 <= len(learned.frames) <= 6 and learned.frames[-1].utility.shape == (64, 64)
    assert not expert.frames  # only the flown planner is animated


def test_expert_only_without_gif(tmp_path, tiny_checkpoint):
    result = simulate(tiny(tiny_checkpoint, planner="expert", gif=False, checkpoint=""), tmp_path,
                      progress=False)
    assert list(result.runs) == ["expert"] and "ratios_learned_over_expert" not in result.summary
    assert not (tmp_path / "scene.gif").exists() and (tmp_path / "qos.png").exists()


def test_a_planning_peaks_table_is_flown_and_named_in_the_summary(tmp_path, tiny_checkpoint):
    config = tiny(tiny_checkpoint, duration_s=1.0, gif=False, compare_expert=False,
                  planning={"peaks": {"threshold_abs": 0.02, "max_peaks": 2}})
    result = simulate(config, tmp_path, progress=False)
    peaks = result.summary["peaks"]
    assert peaks["settings"]["threshold_abs"] == 0.02 and peaks["settings"]["max_peaks"] == 2
    assert peaks["overridden"] == ["max_peaks", "threshold_abs"]
    assert "[planning.peaks] max_peaks threshold_abs" in peaks["source"]


@pytest.mark.parametrize(("extra", "message"), [
    (["--n-uavs", "11"], "argument --n-uavs: 11 is out of range: allowed >= 1 and <= 10"),
    (["--duration-s", "-1"], "argument --duration-s: -1 is out of range"),
    (["--checkpoint", "/does/not/exist.pt"], "checkpoint not found: /does/not/exist.pt"),
    (["--bridge-config", "/does/not/exist.toml"], "config file not found"),
], ids=["uavs", "duration", "checkpoint", "bridge"])
def test_bad_configuration_exits_2_before_any_work(tmp_path, small_config, capsys, extra, message):
    out = tmp_path / "never"
    argv = ["simulate", "--out", str(out), "--config", str(small_config), "--no-telemetry", "--quiet", *extra]
    assert main(argv) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_area_outside_the_geofence_exits_2_before_any_work(tmp_path, small_config, capsys):
    bridge = tmp_path / "fence.toml"
    bridge.write_text("[geofence]\nx_max_m = 100.0\n", encoding="utf-8")
    out = tmp_path / "never"
    argv = ["simulate", "--out", str(out), "--config", str(small_config), "--planner", "expert",
            "--bridge-config", str(bridge), "--no-telemetry", "--quiet"]
    assert main(argv) == 2
    assert "geofence" in capsys.readouterr().err.lower()
    assert not out.exists()


def test_unknown_config_key_exits_2(tmp_path, capsys):
    path = tmp_path / "bad.toml"
    path.write_text("n_uavz = 3\n", encoding="utf-8")
    assert main(["simulate", "--out", str(tmp_path / "o"), "--config", str(path)]) == 2
    assert "unknown key(s) ['n_uavz'] (did you mean 'n_uavs'?)" in capsys.readouterr().err


def test_a_telemetry_endpoint_in_use_exits_2_before_the_first_step_and_writes_nothing(
        tmp_path, small_config, tiny_checkpoint, capsys, monkeypatch):
    import uav_swarm.runs.simulate as simulate_module

    def no_step(*args, **kwargs):
        raise AssertionError("a step ran before the telemetry endpoint was checked")

    monkeypatch.setattr(simulate_module, "run_sequence", no_step)
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as holder:
        holder.bind(("127.0.0.1", 0))
        holder.listen(1)
        endpoint = f"tcp/127.0.0.1:{holder.getsockname()[1]}"
        config = tmp_path / "busy.toml"
        config.write_text(small_config.read_text() + f'\n[telemetry]\nlisten = ["{endpoint}"]\n')
        out = tmp_path / "never"
        argv = ["simulate", "--out", str(out), "--config", str(config), "--checkpoint", str(tiny_checkpoint),
                "--duration-s", "3", "--quiet"]
        assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"{endpoint} is in use" in err and "--no-telemetry" in err
    assert not out.exists()


def test_a_run_beside_another_one_publishes_on_a_free_port_and_says_where(
        tmp_path, small_config, tiny_checkpoint, caplog):
    """With tcp/127.0.0.1:7447 held (another run), a run left at the default endpoint still runs."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as holder:
        try:
            holder.bind(("127.0.0.1", 7447))
            holder.listen(1)
        except OSError:
            pass  # another run on this machine holds it already
        out = tmp_path / "beside"
        argv = ["simulate", "--out", str(out), "--config", str(small_config), "--checkpoint",
                str(tiny_checkpoint), "--duration-s", "1", "--no-expert", "--no-gif", "--quiet"]
        assert main(argv) == 0
    (endpoint,) = json.loads((out / "summary.json").read_text())["config"]["telemetry"]["listen"]
    assert endpoint != "tcp/127.0.0.1:7447" and endpoint.startswith("tcp/127.0.0.1:")
    assert (f"tcp/127.0.0.1:7447 is in use (another run?): telemetry listens on {endpoint} instead"
            in caplog.text)


def test_telemetry_reaches_a_subscriber_on_loopback(tmp_path, tiny_checkpoint):
    port = free_tcp_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    config = tiny(tiny_checkpoint, publish_telemetry=True, compare_expert=False, gif=False,
                  wait_for_subscriber_s=10.0,
                  telemetry={"swarm": "simtest", "listen": [endpoint], "multicast_scouting": False})
    received: list = []
    watch = TelemetryConfig(swarm="simtest", listen=(), connect=(endpoint,), multicast_scouting=False)
    with SwarmSubscriber(watch, callback=received.append, presence=False):
        simulate(config, tmp_path, progress=False)
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline and sum(isinstance(m, Plan) for m in received) < 3:
            time.sleep(0.05)
    states = [m for m in received if isinstance(m, UavState)]
    plans = [m for m in received if isinstance(m, Plan)]
    qos = [m for m in received if isinstance(m, Qos)]
    assert {s.uav_id for s in states} == {0, 1, 2}
    assert all(s.source == "sim" and s.position_wgs84 is not None for s in states)
    assert all(s.target_enu_m is not None and s.position_enu_m[2] == 10.0 for s in states)
    assert plans and all(p.planner == "cnn-peaks-hungarian" and len(p.targets) == 3 for p in plans)
    assert [p.seq for p in plans] == sorted(p.seq for p in plans)
    assert qos and all(0.0 <= q.qos_s2 <= q.qos_s1 <= 1.0 for q in qos)


def test_final_missions_are_uploaded_to_the_configured_vehicles(tmp_path, tiny_checkpoint):
    from bridge.simulated.peer import SimVehicle

    ports = {7: free_udp_port(), 8: free_udp_port()}
    lines = ["[protocol]", "heartbeat_timeout_s = 5.0", ""]
    for sid, port in ports.items():
        lines += ["[[vehicles]]", f"system_id = {sid}", f'url = "udpin:127.0.0.1:{port}"', ""]
    bridge = tmp_path / "bridge.toml"
    bridge.write_text("\n".join(lines), encoding="utf-8")
    vehicles = [SimVehicle(f"udpout:127.0.0.1:{port}", sid, telemetry_period_s=0.2)
                for sid, port in ports.items()]
    try:
        config = tiny(tiny_checkpoint, n_uavs=2, duration_s=1.0, gif=False, compare_expert=False,
                      bridge_config=str(bridge))
        result = simulate(config, tmp_path / "out", progress=False)
    finally:
        for vehicle in vehicles:
            vehicle.close()
    assert result.summary["uploaded_to_vehicles"] == [7, 8]
    for vehicle in vehicles:
        sent = load_plan(tmp_path / "out" / "missions" / f"vehicle_{vehicle.system_id}.plan").items
        assert len(vehicle.mission) == 3 and tuple(vehicle.mission) == sent
        assert [item.z for item in sent] == [config.uav.alt_m] * 3  # take-off, target, loiter: one altitude


def test_refine_flag_merges_into_the_planning_table_of_the_file(tmp_path):
    from uav_swarm.cli import build_parser
    from uav_swarm.cli.simulate import _overrides
    from uav_swarm.runs.simulate_config import load_simulate_config

    path = tmp_path / "sim.toml"
    path.write_text("[planning]\nhysteresis_m = 7.0\n\n[planning.refinement]\ngrid_step_m = 5.0\n")
    args = build_parser().parse_args(["simulate", "--config", str(path), "--refine", "--n-uavs", "4"])
    config = load_simulate_config(args.config, _overrides(args))
    assert config.planning.refine and config.planning.hysteresis_m == 7.0
    assert config.planning.refinement.grid_step_m == 5.0 and config.n_uavs == 4
    plain_args = build_parser().parse_args(["simulate", "--config", str(path)])
    assert not load_simulate_config(path, _overrides(plain_args)).planning.refine
    both = build_parser().parse_args(["simulate", "--config", str(path), "--refine", "--rule-check"])
    planning = load_simulate_config(path, _overrides(both)).planning
    assert planning.refine and planning.rule_check and planning.hysteresis_m == 7.0
    assert not load_simulate_config(path, _overrides(plain_args)).planning.rule_check


def test_the_strategy_2_config_flies_the_evaluated_relocation_refinement(tmp_path):
    from uav_swarm.missions.registry import load_settings
    from uav_swarm.missions.wifi.refine import WifiRefineConfig
    from uav_swarm.runs.simulate_config import load_simulate_config

    root = Path(__file__).resolve().parents[2]
    config = load_simulate_config(root / "configs/simulate/wifi-s2-refined.toml", {})
    evaluated = load_settings("wifi-s2", root / "configs/tasks/wifi-s2.toml").refine
    assert config.task.strategy == 2 and config.planning.refine
    assert config.planning.refinement == WifiRefineConfig.from_dict(evaluated)
    short = SimulateConfig.from_dict({**config.to_dict(), "duration_s": 2.0, "n_uavs": 4, "gif": False,
                                      "compare_expert": False, "publish_telemetry": False})
    run = simulate(short, tmp_path / "out", progress=False).runs["learned"]
    assert run.planner_name == "cnn-peaks-refine-hungarian" and run.latency_ms.size == 2
    assert np.all(run.qos_s2 <= run.qos_s1 + 1e-12)


def test_a_minimum_separation_the_fleet_cannot_keep_exits_2_naming_the_field(tmp_path, capsys):
    out = tmp_path / "never"
    config = tmp_path / "far.toml"
    config.write_text("n_uavs = 10\n[uav]\nmin_separation_m = 90.0\n", encoding="utf-8")
    assert main(["simulate", "--out", str(out), "--config", str(config), "--no-telemetry", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert ("uav.min_separation_m = 90 m cannot be kept by 10 UAVs in a 200 x 200 m area: allowed 0 <= "
            "uav.min_separation_m <= 83.3") in err
    assert err.strip().count("\n") == 0  # one line, no traceback
    assert not out.exists()


def test_a_minimum_the_fleet_check_accepts_starts_and_flies_separated(tmp_path, capsys):
    out = tmp_path / "wide"
    config = tmp_path / "wide.toml"  # 80 m in 200 m: 10 UAVs on 3-2-3-2 staggered lines fit (83.3 m)
    config.write_text("n_uavs = 10\nduration_s = 2.0\ngif = false\n[uav]\nmin_separation_m = 80.0\n",
                      encoding="utf-8")
    argv = ["simulate", "--out", str(out), "--config", str(config), "--no-telemetry", "--no-expert", "-q"]
    assert main(argv) == 0, capsys.readouterr().err
    separation = json.loads((out / "summary.json").read_text())["planners"]["learned"]["separation"]
    assert separation["closest_m"] >= 80.0


def test_the_802_11_radio_flies_with_a_channel_plan_and_its_static_reference(tmp_path, tiny_checkpoint):
    task = {**SMALL_WIFI_TASK, "strategy": 2, "radio": {"propagation": "802.11"}}
    result = simulate(tiny(tiny_checkpoint, planner="expert", gif=False, checkpoint="", duration_s=2.0,
                           replan_every=5, task=task), tmp_path, progress=False)
    run = result.runs["expert"]
    assert np.all((run.qos_s2 >= 0) & (run.qos_s2 <= run.qos_s1 + 1e-12) & (run.qos_s1 <= 1))
    assert result.summary["planners"]["expert"]["association"].startswith("802.11")
    assert 0.0 <= result.summary["static_reference"]["mean_qos"] <= 1.0


def test_the_command_prints_the_802_11_radio_and_its_figures(tmp_path, capsys):
    config = tmp_path / "wifi.toml"
    config.write_text('n_uavs = 3\nduration_s = 0.5\ngif = false\nstatic_reference = false\n'
                      '[task]\nstrategy = 2\nwarmup_min_s = 1.0\nwarmup_max_s = 2.0\n'
                      '[task.radio]\npropagation = "802.11"\n', encoding="utf-8")
    out = tmp_path / "out"
    assert main(["simulate", "--out", str(out), "--config", str(config), "--planner", "expert", "--no-expert",
                 "--no-telemetry", "--quiet"]) == 0
    printed = capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    wifi = summary["planners"]["expert"]["wifi_80211"]
    assert "radio: 802.11, urban air-to-ground, 5.18 GHz, 20 MHz" in printed
    assert f"expert 802.11: median SINR {wifi['median_sinr_db']:.1f} dB" in printed
    assert f"channels {wifi['channels_final']}" in printed and len(wifi["channels_final"]) == 3


def test_a_radio_altitude_other_than_the_flight_altitude_exits_2_naming_the_field(tmp_path, capsys):
    out = tmp_path / "never"
    config = tmp_path / "high.toml"
    config.write_text('[task.radio]\npropagation = "802.11"\naltitude_m = 30.0\n', encoding="utf-8")
    assert main(["simulate", "--out", str(out), "--config", str(config), "--no-telemetry", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "task.radio.altitude_m = 30.0 differs from uav.alt_m = 10.0" in err and err.count("\n") == 1
    assert not out.exists()


def test_an_upload_to_vehicles_not_running_ends_naming_what_to_start(tmp_path, tiny_checkpoint, small_config,
                                                                      capsys):
    """No vehicle serves the bridge config: the run is written, the last line says what to start and how
    to upload the missions then (exit code 1), and it begins with no exception class."""
    ports = {7: free_udp_port(), 8: free_udp_port()}
    lines = ["[protocol]", "heartbeat_timeout_s = 1.0", ""]
    for sid, port in ports.items():
        lines += ["[[vehicles]]", f"system_id = {sid}", f'url = "udpin:127.0.0.1:{port}"', ""]
    bridge = tmp_path / "bridge.toml"
    bridge.write_text("\n".join(lines), encoding="utf-8")
    out = tmp_path / "out"
    argv = ["simulate", "--out", str(out), "--config", str(small_config),
            "--checkpoint", str(tiny_checkpoint), "--n-uavs", "2", "--duration-s", "1", "--no-gif",
            "--no-expert", "--no-telemetry", "--quiet",
            "--bridge-config", str(bridge)]
    assert main(argv) == 1
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last.startswith("uav-swarm simulate: the upload failed: ")
    assert f"uav-swarm vehicles --bridge-config {bridge}" in last
    assert f"uav-swarm mission upload --config {bridge} --from-dir {out / 'missions'}" in last
    assert (out / "summary.json").is_file() and sorted(p.name for p in (out / "missions").iterdir()) == [
        "vehicle_7.plan", "vehicle_8.plan"]
