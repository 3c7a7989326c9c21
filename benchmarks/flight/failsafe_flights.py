"""Are the vehicles' own failsafe flights separated? Ground-side faults in cruise, judged by true tracks.

Each run starts ``--n`` simulated vehicles of one autopilot (the packaged fleet's ArduCopter-like or
PX4-like vehicle, link-loss failsafe set to RTL, swift limits so that a run stays short) on random homes
(drawn at least ``--spacing-m`` apart in a square), starts ``uav-swarm fly`` on them as its own process
(seeded), and once every vehicle flies its targets in guided flight waits a random time and then
(``--scenario``):

- ``kill``: kills ``fly`` with SIGKILL (1-15 s after cruise): every vehicle loses its ground station at once;
- ``cut``: cuts every vehicle's link both ways at once (1-15 s after cruise; ``fly`` goes on running);
- ``silent-end``: ``fly`` flies ``--duration-s`` and ends (the RTLs it sends, ordered by its return rule),
  one random vehicle's link cut 1-20 s after cruise, before that end.

The judge is the vehicles' own true tracks (:attr:`ArduCopter.track`, one row per telemetry step, 20 Hz,
interpolated on a 10 ms clock): each vehicle that lost its link must be in RTL within its link-loss timeout
(PX4: ``COM_DL_LOSS_T`` + ``COM_FAIL_ACT_T``; its own 2.5 s heartbeat timeout is inside the 5 s) + 5 s, every
vehicle must land, and the closest pair (3-D) from take-off until the last has landed must keep ``[uav]
min_separation_m`` (5 m).

Usage: python benchmarks/flight/failsafe_flights.py --autopilot ardupilot --scenario kill --runs 20
       [--seed 62] [--n 5] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from bridge.geo import Home, enu_to_geodetic, geodetic_to_enu
from bridge.simulated.ardupilot import FAILSAFE_ON as ARDUPILOT_FAILSAFE
from bridge.simulated.ardupilot import GUIDED, ArduCopter
from bridge.simulated.fleet import free_udp_port
from bridge.simulated.peer import endpoint_pair
from bridge.simulated.px4 import FAILSAFE_ON as PX4_FAILSAFE
from bridge.simulated.px4 import LOITER, RTL, Px4Copter, px4_mode

REPO = Path(__file__).resolve().parents[2]
MIN_M = 5.0
SWIFT = {"ardupilot": {"WPNAV_SPEED": 1000.0, "WPNAV_ACCEL": 500.0, "WPNAV_SPEED_UP": 500.0,
                       "WPNAV_SPEED_DN": 500.0, "WPNAV_ACCEL_Z": 500.0, "PSC_JERK_XY": 20.0},
         "px4": {"MPC_XY_CRUISE": 10.0, "MPC_XY_VEL_MAX": 12.0, "MPC_ACC_HOR": 5.0, "MPC_JERK_AUTO": 20.0,
                 "MPC_TKO_SPEED": 5.0, "MPC_Z_V_AUTO_UP": 5.0, "MPC_Z_V_AUTO_DN": 5.0,
                 "MPC_ACC_UP_MAX": 5.0, "MPC_ACC_DOWN_MAX": 5.0}}


def random_homes(rng: np.random.Generator, n: int, spacing_m: float,
                 side_m: float) -> list[tuple[float, float]]:
    """``n`` points of a ``side_m`` square, each at least ``spacing_m`` from the others (rejection)."""
    while True:
        points: list[tuple[float, float]] = []
        for _ in range(2000):
            p = (float(rng.uniform(0, side_m)), float(rng.uniform(0, side_m)))
            if all(math.dist(p, q) >= spacing_m for q in points):
                points.append(p)
                if len(points) == n:
                    return points


def _toml(path: Path, urls: list[str]) -> None:
    lines = ["[geofence]", "x_min_m = -50.0", "y_min_m = -50.0", "x_max_m = 300.0", "y_max_m = 300.0",
             "[protocol]", "handshake_timeout_s = 1.0", "item_timeout_s = 0.3", "max_retries = 5"]
    for sid, url in enumerate(urls, start=1):
        lines += ["[[vehicles]]", f"system_id = {sid}", f'url = "{url}"']
    path.write_text("\n".join(lines) + "\n")


def _in_cruise(vehicles: list[ArduCopter]) -> bool:
    def guided(v: ArduCopter) -> bool:
        return (px4_mode(v.custom_mode) == LOITER) if isinstance(v, Px4Copter) else v.custom_mode == GUIDED
    return all(v.armed and v.enu[2] > 8.0 and v.reposition_target is not None and guided(v) for v in vehicles)


def _in_rtl(v: ArduCopter) -> bool:
    return px4_mode(v.custom_mode) == RTL if isinstance(v, Px4Copter) else v.custom_mode == 6


def closest_m(vehicles: list[ArduCopter], step_s: float = 0.01) -> tuple[float, tuple[int, int]]:
    """Closest 3-D approach of every pair over their common tracks (one frame, interpolated)."""
    origin = Home()
    tracks = []
    for v in vehicles:
        offset = np.array(geodetic_to_enu(origin, v.geo_home.lat_deg, v.geo_home.lon_deg, v.geo_home.alt_m))
        rows = np.array(list(v.track), dtype=np.float64)
        tracks.append(np.column_stack([rows[:, 0], rows[:, 1:4] + offset]))
    clock = np.arange(max(t[0, 0] for t in tracks), min(t[-1, 0] for t in tracks), step_s)
    points = np.stack([np.column_stack([np.interp(clock, t[:, 0], t[:, c]) for c in (1, 2, 3)])
                       for t in tracks])
    best, pair = math.inf, (-1, -1)
    for i in range(len(vehicles)):
        for j in range(i + 1, len(vehicles)):
            gap = float(np.linalg.norm(points[i] - points[j], axis=1).min())
            if gap < best:
                best, pair = gap, (vehicles[i].system_id, vehicles[j].system_id)
    return best, pair


def _timeout_s(v: ArduCopter) -> float:
    """Its link-loss timeout: from the last heartbeat heard to its failsafe's action."""
    if isinstance(v, Px4Copter):
        return v.param("COM_DL_LOSS_T") + v.param("COM_FAIL_ACT_T")  # its 2.5 s heartbeat timeout not added
    return v.param("FS_GCS_TIMEOUT")


