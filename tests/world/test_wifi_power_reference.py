"""The compiled received power of all worlds' users against the whole-array numpy formula it replaced.

The compiled pass reads the elevation's share of the power from a table: within ``TABLE_ERROR_DB`` of the
formula, and the users served, their MCS and their throughput as with the formula itself.
"""

import math

import numpy as np
import pytest

from uav_swarm.env.batched import BatchedUAVSwarm
from uav_swarm.world.wifi import coverage
from uav_swarm.world.wifi.config import Ieee80211Config
from uav_swarm.world.wifi.phy import TABLE_ERROR_DB, station_power_mw

SPEED_OF_LIGHT_M_S = 299_792_458.0
TOLERANCE = 1e-13
"""Relative, below the users (the formula itself): numba's and numpy's ``exp`` and ``arctan2`` may differ in
the last bit on some processors."""


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


def error_db(power_mw, reference_mw):
    return np.abs(10.0 * np.log10(power_mw / reference_mw))


@pytest.mark.parametrize("environment", ["suburban", "urban", "dense urban", "high-rise urban"])
def test_every_world_gets_the_reference_power(environment):
    config = Ieee80211Config(environment=environment)
    rng = np.random.default_rng(len(environment))
    counts = rng.integers(0, 300, 16)
    copy = np.repeat(np.arange(16), counts)
    users = rng.uniform(0, 200, (len(copy), 2))
    users[:5] = [[0.0, 0.0], [0.2, 0.1], [200.0, 200.0], [100.0, 100.0], [50.0, 50.0]]  # under a UAV too
    users[-3:] = [[5000.0, 0.0], [0.0, 20000.0], [3.0, 4.0]]  # near the horizon
    uavs = rng.uniform(0, 200, (16, 10, 2))
    uavs[0, 0] = users[0]
    heights = rng.uniform(0.5, 60, (16, 10))
    heights[-1, :3] = [0.0, -0.5, -20.0]  # on the ground, below the users: the formula itself
    power = station_power_mw(users, copy, uavs, heights, config)
    assert power.shape == (len(copy), 10)
    worst = 0.0
    for c in range(16):
        rows = copy == c
        reference = reference_power_mw(users[rows], uavs[c], heights[c], config)
        below = heights[c] < 0.0
        np.testing.assert_allclose(power[rows][:, below], reference[:, below], rtol=TOLERANCE, atol=0.0)
        worst = max(worst, error_db(power[rows], reference).max(initial=0.0))
        alone = station_power_mw(users[rows], np.zeros(rows.sum(), np.int64), uavs[c:c + 1], heights[c:c + 1],
                                 config)
        np.testing.assert_array_equal(alone, power[rows])  # a world alone gets its numbers in a batch
    assert 0.0 < worst <= TABLE_ERROR_DB


def test_the_table_serves_the_users_the_formula_serves(monkeypatch):
    """64 worlds of the env's default scenario: association, MCS and throughput as with the formula."""
    envs = BatchedUAVSwarm(64, n_uavs=10, max_cycles=100)
    envs.reset(seed=11)
    rng = np.random.default_rng(0)
    for _ in range(3):
        envs.step(rng.uniform(-1.0, 1.0, (64, 10, 2)))
    crowd, uavs, radio = envs.crowd, envs.uav_positions_m, envs.radio
    heights = np.broadcast_to(envs._core.altitudes_m, (64, 10))
    plan = envs._core.channel_plan
    table = coverage.wifi_links(crowd.positions_m, crowd.copy_index, uavs, radio, heights, plan)

    def formula(users, copy, uavs_m, heights_m, config):
        return np.concatenate([reference_power_mw(users[copy == c], uavs_m[c], heights_m[c], config)
                               for c in range(len(uavs_m))])

    monkeypatch.setattr(coverage, "station_power_mw", formula)
    exact = coverage.wifi_links(crowd.positions_m, crowd.copy_index, uavs, radio, heights, plan)
    assert (exact.association >= 0).sum() > 10_000
    np.testing.assert_array_equal(table.association, exact.association)
    np.testing.assert_array_equal(table.mcs, exact.mcs)
    np.testing.assert_allclose(table.throughput_mbps, exact.throughput_mbps, rtol=1e-9, atol=0.0)
    assert np.abs(table.sinr_db - exact.sinr_db).max() <= TABLE_ERROR_DB
