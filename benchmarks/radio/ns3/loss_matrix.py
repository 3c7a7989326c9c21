"""The path loss ns-3 is given: every pair of radios of a scene, in dB, from the project's 802.11 model.

UAV to user: Al-Hourani's air-to-ground loss (the model's ``station_power_mw``); UAV to UAV: free space
(``ap_pair_power_dbm``); user to user (only ns-3 needs it: stations send block acknowledgements): the
air-to-ground formula at zero height, i.e. free space plus almost all of the NLoS excess. Positions are
``(x_m, y_m, height_m)`` with users at height 0 and UAVs at their altitude above the users.

The model's functions take a :class:`~uav_swarm.world.wifi.config.Ieee80211Config`; :data:`RADIO` lists the
settings every scene uses (the model's defaults: channel 36's 5.18 GHz for the path loss, 20 dBm, 0 dBi
antennas, 7 dB noise figure, Al-Hourani's urban environment).
"""

from __future__ import annotations

import math

import numpy as np

from uav_swarm.world.wifi.config import Ieee80211Config
from uav_swarm.world.wifi.phy import ap_pair_power_dbm, station_power_mw

RADIO: dict[str, float | str] = {"environment": "urban", "frequency_ghz": 5.18, "tx_power_dbm": 20.0,
                                 "noise_figure_db": 7.0}
CONFIG = Ieee80211Config(environment="urban", frequency_ghz=5.18, tx_power_dbm=20.0, noise_figure_db=7.0)
NOISE_20MHZ_DBM = -174.0 + 10.0 * math.log10(20e6) + float(RADIO["noise_figure_db"])


def link_loss_db(a_m: np.ndarray, b_m: np.ndarray) -> float:
    """Path loss (dB) between two radios at ``(x_m, y_m, height_m)``: the model's powers, less its EIRP."""
    if a_m[2] > 0.0 and b_m[2] > 0.0:
        uavs_m = np.array([[a_m[:2], b_m[:2]]], dtype=float)
        power_dbm = ap_pair_power_dbm(uavs_m, np.array([[a_m[2], b_m[2]]], dtype=float), CONFIG)[0, 0, 1]
        return float(CONFIG.tx_power_dbm + 2.0 * CONFIG.ap_antenna_gain_dbi - power_dbm)
    low, high = (a_m, b_m) if a_m[2] <= b_m[2] else (b_m, a_m)  # the user, and the UAV (or the other user)
    power_mw = station_power_mw(np.array([low[:2]], dtype=float), np.zeros(1, np.int64),
                                np.array([[high[:2]]], dtype=float), np.array([[high[2] - low[2]]]), CONFIG)
    eirp_dbm = CONFIG.tx_power_dbm + CONFIG.ap_antenna_gain_dbi + CONFIG.station_antenna_gain_dbi
    return float(eirp_dbm - 10.0 * np.log10(power_mw[0, 0]))


def scene_positions_m(scene: dict) -> np.ndarray:
    """``(K + U, 3)`` positions: the UAVs first, then the users at height 0."""
    users = np.column_stack([np.asarray(scene["users_m"], float), np.zeros(len(scene["users_m"]))])
    return np.vstack([np.asarray(scene["uavs_m"], float), users])


def loss_matrix_db(scene: dict) -> np.ndarray:
    """``(N, N)`` symmetric path loss (dB) between every pair of radios of the scene (0 on the diagonal)."""
    positions = scene_positions_m(scene)
    n = len(positions)
    loss = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1, n):
            loss[i, j] = loss[j, i] = link_loss_db(positions[i], positions[j])
    return loss
