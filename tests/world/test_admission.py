"""Admission control in the radio model: a station limit per UAV, snapshot and sequence association."""

import subprocess
import sys

import numpy as np
import pytest

from typed_config import ConfigError
from uav_swarm.world.comms import Association, RadioConfig, evaluate_coverage


def greedy_reference(users, uavs, config):
    """The definition, pair by pair: strongest first (ties: lower UAV, then lower user); full UAVs refuse."""
    d2 = ((uavs[:, None, :] - users[None, :, :]) ** 2).sum(-1)  # (K, N)
    signal = np.exp(d2 * (-0.5 / config.effective_sigma_sq_m2))
    pairs = sorted((d2[k, u], k, u) for k in range(len(uavs)) for u in range(len(users))
                   if signal[k, u] >= config.signal_at_range)
    association = np.full(len(users), -1)
    load = np.zeros(len(uavs), int)
    for _, k, u in pairs:
        if association[u] < 0 and load[k] < config.max_stations:
            association[u] = k
            load[k] += 1
    return association


def cell(centre, n, rng, radius=10.0):
    angle = rng.uniform(0, 2 * np.pi, n)
    r = radius * np.sqrt(rng.uniform(0, 1, n))
    return np.asarray(centre) + np.column_stack([r * np.cos(angle), r * np.sin(angle)])


def test_a_full_cell_refuses_the_41st_user_who_joins_the_next_uav_in_range():
    rng = np.random.default_rng(0)
    users = cell([0.0, 0.0], 40, rng, radius=5.0)
    users = np.vstack([users, [[12.0, 0.0]]])  # the 41st: nearest to UAV 0, but in range of UAV 1 too
    uavs = np.array([[0.0, 0.0], [35.0, 0.0]])
    paper = evaluate_coverage(users, uavs, RadioConfig())
    assert paper.users_per_uav.tolist() == [41, 0] and paper.qos_s2 == 0.0  # everyone below 5 Mbps
    limited = evaluate_coverage(users, uavs, RadioConfig(station_limit="auto"))
    assert limited.users_per_uav.tolist() == [40, 1]
    assert limited.association[40] == 1
    assert limited.qos_s2 == limited.qos_s1 == 1.0
    assert limited.throughput_mbps.min() >= 5.0


def test_a_refused_user_with_no_other_uav_in_range_has_no_network():
    rng = np.random.default_rng(1)
    users = np.vstack([cell([0.0, 0.0], 40, rng, radius=5.0), [[12.0, 0.0]]])
    coverage = evaluate_coverage(users, np.zeros((1, 2)), RadioConfig(station_limit=40))
    assert coverage.association[40] == -1 and coverage.in_range[40] and not coverage.covered[40]
    assert coverage.qos_s1 == pytest.approx(40 / 41)


