"""The project's 802.11 model on a calibration scene, and the ns-3 result of the same scene, side by side.

The model runs as ``simulate`` runs it (:func:`uav_swarm.world.wifi.coverage.wifi_links`) with the settings
ns-3 was given (:data:`loss_matrix.RADIO`, the scene's channel width and channels, each UAV's altitude) and,
to compare like with like, **throughput fairness** (ns-3's access point queues serve every station the same
throughput at saturation) and no admission on rate (every user of the scene is a station in ns-3). The model
associates by itself (strongest signal); :func:`model_scene` checks that it picks the scene's serving UAVs.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from loss_matrix import RADIO, loss_matrix_db

from uav_swarm.world.comms import RadioConfig
from uav_swarm.world.wifi.config import Ieee80211Config
from uav_swarm.world.wifi.coverage import wifi_links


@dataclass(frozen=True)
class Ns3Scene:
    """ns-3's result of one scene over its seeds.

    Attributes:
        station_mbps: (R, U) throughput of each station in each seed.
        ap_mbps: (R, K) total of each AP in each seed.
        mcs: (U,) the MCS that carried most of each station's data PPDUs (all seeds), -1 for none.
        wall_s: Seconds of simulation per seed (after the import).
        guard_interval_us: The guard interval ns-3 ran with.
    """

    station_mbps: np.ndarray
    ap_mbps: np.ndarray
    mcs: np.ndarray
    wall_s: list[float]
    guard_interval_us: float


def load_ns3(path: Path, scene: dict) -> Ns3Scene:
    """Read ``results/<name>.json``; refuse a result whose path loss is not the model's (regenerate it).

    Raises:
        ValueError: The result's loss matrix differs from the model's by more than 0.01 dB.
    """
    result = json.loads(path.read_text(encoding="utf-8"))
    gap_db = float(np.abs(np.asarray(result["job"]["loss_db"]) - loss_matrix_db(scene)).max())
    if gap_db > 0.01:
        raise ValueError(f"{path}: its path loss differs from the model's by {gap_db:.3f} dB: "
                         "rerun run_ns3.py")
    n_uavs = len(scene["uavs_m"])
    serving = np.asarray(scene["serving_uav"])
    stations = np.array([[s["throughput_mbps"] for s in run["stations"]] for run in result["runs"]])
    per_ap = np.stack([np.bincount(serving, weights=row, minlength=n_uavs) for row in stations])
    mcs = []
    for u in range(len(serving)):
        counts: dict[int, int] = {}
        for run in result["runs"]:
            for m, (ppdus, _) in run["stations"][u]["data_ppdus_by_mcs"].items():
                counts[int(m)] = counts.get(int(m), 0) + ppdus
        mcs.append(max(counts, key=lambda m: counts[m]) if counts else -1)
    return Ns3Scene(stations, per_ap, np.asarray(mcs), [run["wall_s"] for run in result["runs"]],
                    result["job"]["guard_interval_ns"] / 1000.0)


@dataclass(frozen=True)
class ModelScene:
    """The model's view of one scene.

    Attributes:
        station_mbps: (U,) each station's throughput.
        ap_mbps: (K,) each AP's total.
        sinr_db: (U,) SINR at the serving AP.
        mcs: (U,) the model's MCS.
        airtime: (K,) each AP's airtime share.
    """

    station_mbps: np.ndarray
    ap_mbps: np.ndarray
    sinr_db: np.ndarray
    mcs: np.ndarray
    airtime: np.ndarray


def radio_config(width_mhz: int, tables_file: str = "", mac_efficiency: float | None = None,
                 guard_interval_us: float = 0.8) -> RadioConfig:
    """The model's settings for the calibration (throughput fairness, no admission on rate)."""
    return RadioConfig(propagation="802.11", ieee80211=Ieee80211Config(
        environment=str(RADIO["environment"]), frequency_ghz=float(RADIO["frequency_ghz"]),
        tx_power_dbm=float(RADIO["tx_power_dbm"]), noise_figure_db=float(RADIO["noise_figure_db"]),
        channel_width_mhz=width_mhz, fairness="throughput", rate_admission=False,
        mac_efficiency=mac_efficiency, tables_file=tables_file, guard_interval_us=guard_interval_us))


def model_scene(scene: dict, tables_file: str = "", mac_efficiency: float | None = None,
                guard_interval_us: float = 0.8) -> ModelScene:
    """Run the model on the scene.

    Raises:
        ValueError: The model associates a user elsewhere than the scene's serving UAV (a user it leaves
            without a usable rate gets 0, as the model says).
    """
    uavs = np.asarray(scene["uavs_m"], dtype=float)
    users = np.asarray(scene["users_m"], dtype=float)
    links = wifi_links(users, np.zeros(len(users), np.int64), uavs[None, :, :2],
                       radio_config(scene["width_mhz"], tables_file, mac_efficiency, guard_interval_us),
                       altitudes_m=uavs[:, 2], channels=np.asarray(scene["channels"]))
    serving = np.asarray(scene["serving_uav"])
    wrong = np.flatnonzero((links.association >= 0) & (links.association != serving)).tolist()
    if wrong:
        raise ValueError(f"{scene['name']}: the model associates users {wrong} elsewhere than the scene")
    per_ap = np.bincount(serving, weights=links.throughput_mbps, minlength=len(uavs))
    return ModelScene(links.throughput_mbps, per_ap, links.sinr_db, links.mcs, links.airtime[0])
