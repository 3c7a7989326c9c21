"""Run every calibration scene in ns-3 (one subprocess per scene), caching each result as JSON; resumable.

For each scene of ``scenes.json`` (in file order: the small ones first) whose result is not yet in
``--results`` (``<name>.json`` whose job equals the scene's job), it writes the ns-3 job (positions, the
path-loss matrix of :mod:`loss_matrix`, channels, seeds) and runs ``ns3_scene.py`` (small scenes several
to a process, one import of ns-3 for all) under ``--ns3-python`` (a Python with the PyPI ``ns3`` package,
the ``radio-calibration`` extra), optionally behind ``flock --lock`` and ``nice``
so that each scene waits for a shared CPU lock. A scene that fails or times out is reported and skipped;
the next run retries it.

``--guard-interval-ns`` sets 802.11ax's guard interval (800 by default, as the model's tables are fitted;
3200 is ns-3's own default); keep each guard interval's results in a directory of their own (``--results``).

Usage: python benchmarks/radio/ns3/run_ns3.py --ns3-python PYTHON [--lock FILE] [--only NAME ...]
       [--seeds 1 2 3] [--timeout-s 1800] [--batch-radios 60] [--guard-interval-ns 800] [--results DIR]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from loss_matrix import RADIO, loss_matrix_db, scene_positions_m

HERE = Path(__file__).resolve().parent
RATE_MANAGER = "ns3::IdealWifiManager"
GUARD_INTERVALS_NS = (800, 1600, 3200)
"""802.11ax's guard intervals; 800 unless told (the model's tables are fitted at 0.8 us)."""
OFFERED_OVER_PEAK = 1.4
"""Each AP is offered 1.4 times the top PHY rate of its width (saturated whatever the MCS)."""
PEAK_MBPS = {20: 143.4, 40: 286.8, 80: 600.4}


def job_of(scene: dict, seeds: list[int], guard_interval_ns: int = 800) -> dict:
    """The ns-3 job of a scene (everything ``ns3_scene.py`` reads)."""
    n_uavs = len(scene["uavs_m"])
    return {
        "name": scene["name"],
        "positions_m": scene_positions_m(scene).round(3).tolist(),
        "serving_ap": [-1] * n_uavs + [int(k) for k in scene["serving_uav"]],
        "channels": scene["channels"],
        "width_mhz": [scene["width_mhz"]] * n_uavs,
        "tx_power_dbm": RADIO["tx_power_dbm"],
        "guard_interval_ns": guard_interval_ns,
        "rate_manager": RATE_MANAGER,
        "offered_mbps_per_ap": round(OFFERED_OVER_PEAK * PEAK_MBPS[scene["width_mhz"]], 1),
        "warmup_s": scene["warmup_s"],
        "measure_s": scene["measure_s"],
        "seeds": seeds,
        "loss_db": loss_matrix_db(scene).round(4).tolist(),
    }


def _batches(jobs: list[dict], most_radios: int) -> list[list[dict]]:
    """Consecutive jobs grouped while their radios add up to at most ``most_radios`` (a big one alone)."""
    batches: list[list[dict]] = []
    radios = most_radios + 1
    for job in jobs:
        size = len(job["positions_m"])
        if radios + size > most_radios:
            batches.append([])
            radios = 0
        batches[-1].append(job)
        radios += size
    return batches


def _cached(path: Path, job: dict) -> bool:
    if not path.exists():
        return False
    try:
        return json.loads(path.read_text(encoding="utf-8"))["job"] == job
    except (json.JSONDecodeError, KeyError):
        return False


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ns3-python", required=True, help="a Python interpreter with the PyPI ns3 package")
    parser.add_argument("--scenes", type=Path, default=HERE / "scenes.json")
    parser.add_argument("--results", type=Path, default=HERE / "results")
    parser.add_argument("--lock", default="", help="run each scene behind `flock LOCK nice -n 10`")
    parser.add_argument("--only", nargs="*", default=[], help="scene names (default: all)")
    parser.add_argument("--seeds", nargs="+", type=int, default=[1, 2, 3])
    parser.add_argument("--timeout-s", type=float, default=1800.0, help="per batch")
    parser.add_argument("--batch-radios", type=int, default=60,
                        help="scenes run in one ns-3 process while their radios add up to at most this")
    parser.add_argument("--guard-interval-ns", type=int, default=800, choices=GUARD_INTERVALS_NS,
                        help="802.11ax guard interval (ns-3's default is 3200; the tables are fitted at 800)")
    args = parser.parse_args()
    scenes = json.loads(args.scenes.read_text(encoding="utf-8"))["scenes"]
    unknown = sorted(set(args.only) - {s["name"] for s in scenes})
    if unknown:
        print(f"--only: unknown scene(s) {unknown}; allowed: the names in {args.scenes}", file=sys.stderr)
        return 2
    args.results.mkdir(parents=True, exist_ok=True)
    pending = []
    for scene in scenes:
        if args.only and scene["name"] not in args.only:
            continue
        job = job_of(scene, args.seeds, args.guard_interval_ns)
        if _cached(args.results / f"{scene['name']}.json", job):
            print(f"{scene['name']}: cached", flush=True)
        else:
            pending.append(job)
    failed = []
    for batch in _batches(pending, args.batch_radios):
        names = [job["name"] for job in batch]
        with tempfile.TemporaryDirectory() as tmp:
            command = [args.ns3_python, str(HERE / "ns3_scene.py")]
            for job in batch:
                job_path = Path(tmp) / f"{job['name']}.json"
                job_path.write_text(json.dumps(job), encoding="utf-8")
                command += [str(job_path), str(args.results / f"{job['name']}.json")]
            if args.lock:
                command = ["flock", args.lock, "nice", "-n", "10", *command]
            started = time.perf_counter()
            try:
                done = subprocess.run(command, capture_output=True, text=True, timeout=args.timeout_s)
                lines = done.stdout.strip().splitlines() or done.stderr.strip().splitlines()
                tail = lines[-len(batch) * 3:]
            except subprocess.TimeoutExpired:
                tail = [f"timed out after {args.timeout_s} s"]
        missing = [job["name"] for job in batch if not _cached(args.results / f"{job['name']}.json", job)]
        print(f"{names}: {len(batch) - len(missing)} done in {time.perf_counter() - started:.0f} s "
              f"(with the wait for the lock)\n  " + "\n  ".join(tail), flush=True)
        failed += missing
    if failed:
        print(f"failed: {failed} (rerun to retry)")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