@pytest.mark.parametrize("seed", range(12))
def test_snapshot_equals_the_pair_by_pair_definition(seed):
    rng = np.random.default_rng(seed)
    users = rng.uniform(0, 120, (int(rng.integers(50, 400)), 2))
    users[: len(users) // 3] = np.round(users[: len(users) // 3])  # exact ties in distance
    uavs = np.round(rng.uniform(0, 120, (int(rng.integers(1, 10)), 2)))
    limit = int(rng.integers(1, 41))
    config = RadioConfig(station_limit=limit)
    coverage = evaluate_coverage(users, uavs, config)
    assert coverage.association.tolist() == greedy_reference(users, uavs, config).tolist()
    assert coverage.users_per_uav.max() <= limit


def test_the_paper_model_is_unchanged_bit_for_bit_without_a_limit():
    rng = np.random.default_rng(3)
    users, uavs = rng.uniform(0, 200, (500, 2)), rng.uniform(0, 200, (10, 2))
    config = RadioConfig()
    d2 = ((uavs[:, None, :] - users[None]) ** 2).sum(-1)
    nearest = d2.argmin(axis=0)
    covered = np.exp(d2.min(axis=0) * (-0.5 / config.effective_sigma_sq_m2)) >= config.signal_at_range
    counts = np.bincount(nearest[covered], minlength=10)
    coverage = evaluate_coverage(users, uavs, config)
    assert coverage.association.tolist() == np.where(covered, nearest, -1).tolist()
    assert np.array_equal(coverage.throughput_mbps,
                          np.where(covered, 200.0 / np.maximum(counts, 1)[nearest], 0.0))
    assert coverage.qos_s1 == covered.sum() / 500
    assert coverage.model == "paper (no admission control)"
    assert np.array_equal(Association(config).update(users, uavs).association, coverage.association)


def test_an_incumbent_is_never_evicted_by_a_nearer_newcomer():
    config = RadioConfig(station_limit=1)
    link = Association(config)
    uavs = np.array([[0.0, 0.0], [25.0, 0.0]])
    first = link.update(np.array([[-10.0, 0.0], [100.0, 0.0]]), uavs)
    assert first.association.tolist() == [0, -1]
    # The second user walks in right under UAV 0: UAV 0 is full, so it joins UAV 1; the incumbent stays.
    second = link.update(np.array([[-10.0, 0.0], [2.0, 0.0]]), uavs)
    assert second.association.tolist() == [0, 1]
    # A snapshot gives UAV 0 to the nearer newcomer; the other user, in range of UAV 0 alone, is refused.
    snapshot = evaluate_coverage(np.array([[-10.0, 0.0], [2.0, 0.0]]), uavs, config)
    assert snapshot.association.tolist() == [-1, 0]


def test_an_incumbent_does_not_roam_while_its_signal_holds_and_leaves_out_of_range():
    link = Association(RadioConfig(station_limit=5))
    uavs = np.array([[0.0, 0.0], [50.0, 0.0]])
    assert link.update(np.array([[10.0, 0.0]]), uavs).association.tolist() == [0]
    assert link.update(np.array([[28.0, 0.0]]), uavs).association.tolist() == [0]  # nearer UAV 1 now
    assert link.update(np.array([[31.0, 0.0]]), uavs).association.tolist() == [1]  # out of UAV 0's range
    link.reset()
    assert link.update(np.array([[28.0, 0.0]]), uavs).association.tolist() == [1]  # reset: fresh snapshot


def test_sequences_are_deterministic_and_respect_the_limit():
    def run():
        rng = np.random.default_rng(11)
        link = Association(RadioConfig(station_limit="auto"))
        users = rng.uniform(0, 100, (300, 2))
        uavs = rng.uniform(20, 80, (4, 2))
        out = []
        for _ in range(20):
            users = users + rng.normal(0, 1.5, users.shape)
            uavs = uavs + rng.normal(0, 1.0, uavs.shape)
            coverage = link.update(users, uavs)
            assert coverage.users_per_uav.max() <= 40
            assert np.all(coverage.in_range[coverage.covered])
            out.append(coverage.association.copy())
        return np.array(out)
    assert np.array_equal(run(), run())


@pytest.mark.parametrize(("value", "needle"), [
    (0, "station_limit = 0 is out of range"),
    (-3, "station_limit = -3 is out of range"),
    (41, "station_limit = 41 is out of range: allowed 1 <= station_limit <= 40"),
    ("many", "station_limit = 'many'"),
    (2.5, "station_limit"),
])
def test_bad_station_limits_are_refused_naming_the_field(value, needle):
    with pytest.raises(ConfigError, match="RadioConfig.station_limit") as error:
        RadioConfig(station_limit=value)
    assert needle in str(error.value)


def test_auto_and_off():
    assert RadioConfig(station_limit="auto").max_stations == 40
    assert RadioConfig(station_limit="auto", capacity_mbps=300.0, min_user_rate_mbps=2.0).max_stations == 150
    assert RadioConfig(station_limit="off").max_stations is None
    assert RadioConfig(station_limit="off").association_name == "paper (no admission control)"
    assert RadioConfig(min_user_rate_mbps=0.0, station_limit=500).max_stations == 500
    with pytest.raises(ConfigError, match="min_user_rate_mbps > 0"):
        RadioConfig(min_user_rate_mbps=0.0, station_limit="auto")


def test_a_step_on_1000_users_stays_vectorised():
    """The round count of deferred acceptance is small: 1,000 users, 10 full UAVs, in far fewer rounds."""
    code = ("import numpy as np; from uav_swarm.world.comms import evaluate_coverage, RadioConfig;"
            "rng = np.random.default_rng(0); u = rng.normal(100, 15, (1000, 2));"
            "k = rng.normal(100, 20, (10, 2));"
            "c = evaluate_coverage(u, k, RadioConfig(station_limit='auto')); print(c.users_per_uav.sum())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert int(out.stdout) == 400


def test_incumbents_follow_their_uav_by_id_when_the_fleet_rows_change():
    link = Association(RadioConfig(station_limit=2))
    users = np.array([[10.0, 0.0], [40.0, 0.0]])
    uavs = np.array([[0.0, 0.0], [25.0, 0.0]])
    assert link.update(users, uavs, [7, 9]).association.tolist() == [0, 1]
    # UAV 7 is lost: the rows shift, user 1 stays with UAV 9 (now row 0), user 0 joins it too.
    assert link.update(users, uavs[1:], [9]).association.tolist() == [0, 0]
    with pytest.raises(ValueError, match="uav_ids"):
        link.update(users, uavs, [1])
