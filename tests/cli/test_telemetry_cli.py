"""`uav-swarm telemetry`: arguments and config files (live runs: tests/bridge/test_telemetry.py)."""

from __future__ import annotations

import argparse

import pytest

from typed_config import ConfigError
from uav_swarm.cli import telemetry


def parse(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    telemetry.register(parser.add_subparsers())
    return parser.parse_args(["telemetry", *argv])


def test_watcher_defaults_connect_to_the_local_publisher_without_listening():
    config = telemetry._config(parse("watch"))
    assert config.listen == () and config.connect == ("tcp/127.0.0.1:7447",)
    assert config.mode == "peer" and not config.multicast_scouting


def test_toml_keys_override_defaults_and_flags_override_both(tmp_path):
    path = tmp_path / "watch.toml"
    path.write_text('[telemetry]\nswarm = "field"\nconnect = ["tcp/127.0.0.1:7500"]\ntimeout_s = 5.0\n')
    config = telemetry._config(parse("record", "--out", str(tmp_path / "x.jsonl"), "--config", str(path),
                                     "--connect", "tcp/127.0.0.1:7600"))
    assert (config.swarm, config.connect, config.listen, config.timeout_s) == (
        "field", ("tcp/127.0.0.1:7600",), (), 5.0)


@pytest.mark.parametrize(("text", "message"), [
    ('[telemetry]\nscouting = true\n', "unknown key"),
    ('[telemetry]\nconnect = ["http/127.0.0.1:80"]\n', "must start with one of"),
    ("[other]\n", r"missing table \[telemetry\]"),
    ("[telemetry\n", "invalid TOML"),
])
def test_bad_config_files_are_config_errors(tmp_path, text, message):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=message):
        telemetry._config(parse("watch", "--config", str(path)))


@pytest.mark.parametrize("flag", ["--count", "--duration-s"])
def test_non_positive_bounds_are_refused(flag, capsys):
    with pytest.raises(SystemExit) as exit_info:
        parse("watch", flag, "0")
    assert exit_info.value.code == 2
    assert f"argument {flag}: 0 is out of range" in capsys.readouterr().err


def test_ctrl_c_ends_a_recording_and_keeps_the_file(tmp_path):
    """``telemetry record`` without a bound runs until Ctrl-C: its normal end, exit 0, the file written."""
    import os
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    from ports import free_tcp_port

    out = tmp_path / "run.jsonl"
    repo = Path(__file__).resolve().parents[2]
    argv = [sys.executable, "-m", "uav_swarm", "telemetry", "record", "--out", str(out), "--connect",
            f"tcp/127.0.0.1:{free_tcp_port()}"]  # nobody publishes there: the file stays empty
    path = os.pathsep.join(filter(None, (str(repo), os.environ.get("PYTHONPATH"))))
    env = {**os.environ, "PYTHONPATH": path}
    process = subprocess.Popen(argv, stderr=subprocess.PIPE, text=True, env=env, cwd=tmp_path)
    try:
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline and not any(p.name.endswith(".tmp") for p in tmp_path.iterdir()):
            time.sleep(0.1)  # recording: its partial file is open
        process.send_signal(signal.SIGINT)
        _, err = process.communicate(timeout=30)
    finally:
        process.kill()
    assert process.returncode == 0, err
    assert out.read_text() == "" and f"recorded 0 messages to {out}" in err
