"""The calibration scenes of the 802.11 model against ns-3, written as data (``scenes.json``), seeded.

Every scene is UAV access points (x, y, altitude above the users, channel) and users on the ground, each user
served by the UAV it receives strongest (the path loss of the project's model); users are placed only where
the serving UAV reaches them at 8 dB SNR or more (those under 12 dB, -82 dBm, are below ns-3's preamble
detection and never associate there: the edge of coverage is part of the test). The families, and which scenes
are fitted and which are held out (the split alternates inside each family, fixed here and written into the
file):

- ``single-*``: one UAV at 10 m, one user at a growing horizontal distance (5-100 m): the SINR -> MCS map;
- ``cell-*``: one UAV, 8-16 users in a disk (mixed rates: the performance anomaly), 20, 40 and 80 MHz;
- ``pair-co-*``: two UAVs 5-60 m apart on one channel, 8 users each: they share the airtime;
- ``pair-2ch-*``: the same pairs on two channels: each has the medium to itself;
- ``three-*`` and ``six-3ch``: three APs on one channel and on three; six APs on three channels;
- ``hidden-*``: co-channel UAVs at 30 m, 330-350 m apart in a line: neighbours hear each other (free space,
  -78 dBm), the next but one does not (-84 dBm): the AP in the middle of three defers to both ends;
- ``ten-*``: ten UAVs (altitude layers 10-28 m) over 120 m x 120 m, 20 users each, on one channel and on
  three (a greedy colouring);
- ``five-1ch-*``: five UAVs (altitude layers 10-18 m) over 80 m x 80 m, 12 users each, all on one channel (one
  contention domain: every AP hears every other). Added after the others, so that the earlier scenes keep
  their random draws.

Usage: python benchmarks/radio/ns3/scenes.py [--out benchmarks/radio/ns3/scenes.json] [--seed 2026]
"""

from __future__ import annotations

import argparse
import json
import math
import os
from pathlib import Path

import numpy as np
from loss_matrix import NOISE_20MHZ_DBM, RADIO, link_loss_db

HERE = Path(__file__).resolve().parent
MIN_SNR_DB = 8.0
"""Users are placed where their UAV reaches them at this SNR or more (20 MHz noise)."""


def _users_around(rng: np.random.Generator, uavs_m: np.ndarray, serving: int, n_users: int, radius_m: float
                  ) -> list[list[float]]:
    """``n_users`` ground positions within ``radius_m`` of UAV ``serving``, served by it at >= 8 dB."""
    users: list[list[float]] = []
    while len(users) < n_users:
        angle = rng.uniform(0.0, 2.0 * math.pi)
        r_m = radius_m * math.sqrt(rng.uniform())
        x_m = uavs_m[serving, 0] + r_m * math.cos(angle)
        y_m = uavs_m[serving, 1] + r_m * math.sin(angle)
        loss = [link_loss_db(np.array([x_m, y_m, 0.0]), uav) for uav in uavs_m]
        snr_db = RADIO["tx_power_dbm"] - loss[serving] - NOISE_20MHZ_DBM
        if int(np.argmin(loss)) == serving and snr_db >= MIN_SNR_DB:
            users.append([round(x_m, 2), round(y_m, 2)])
    return users


def _scene(name: str, family: str, uavs_m: list[list[float]], channels: list[int], users: list[list[float]],
           serving: list[int], width_mhz: int = 20, measure_s: float = 1.5) -> dict:
    return {"name": name, "family": family, "uavs_m": uavs_m, "channels": channels, "width_mhz": width_mhz,
            "users_m": users, "serving_uav": serving, "warmup_s": 0.5, "measure_s": measure_s}


def _cells(rng: np.random.Generator, name: str, family: str, uavs_m: list[list[float]], channels: list[int],
           users_per_uav: int, radius_m: float, width_mhz: int = 20, measure_s: float = 1.5) -> dict:
    uavs = np.asarray(uavs_m, dtype=float)
    users: list[list[float]] = []
    serving: list[int] = []
    for k in range(len(uavs_m)):
        users += _users_around(rng, uavs, k, users_per_uav, radius_m)
        serving += [k] * users_per_uav
    return _scene(name, family, uavs_m, channels, users, serving, width_mhz, measure_s)


def _greedy_channels(uavs_m: np.ndarray, plan: list[int]) -> list[int]:
    """Each UAV in turn takes the plan's channel used least among its nearest already-coloured UAVs."""
    channels: list[int] = []
    for k in range(len(uavs_m)):
        distance = np.linalg.norm(uavs_m[:k] - uavs_m[k], axis=1)
        cost = [sum(1.0 / (1.0 + d) for d, c in zip(distance, channels, strict=True) if c == ch)
                for ch in plan]
        channels.append(plan[int(np.argmin(cost))])
    return channels


