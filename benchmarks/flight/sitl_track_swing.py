"""How far a real ArduCopter (SITL) flies from the straight segment it is sent along, in GUIDED.

One ArduCopter 4.6 SITL instance (its default parameters: ``WPNAV_SPEED``, ``WPNAV_ACCEL``, ``PSC_JERK_XY``
as shipped) takes off to 20 m in GUIDED and is sent position targets (``SET_POSITION_TARGET_LOCAL_NED``,
position only, once each, as ``fly`` sends its points):

- **from rest**: hovering, sent a point 60-70 m away on a diagonal;
- **on the line**: flying toward a far point, sent, once at 7 m/s, a point 40 m ahead on the same line;
- **turned 30 / 60 / 90 degrees**: flying at 7 m/s, sent a point 50 m away in a direction that far off.

Its EKF position (LOCAL_POSITION_NED at 20 Hz, on its own link) gives, for each segment (from where it was
when the point was sent to the point), the largest distance across the segment's line (**swing**), the
furthest past its end (**overshoot**) and the lateral speed when it was sent; the same figures as
``track_swing.py`` gives for the simulated models.

Usage (through the SITL lock): flock /work/sitl/run.lock python benchmarks/flight/sitl_track_swing.py
       --ardupilot-dir /work/sitl/ap
"""

from __future__ import annotations

import argparse
import math
import os
import signal
import subprocess
import tempfile
import time
from pathlib import Path

from pymavlink import mavutil

_ALT_M = 20.0
_HOME = "-35.3633,149.165,584,0"


def _start(root: Path, work: Path) -> subprocess.Popen:
    (work / "sysid.parm").write_text("SYSID_THISMAV 1\n")
    defaults = root / "ardupilot/Tools/autotest/default_params/copter.parm"
    argv = [str(root / "ardupilot/build/sitl/bin/arducopter"), "--model", "+", "--speedup", "1", "-I0",
            "--wipe", "--defaults", f"{defaults},{work / 'sysid.parm'}", "--home", _HOME]
    log = (work / "arducopter.log").open("wb")
    env = {**os.environ, "LD_PRELOAD": str(root / "run/loopback_bind.so")}
    return subprocess.Popen(argv, cwd=work, env=env, stdout=log, stderr=subprocess.STDOUT,
                            stdin=subprocess.DEVNULL)


class _Vehicle:
    def __init__(self, url: str) -> None:
        self.link = mavutil.mavlink_connection(url, source_system=250)
        self.link.wait_heartbeat(timeout=60)
        self.state = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)  # n, e, d, vn, ve, vd
        self.armed = False
        for message_id, hz in ((32, 20.0), (0, 2.0)):
            self.link.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0, message_id,
                                            1e6 / hz, 0, 0, 0, 0, 0)

    def pump(self, seconds: float, track: list | None = None) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            msg = self.link.recv_match(blocking=True, timeout=0.05)
            if msg is None:
                continue
            kind = msg.get_type()
            if kind == "LOCAL_POSITION_NED":
                self.state = (msg.x, msg.y, msg.z, msg.vx, msg.vy, msg.vz)
                if track is not None:
                    track.append(self.state)
            elif kind == "HEARTBEAT" and msg.get_srcSystem() == 1:
                self.armed = bool(msg.base_mode & mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED)

    def command(self, command: int, *params: float) -> None:
        self.link.mav.command_long_send(1, 1, command, 0, *(list(params) + [0.0] * (7 - len(params))))

    def goto(self, n: float, e: float) -> None:
        self.link.mav.set_position_target_local_ned_send(0, 1, 1, mavutil.mavlink.MAV_FRAME_LOCAL_NED, 0x0DF8,
                                                         n, e, -_ALT_M, 0, 0, 0, 0, 0, 0, 0, 0)

    @property
    def speed(self) -> float:
        return math.hypot(self.state[3], self.state[4])


def _segment(vehicle: _Vehicle, name: str, target: tuple[float, float], log: list[str]) -> None:
    """Send ``target`` now and follow the flight until at rest there; record swing and overshoot."""
    n0, e0, _, vn, ve, _ = vehicle.state
    vehicle.goto(*target)
    track: list = []
    begun = time.monotonic()
    while time.monotonic() - begun < 60.0:
        vehicle.pump(0.5, track)
        there = math.hypot(vehicle.state[0] - target[0], vehicle.state[1] - target[1]) < 0.5
        if there and vehicle.speed < 0.3:
            break
    length = math.hypot(target[0] - n0, target[1] - e0)
    un, ue = (target[0] - n0) / length, (target[1] - e0) / length
    swing = max(abs(-(n - n0) * ue + (e - e0) * un) for n, e, *_ in track)
    overshoot = max((n - n0) * un + (e - e0) * ue - length for n, e, *_ in track)
    across = -vn * ue + ve * un
    line = (f"| {name} | {length:.1f} m | {math.hypot(vn, ve):.2f} m/s ({across:+.2f} across) | "
            f"{swing:.2f} m | {max(0.0, overshoot):.2f} m | {time.monotonic() - begun:.1f} s |")
    print(line, flush=True)
    log.append(line)


def _at_speed(vehicle: _Vehicle, far: tuple[float, float], speed: float) -> None:
    vehicle.goto(*far)
    begun = time.monotonic()
    while vehicle.speed < speed and time.monotonic() - begun < 30.0:
        vehicle.pump(0.05)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ardupilot-dir", type=Path, required=True)
    args = parser.parse_args()
    print(f"load {tuple(round(x, 2) for x in os.getloadavg())}", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        process = _start(args.ardupilot_dir, Path(tmp))
        try:
            time.sleep(2.0)
            vehicle = _Vehicle("tcp:127.0.0.1:5760")
            deadline = time.monotonic() + 180.0
            while not vehicle.armed and time.monotonic() < deadline:
                vehicle.command(mavutil.mavlink.MAV_CMD_DO_SET_MODE, 1, 4)  # GUIDED
                vehicle.command(mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
                vehicle.pump(2.0)
            vehicle.command(mavutil.mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, _ALT_M)
            while -vehicle.state[2] < _ALT_M - 0.5 and time.monotonic() < deadline + 60.0:
                vehicle.pump(0.5)
            vehicle.pump(3.0)
            print("| segment | length | speed when sent | swing | overshoot | flown |", flush=True)
            print("|---|---|---|---|---|---|", flush=True)
            log: list[str] = []
            _segment(vehicle, "from rest, diagonal", (60.0, 30.0), log)
            _at_speed(vehicle, (-200.0, 30.0), 7.0)
            n, e = vehicle.state[:2]
            _segment(vehicle, "on the line, 7 m/s", (n - 40.0, e), log)
            for turn in (30.0, 60.0, 90.0):
                n, e = vehicle.state[:2]
                _at_speed(vehicle, (n, e + 300.0), 7.0)  # east
                n, e = vehicle.state[:2]
                angle = math.radians(turn)
                _segment(vehicle, f"turned {turn:.0f} degrees at 7 m/s",
                         (n + 50.0 * math.sin(angle), e + 50.0 * math.cos(angle)), log)
                _segment(vehicle, "back home (from rest)", (0.0, 0.0), log)
        finally:
            if process.poll() is None:
                os.kill(process.pid, signal.SIGTERM)
                process.wait(timeout=10.0)
    print(f"load after {tuple(round(x, 2) for x in os.getloadavg())}", flush=True)


if __name__ == "__main__":
    main()
