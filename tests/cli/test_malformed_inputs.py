"""Every subcommand answers a user's mistake the same way: one line naming the flag or the file, exit 2,
no traceback, nothing written (docs/cli.md, "Mistakes")."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from uav_swarm.cli import build_parser, main
from uav_swarm.cli.conventions import iter_parsers

ROOT = Path(__file__).resolve().parents[2]
BRIDGE = str(ROOT / "configs" / "bridge" / "px4_sitl_10.toml")
AGP_SETTINGS = str(ROOT / "configs" / "tasks" / "agp.toml")
BUILDING = str(ROOT / "tests" / "data" / "buildings" / "picnic_shelter.geojson")
S1 = str(ROOT / "uav_swarm" / "checkpoints" / "wifi-s1.pt")
GEN = ["--n", "3", "--seed", "1", "--out", "out"]

# (argv, what the last line of stderr must name); every --out points at ./out, which must not appear
CASES: list[tuple[list[str], str]] = [
    (["no-such-command"], "invalid choice: 'no-such-command'"),
    (["env-demo", "--n-uavs", "0", "--out", "out"], "--n-uavs"),
    (["env-demo", "--replan-every-steps", "0", "--out", "out"], "--replan-every-steps"),
    (["env-demo", "--steps", "ten", "--out", "out"], "--steps"),
    (["telemetry", "watch", "--duration-s", "0"], "--duration-s"),
    (["telemetry", "watch", "--config", "missing.toml"], "missing.toml"),
    (["telemetry", "record", "--out", "out/run.jsonl", "--count", "-1"], "--count"),
    (["telemetry", "ros2", "--n-uavs", "11"], "--n-uavs"),
    (["telemetry", "ros2", "--namespace", "bad name", "--count", "1"], "namespace"),
    (["mission", "export", "--config", "missing.toml", "--target", "1:4,2", "--out", "out"], "missing.toml"),
    (["mission", "export", "--config", BRIDGE, "--target", "1:40", "--out", "out"], "--target"),
    (["mission", "export", "--config", BRIDGE, "--plans", "missing.json", "--out", "out"],
     "--plans missing.json"),
    (["mission", "export", "--config", BRIDGE, "--target", "1:5000,0", "--out", "out"], "geofence"),
    (["mission", "export", "--config", BRIDGE, "--target", "1:4,2", "--format", "kml", "--out", "out"],
     "--format"),
    (["mission", "upload", "--config", BRIDGE, "--from-dir", "missing"], "--from-dir"),
    (["mission", "download", "--config", BRIDGE], "--out"),
    (["mission", "clear", "--config", BRIDGE, "--vehicle", "77"], "configured vehicle ids"),
    (["dataset", "--task", "wifi-s1", "--n", "-5", "--seed", "1", "--out", "out"], "--n"),
    (["dataset", "--task", "wifi-s1", "--n", "5", "--seed", "-1", "--out", "out"], "--seed"),
    (["dataset", "--task", "wifi-s1", *GEN, "--shard-size", "0"], "--shard-size"),
    (["dataset", "--task", "wifi-s3", *GEN], "--task"),
    (["dataset", "--task", "wifi-s1", "--config", AGP_SETTINGS, *GEN], "agp.toml"),
    (["dataset", "--task", "agp", "--config", "missing.toml", *GEN], "missing.toml"),
    (["train", "--task", "agp", "--data", "missing", "--out", "out"], "missing"),
    (["train", "--task", "agp", "--data", "missing", "--out", "out", "--epochs", "0"], "--epochs"),
    (["train", "--task", "agp", "--data", "missing", "--out", "out", "--precision", "fp8"], "--precision"),
    (["evaluate", "--task", "agp", "--checkpoint", "missing.pt", *GEN], "missing.pt"),
    (["evaluate", "--task", "wifi-s1", "--checkpoint", S1, "--n", "0", "--seed", "1", "--out", "out"], "--n"),
    (["evaluate", "--task", "wifi-s1", "--checkpoint", S1, "--config", AGP_SETTINGS, *GEN], "agp.toml"),
    (["evaluate", "--task", "agp", "--checkpoint", S1, *GEN], "wifi-s1"),
    (["search", "--task", "agp", "--data", "missing", "--out", "out"], "missing"),
    (["search", "--task", "agp", "--data", "d", "--out", "out", "--alpha2", "3:x"], "--alpha2"),
    (["search", "--task", "agp", "--data", "d", "--out", "out", "--torch-threads", "0"], "--torch-threads"),
    (["expert-stability", "--task", "agp", "--scale-m", "-1", "--out", "out/r.json"], "--scale-m"),
    (["expert-stability", "--task", "agp", "--probe", "jitter", "--n", "2", "--out", "out/r.json"], "jitter"),
    (["calibrate-check", "--task", "agp", "--checkpoint", S1, "--data", "d", "--out", "out/c.json"],
     "--task"),
    (["calibrate-check", "--task", "wifi-s1", "--checkpoint", S1, "--data", "d", "--qos-floor", "2",
      "--out", "out/c.json"], "--qos-floor"),
    (["calibrate-check", "--task", "wifi-s1", "--checkpoint", S1, "--data", "missing", "--out", "out/c.json"],
     "missing"),
    (["calibrate-mission", "--task", "agp", "--n", "0", "--out", "out"], "--n"),
    (["calibrate-mission", "--task", "agp", "--checkpoint", "missing.pt", "--out", "out"], "missing.pt"),
    (["calibrate-mission", "--task", "agp", "--distances-px", "0", "--out", "out"], "distances_px"),
    (["simulate", "--n-uavs", "11", "--out", "out"], "--n-uavs"),
    (["simulate", "--duration-s", "-1", "--out", "out"], "--duration-s"),
    (["simulate", "--planner", "oracle", "--out", "out"], "--planner"),
    (["simulate", "--config", "missing.toml", "--out", "out"], "missing.toml"),
    (["simulate", "--checkpoint", "missing.pt", "--no-telemetry", "--out", "out"], "missing.pt"),
    (["simulate", "--speedup", "2", "--no-telemetry", "--out", "out"], "--speedup 2.0"),
    (["simulate", "--live", "80:80:80", "--no-telemetry", "--out", "out"], "--live"),
    (["fly", "--out", "out"], "--bridge-config"),
    (["fly", "--bridge-config", "missing.toml", "--out", "out"], "missing.toml"),
    (["fly", "--bridge-config", BRIDGE, "--replan-every-s", "0", "--out", "out"], "--replan-every-s"),
    (["telemetry", "ros2-topics", "--duration-s", "0"], "--duration-s"),
    (["vehicles", "--autopilot", "ardupilot", "--n", "0", "--out", "out"], "--n"),
    (["vehicles", "--autopilot", "px4", "--command-loss", "2", "--out", "out"], "--command-loss"),
    (["vehicles", "--autopilot", "px4", "--param", "WPNAV_SPEED", "--out", "out"], "--param"),
    (["place", "--task", "agp", "--building", "missing.geojson", "--out", "out"], "missing.geojson"),
    (["place", "--task", "wifi-s1", "--building", BUILDING, "--out", "out"], "--task"),
    (["place", "--task", "agp", "--building", BUILDING, "--max-pixel-m", "0", "--out", "out"],
     "--max-pixel-m"),
    (["place", "--task", "agp", "--building", BUILDING, "--standoff-m", "-1", "--out", "out"],
     "--standoff-m"),
    (["place", "--task", "agp", "--building", BUILDING, "--bridge-config", "missing.toml", "--out", "out"],
     "missing.toml"),
    (["rl-train", "--config", "missing.toml", "--out", "out"], "missing.toml"),
    (["rl-train", "--num-envs", "0", "--out", "out"], "--num-envs"),
    (["rl-compare", "--episodes", "0", "--out", "out"], "--episodes"),
    (["rl-compare", "--controllers", "oracle", "--out", "out"], "--controllers"),
    (["rl-compare", "--controllers", "mappo", "--out", "out"], "--policy"),
]


def test_every_subcommand_has_malformed_inputs():
    leaves = {path for path, parser in iter_parsers(build_parser()) if path and path != ("telemetry",)}
    covered = {tuple(argv[:2]) if argv[0] == "telemetry" else (argv[0],) for argv, _ in CASES}
    assert leaves <= covered, f"no malformed input for {sorted(leaves - covered)}"


@pytest.mark.parametrize(("argv", "named"), CASES, ids=[" ".join(argv[:4]) for argv, _ in CASES])
def test_a_mistake_ends_in_one_line_naming_it_exit_2_nothing_written(argv, named, tmp_path, monkeypatch,
                                                                       capsys):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    captured = capsys.readouterr()
    last = captured.err.strip().splitlines()[-1]
    assert "Traceback" not in captured.err and "Traceback" not in captured.out
    assert named in last, f"the message does not name {named!r}: {last}"
    assert last.startswith("uav-swarm"), last
    assert sorted(os.listdir(tmp_path)) == [], "something was written"


@pytest.mark.slow
@pytest.mark.parametrize("argv", [
    ["dataset", "--task", "wifi-s1", "--n", "-5", "--seed", "1", "--out", "out"],
    ["mission", "export", "--config", BRIDGE, "--plans", "missing.json", "--out", "out"],
])
def test_the_installed_command_answers_the_same(argv, tmp_path):
    done = subprocess.run([sys.executable, "-m", "uav_swarm", *argv], cwd=tmp_path, capture_output=True,
                          text=True, timeout=120, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert done.returncode == 2
    assert "Traceback" not in done.stderr
    assert not (tmp_path / "out").exists()


def test_a_mission_file_that_is_no_plan_names_the_file(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    plans = tmp_path / "plans.json"
    plans.write_text(json.dumps({"1": "north"}))
    assert main(["mission", "export", "--config", BRIDGE, "--plans", str(plans), "--out", "out"]) == 2
    assert f"--plans {plans}: vehicle 1" in capsys.readouterr().err
    assert sorted(os.listdir(tmp_path)) == ["plans.json"]


def _with_typo(shipped: str, table: str, line: str) -> str:
    """A shipped config with one more line at the start of one of its tables (its header may be commented)."""
    text = (ROOT / shipped).read_text(encoding="utf-8")
    header = re.compile(rf"^{re.escape(table)}[ \t]*(#.*)?$", re.MULTILINE)
    assert header.search(text), f"{shipped} has no {table}"
    return header.sub(lambda found: f"{found[0]}\n{line}", text, count=1)


SIMULATE = "configs/simulate/wifi-s2-80211.toml"
# (argv before --config FILE, the file's text, the full key named, the key suggested, the table's own keys)
TYPOS = [
    (["simulate", "--out", "out"], _with_typo(SIMULATE, "[task.radio.ieee80211]", "chanels = [36]"),
     "task.radio.ieee80211.chanels", "task.radio.ieee80211.channels", "in [task.radio.ieee80211]"),
    (["simulate", "--out", "out"], _with_typo(SIMULATE, "[task]", "duraton_s = 3"),  # in the wrong table
     "task.duraton_s", "duration_s", "in [task]"),
    (["simulate", "--out", "out"], "duraton_s = 3\n", "duraton_s", "duration_s", "are ['bridge_config'"),
    (["fly", "--bridge-config", BRIDGE, "--out", "out"], "[flight]\nend_actoin = 'land'\n",
     "flight.end_actoin", "flight.end_action", "in [flight]"),
    (["telemetry", "watch"], "[telemetry]\nscouting = true\n", "telemetry.scouting",
     "telemetry.multicast_scouting", "in [telemetry]"),
    (["evaluate", "--task", "wifi-s1", "--checkpoint", S1, *GEN], "[task.radio]\nprpagation = 'paper'\n",
     "task.radio.prpagation", "task.radio.propagation", "in [task.radio]"),
    (["mission", "export", "--target", "1:4,2", "--out", "out"],
     _with_typo("configs/bridge/px4_sitl_10.toml", "[geofence]", "alt_max = 50"), "geofence.alt_max",
     "geofence.alt_max_m", "in [geofence]"),
]

@pytest.mark.parametrize(("argv", "text", "key", "suggestion", "table"), TYPOS,
                         ids=[f"{argv[0]} {key}" for argv, _, key, _, _ in TYPOS])
def test_a_mistyped_config_key_at_any_depth_is_named_by_its_full_key(argv, text, key, suggestion, table,
                                                                      tmp_path, monkeypatch, capsys):
    config = tmp_path / "config" / "mine.toml"
    config.parent.mkdir()
    config.write_text(text, encoding="utf-8")
    (tmp_path / "run").mkdir()
    monkeypatch.chdir(tmp_path / "run")
    assert main([*argv, "--config", str(config)]) == 2
    captured = capsys.readouterr()
    (line,) = captured.err.strip().splitlines()
    assert line.startswith(f"uav-swarm {argv[0]}") and f" {config}: " in line, line
    assert f"unknown key(s) [{key!r}] (did you mean {suggestion!r}?); allowed keys {table}" in line, line
    assert "Config" not in line, line  # the file's keys, not the classes that read them
    assert os.listdir(tmp_path / "run") == [], "something was written"