def build_scenes(seed: int) -> list[dict]:
    """All scenes, in the order they are run (small first)."""
    rng = np.random.default_rng(seed)
    scenes: list[dict] = []
    for r_m in (5, 15, 25, 35, 45, 60, 80, 100):
        scenes.append(_scene(f"single-{r_m}m", "single", [[0.0, 0.0, 10.0]], [36], [[float(r_m), 0.0]], [0]))
    scenes.append(_cells(rng, "cell-8-r30", "cell", [[0.0, 0.0, 10.0]], [36], 8, 30.0))
    scenes.append(_cells(rng, "cell-8-r60", "cell", [[0.0, 0.0, 10.0]], [36], 8, 60.0))
    scenes.append(_cells(rng, "cell-16-r40-alt20", "cell", [[0.0, 0.0, 20.0]], [36], 16, 40.0))
    scenes.append(_cells(rng, "cell-8-r30-40mhz", "cell", [[0.0, 0.0, 10.0]], [38], 8, 30.0, width_mhz=40))
    scenes.append(_cells(rng, "cell-8-r30-80mhz", "cell", [[0.0, 0.0, 10.0]], [42], 8, 30.0, width_mhz=80))
    for d_m in (5, 10, 20, 30, 45, 60):
        scenes.append(_cells(rng, f"pair-co-{d_m}m", "pair-co", [[0.0, 0.0, 10.0], [float(d_m), 0.0, 10.0]],
                             [36, 36], 8, 30.0))
    for d_m in (5, 20, 60):
        scenes.append(_cells(rng, f"pair-2ch-{d_m}m", "pair-2ch", [[0.0, 0.0, 10.0], [float(d_m), 0.0, 10.0]],
                             [36, 40], 8, 30.0))
    triangle = [[0.0, 0.0, 10.0], [15.0, 0.0, 10.0], [7.5, 13.0, 10.0]]
    scenes.append(_cells(rng, "three-1ch", "three", triangle, [36, 36, 36], 8, 25.0))
    scenes.append(_cells(rng, "three-3ch", "three", triangle, [36, 40, 44], 8, 25.0))
    six = [[x_m, y_m, 10.0] for y_m in (0.0, 30.0) for x_m in (0.0, 30.0, 60.0)]
    scenes.append(_cells(rng, "six-3ch", "three", six, [36, 40, 44, 44, 36, 40], 6, 25.0))
    line3 = [[0.0, 0.0, 30.0], [350.0, 0.0, 30.0], [700.0, 0.0, 30.0]]
    scenes.append(_cells(rng, "hidden-3", "hidden", line3, [36, 36, 36], 6, 40.0))
    line4 = [[0.0, 0.0, 30.0], [330.0, 0.0, 30.0], [660.0, 0.0, 30.0], [990.0, 0.0, 30.0]]
    scenes.append(_cells(rng, "hidden-4", "hidden", line4, [36, 36, 36, 36], 6, 40.0))
    for name, plan in (("ten-1ch", [36]), ("ten-3ch", [36, 40, 44])):
        uavs = np.column_stack([rng.uniform(0.0, 120.0, 10), rng.uniform(0.0, 120.0, 10),
                                10.0 + 2.0 * np.arange(10)])
        uavs_m = np.round(uavs, 2).tolist()
        scenes.append(_cells(rng, name, "ten", uavs_m, _greedy_channels(uavs, plan), 20, 35.0, measure_s=1.0))
    for name in ("five-1ch-a", "five-1ch-b"):
        uavs = np.column_stack([rng.uniform(0.0, 80.0, 5), rng.uniform(0.0, 80.0, 5),
                                10.0 + 2.0 * np.arange(5)])
        scenes.append(_cells(rng, name, "five", np.round(uavs, 2).tolist(), [36] * 5, 12, 30.0))
    by_family: dict[str, int] = {}
    for scene in scenes:
        n = by_family.get(scene["family"], 0)
        scene["split"] = "fit" if n % 2 == 0 else "test"
        by_family[scene["family"]] = n + 1
    return scenes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=HERE / "scenes.json")
    parser.add_argument("--seed", type=int, default=2026)
    args = parser.parse_args()
    document = {"schema": 1, "seed": args.seed, "radio": RADIO, "scenes": build_scenes(args.seed)}
    tmp = args.out.with_suffix(".tmp")
    tmp.write_text(json.dumps(document, indent=1) + "\n", encoding="utf-8")
    os.replace(tmp, args.out)
    print(f"{len(document['scenes'])} scenes -> {args.out}")


if __name__ == "__main__":
    main()
