"""The compiled received power of all worlds' users against the whole-array numpy formula it replaced."""

import math

import numpy as np
import pytest

from uav_swarm.world.wifi.config import Ieee80211Config
from uav_swarm.world.wifi.phy import station_power_mw

SPEED_OF_LIGHT_M_S = 299_792_458.0
TOLERANCE = 1e-13
"""Relative: numba's and numpy's ``exp`` and ``arctan2`` may differ in the last bit on some processors."""


def reference_power_mw(users_m, uavs_m, heights_m, config):
    """One world's (n, K) powers as numpy computed them, pass by pass over the whole array."""
    a, b, eta_los_db, eta_nlos_db = config.environment_parameters
    eirp_dbm = config.tx_power_dbm + config.ap_antenna_gain_dbi + config.station_antenna_gain_dbi
    fspl_1m_db = 20.0 * math.log10(config.frequency_ghz * 1e9) + 20.0 * math.log10(4.0 * math.pi
                                                                                   / SPEED_OF_LIGHT_M_S)
    to_neper = math.log(10.0) / 10.0
    dx = uavs_m[:, 0] - users_m[:, 0:1]
    dy = uavs_m[:, 1] - users_m[:, 1:2]
    horizontal_sq = dx * dx + dy * dy
    distance_sq = np.maximum(horizontal_sq + heights_m * heights_m, 1.0)
    elevation = np.arctan2(np.broadcast_to(heights_m, horizontal_sq.shape), np.sqrt(horizontal_sq))
    los = 1.0 / (np.exp(elevation * (-b * 180.0 / math.pi) + (math.log(a) + a * b)) + 1.0)
    return np.exp(los * ((eta_nlos_db - eta_los_db) * to_neper)
                  + (eirp_dbm - fspl_1m_db - eta_nlos_db) * to_neper) / distance_sq


@pytest.mark.parametrize("environment", ["suburban", "urban", "dense urban", "high-rise urban"])
def test_every_world_gets_the_reference_power(environment):
    config = Ieee80211Config(environment=environment)
    rng = np.random.default_rng(len(environment))
    counts = rng.integers(0, 300, 16)
    copy = np.repeat(np.arange(16), counts)
    users = rng.uniform(0, 200, (len(copy), 2))
    users[:5] = [[0.0, 0.0], [0.2, 0.1], [200.0, 200.0], [100.0, 100.0], [50.0, 50.0]]  # under a UAV too
    uavs = rng.uniform(0, 200, (16, 10, 2))
    uavs[0, 0] = users[0]
    heights = rng.uniform(0.5, 60, (16, 10))
    power = station_power_mw(users, copy, uavs, heights, config)
    assert power.shape == (len(copy), 10)
    for c in range(16):
        rows = copy == c
        np.testing.assert_allclose(power[rows], reference_power_mw(users[rows], uavs[c], heights[c], config),
                                   rtol=TOLERANCE, atol=0.0)
        alone = station_power_mw(users[rows], np.zeros(rows.sum(), np.int64), uavs[c:c + 1], heights[c:c + 1],
                                 config)
        np.testing.assert_array_equal(alone, power[rows])  # a world alone gets its numbers in a batch
