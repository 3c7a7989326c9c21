"""Ctrl-C during ``fly`` ends the flight safely, keeps what it wrote, says it was interrupted, exits 130.

A real process (``python -m uav_swarm fly --simulated ardupilot``, its fleet on loopback) gets SIGINT
once it says it is flying, as a user's Ctrl-C; nothing here depends on how fast the machine is.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys


def test_ctrl_c_in_flight_keeps_the_flight_and_exits_130(tmp_path):
    config = tmp_path / "fly.toml"
    config.write_text("status_every_s = 0.5\n", encoding="utf-8")
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    argv = [sys.executable, "-m", "uav_swarm", "fly", "--simulated", "ardupilot", "--n-uavs", "2",
            "--planner", "expert", "--duration-s", "600", "--no-telemetry", "--config", str(config),
            "--out", str(out)]
    with subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          env=env) as process:
        assert process.stdout is not None
        seen = []
        for line in process.stdout:
            seen.append(line)
            if "flying (" in line:  # the status line of the loop: the vehicles are in the air
                process.send_signal(signal.SIGINT)
                break
        rest = process.stdout.read()
        code = process.wait()
    text = "".join(seen) + rest
    assert code == 130, text[-2000:]
    assert "uav-swarm fly: interrupted (Ctrl-C) after" in text
    assert "next:" not in text  # an interrupted flight suggests nothing
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert 0.0 < summary["duration_s"] < 600.0
    assert {"qos.png", "track.png", "track.csv", "timeseries.csv"} <= {p.name for p in out.iterdir()}