def one_run(autopilot: str, n: int, rng: np.random.Generator, spacing_m: float, work: Path,
            scenario: str = "kill", duration_s: float = 30.0, return_timeout_s: float = 120.0) -> dict:
    """One flight with the scenario's fault in cruise; the judge's figures."""
    homes = random_homes(rng, n, spacing_m, side_m=40.0)
    cls, failsafe = (Px4Copter, PX4_FAILSAFE) if autopilot == "px4" else (ArduCopter, ARDUPILOT_FAILSAFE)
    vehicles, urls = [], []
    for sid, (x, y) in enumerate(homes, start=1):
        vehicle_url, gcs_url = endpoint_pair("udpin", free_udp_port())
        lat, lon, _ = enu_to_geodetic(Home(), x, y, 0.0)
        vehicles.append(cls(vehicle_url, sid, home=Home(lat_deg=lat, lon_deg=lon, alt_m=Home().alt_m),
                            params=failsafe | SWIFT[autopilot],
                            rng=np.random.default_rng(int(rng.integers(1 << 31))), position_period_s=0.05))
        urls.append(gcs_url)
    toml = work / "bridge.toml"
    _toml(toml, urls)
    (work / "fly.toml").write_text(f"[guard]\nreturn_timeout_s = {return_timeout_s}\n")
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    argv = [sys.executable, "-m", "uav_swarm", "fly", "--bridge-config", str(toml), "--out",
            str(work / "out"), "--duration-s", str(duration_s if scenario == "silent-end" else 600.0),
            "--no-telemetry", "--config", str(work / "fly.toml"), "--wait-ready-s", "60", "--seed",
            str(int(rng.integers(1000)))]
    process = subprocess.Popen(argv, env=env, cwd=str(REPO), stdout=subprocess.DEVNULL,
                               stderr=subprocess.PIPE, text=True)
    result: dict = {"homes_m": [[round(x, 1), round(y, 1)] for x, y in homes]}
    try:
        deadline = time.monotonic() + 240.0
        while not _in_cruise(vehicles) and process.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        if not _in_cruise(vehicles):
            exited = process.poll() is not None
            if not exited:
                process.kill()
            said = process.communicate(timeout=10)[1][-600:]
            result["error"] = f"never in cruise ({'fly exited' if exited else 'timeout'}): {said}"
            return result
        wait_s = float(rng.uniform(1.0, 20.0 if scenario == "silent-end" else 15.0))
        time.sleep(wait_s)
        lost = vehicles
        if scenario == "kill":
            process.send_signal(signal.SIGKILL)
            process.wait(timeout=10)
        elif scenario == "cut":
            for v in vehicles:
                v.cut = True
        else:
            lost = [vehicles[int(rng.integers(n))]]
            lost[0].cut = True
            result["silent"] = lost[0].system_id
        fault_s = time.monotonic()
        result["returning_at_fault"] = sum(_in_rtl(v) for v in vehicles)  # silent-end: must be 0
        result["fault_after_cruise_s"] = round(wait_s, 2)
        deadline = time.monotonic() + 300.0
        while any(v.armed for v in vehicles) and time.monotonic() < deadline:
            time.sleep(0.1)
        result["failsafe_after_fault_s"] = {v.system_id: round(v.failsafes[0] - fault_s, 2) if v.failsafes
                                            else None for v in lost}
        result["in_time"] = all(v.failsafes and v.failsafes[0] - fault_s <= _timeout_s(v) + 5.0 for v in lost)
        result["all_landed"] = not any(v.armed for v in vehicles)
        result["all_rtl"] = all(_in_rtl(v) for v in vehicles)
        result["last_landed_after_fault_s"] = round(time.monotonic() - fault_s, 1)
        result["fly_exit"] = process.poll()  # silent-end: None, fly still waits for the silent vehicle
        result["closest_m"], result["pair"] = closest_m(vehicles)
        return result
    finally:
        if process.poll() is None:
            process.kill()
            process.wait(timeout=10)
        for v in vehicles:
            v.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--autopilot", choices=("ardupilot", "px4"), default="ardupilot")
    parser.add_argument("--scenario", choices=("kill", "cut", "silent-end"), default="kill")
    parser.add_argument("--duration-s", type=float, default=30.0, help="fly's duration (silent-end)")
    parser.add_argument("--return-timeout-s", type=float, default=120.0,
                        help="fly's [guard] return_timeout_s (its default 120 s)")
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--n", type=int, default=5)
    parser.add_argument("--seed", type=int, default=62)
    parser.add_argument("--spacing-m", type=float, default=8.0,
                        help="least home spacing (the launch spacing)")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    runs = []
    for k in range(args.runs):
        with tempfile.TemporaryDirectory() as tmp:
            run = one_run(args.autopilot, args.n, rng, args.spacing_m, Path(tmp), args.scenario,
                          args.duration_s, args.return_timeout_s)
        run["load"] = os.getloadavg()[0]
        runs.append(run)
        print(json.dumps({"run": k, **run}), flush=True)
    judged = [r for r in runs if "closest_m" in r]
    summary = {"autopilot": args.autopilot, "scenario": args.scenario, "runs": args.runs,
               "judged": len(judged), "seed": args.seed,
               "n": args.n, "return_timeout_s": args.return_timeout_s,
               "in_time": sum(bool(r["in_time"]) for r in judged),
               "landed": sum(bool(r["all_landed"]) for r in judged),
               "under_minimum": sum(r["closest_m"] < MIN_M for r in judged),
               "closest_m": min((r["closest_m"] for r in judged), default=None),
               "machine": f"{platform.machine()}, {os.cpu_count()} cores"}
    print(json.dumps(summary))
    if args.json:
        args.json.write_text(json.dumps({"summary": summary, "runs": runs}, indent=1))


if __name__ == "__main__":
    main()
