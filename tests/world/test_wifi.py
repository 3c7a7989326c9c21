"""The 802.11 radio model: carrier sense, airtime, hidden APs, fairness, admission on rate, settings."""

import re

import numpy as np
import pytest

from typed_config import ConfigError
from uav_swarm.world.comms import Association, RadioConfig, evaluate_coverage
from uav_swarm.world.comms_batch import coverage_batch
from uav_swarm.world.wifi.airtime import collision_success
from uav_swarm.world.wifi.config import Ieee80211Config
from uav_swarm.world.wifi.coverage import wifi_links
from uav_swarm.world.wifi.tables import load_wifi_tables

WIFI = RadioConfig(propagation="802.11")
# Carrier sense at the energy-detection level (-62 dBm): APs tens of metres apart no longer hear each other.
DEAF = RadioConfig(propagation="802.11", ieee80211=Ieee80211Config(cca_threshold_20mhz_dbm=-62.0))


def ring(centre, n, radius_m, phase=0.0):
    angle = phase + np.arange(n) * 2 * np.pi / n
    return np.asarray(centre) + radius_m * np.column_stack([np.cos(angle), np.sin(angle)])


def snapshot(users, uavs, config=WIFI, channels=None, altitude_m=20.0):
    uavs = np.asarray(uavs, dtype=float)
    plan = None if channels is None else np.asarray(channels)
    return evaluate_coverage(np.asarray(users, float), uavs, config, np.full(len(uavs), altitude_m), plan)


def shipped_collision_success(contenders):
    tables = load_wifi_tables()
    return collision_success(contenders, tables.cw_min, tables.backoff_stages, tables.collision_time_ratio)


def test_two_co_channel_aps_5_m_apart_share_the_airtime_two_channels_double_it():
    users = np.vstack([ring([-2.5, 0.0], 4, 6.0), ring([2.5, 0.0], 4, 6.0, phase=0.3)])
    uavs = [[-2.5, 0.0], [2.5, 0.0]]
    lone = snapshot(users[:4], uavs[:1])
    shared = snapshot(users, uavs, channels=[36, 36])
    apart = snapshot(users, uavs, channels=[36, 40])
    assert shared.users_per_uav.tolist() == apart.users_per_uav.tolist() == [4, 4]
    # Sharing: together about one AP's airtime; apart: each its own.
    assert shared.airtime.sum() == pytest.approx(lone.airtime[0], rel=0.02)
    np.testing.assert_allclose(apart.airtime, lone.airtime[0])
    total_shared, total_apart = shared.throughput_mbps.sum(), apart.throughput_mbps.sum()
    # ... and on one channel their backoffs sometimes collide (Bianchi with two contenders).
    assert total_apart / total_shared == pytest.approx(2.0 / shipped_collision_success(2.0), rel=0.02)
    # The 802.11 sum is below the paper's 200 Mbps per UAV: one 20 MHz AP delivers at most its MAC efficiency
    # times the top rate (ns-3: 128 Mbps to one MCS-11 station, benchmarks/README.md).
    assert lone.throughput_mbps.sum() <= load_wifi_tables().mac_efficiency * 143.4 + 1e-9


def test_an_ap_between_two_hidden_co_channel_aps_gets_sinr_limited_rates():
    users = [[15.0, 0.0], [-85.0, 0.0], [85.0, 0.0]]
    uavs = [[0.0, 0.0], [-70.0, 0.0], [70.0, 0.0]]
    quiet = snapshot(users, uavs, DEAF, channels=[36, 40, 44])
    hidden = snapshot(users, uavs, DEAF, channels=[36, 36, 36])
    # No AP hears another: the airtime is not shared ...
    np.testing.assert_allclose(hidden.airtime, quiet.airtime)
    # ... but the middle AP's station hears both others on top of its own signal.
    assert hidden.sinr_db[0] < quiet.sinr_db[0] - 3.0
    assert hidden.mcs[0] < quiet.mcs[0]
    assert hidden.throughput_mbps[0] < quiet.throughput_mbps[0]


def test_an_ap_heard_by_two_aps_that_do_not_hear_each_other_is_starved():
    users = [[0.0, 5.0], [-50.0, 5.0], [50.0, 5.0]]
    uavs = [[0.0, 0.0], [-50.0, 0.0], [50.0, 0.0]]
    chain = snapshot(users, uavs, DEAF.replace(min_user_rate_mbps=0.0), channels=[36, 36, 36])
    rho = load_wifi_tables().access_intensity
    # Ideal CSMA on the chain L - M - R: M transmits only when neither L nor R does.
    assert chain.airtime[0] == pytest.approx(rho / (1 + 3 * rho + rho**2))
    assert chain.airtime[1] == pytest.approx((rho + rho**2) / (1 + 3 * rho + rho**2))
    assert chain.throughput_mbps[0] < 0.05 * chain.throughput_mbps[1]
    # Under admission on rate the starved AP refuses its user (5 Mbps cannot be kept): it then serves nobody.
    admitted = snapshot(users, uavs, DEAF, channels=[36, 36, 36])
    assert admitted.association[0] == -1 and admitted.in_range[0]


def test_throughput_fairness_shows_the_performance_anomaly():
    users = [[3.0, 0.0], [75.0, 0.0]]  # a fast station and a slow one
    airtime_fair = snapshot(users, [[0.0, 0.0]])
    config = WIFI.replace(ieee80211=Ieee80211Config(fairness="throughput"))
    throughput_fair = snapshot(users, [[0.0, 0.0]], config)
    fast, slow = airtime_fair.rate_mbps
    assert fast > 3 * slow
    # Equal throughput: the slow station holds the medium longer and drags the fast one down to near its rate.
    assert throughput_fair.throughput_mbps[0] == pytest.approx(throughput_fair.throughput_mbps[1])
    assert throughput_fair.throughput_mbps[0] < 0.5 * airtime_fair.throughput_mbps[0]
    assert throughput_fair.throughput_mbps[1] > airtime_fair.throughput_mbps[1]
    assert throughput_fair.throughput_mbps.sum() < airtime_fair.throughput_mbps.sum()
    # Airtime fairness: each station's throughput is proportional to its own rate.
    ratio = airtime_fair.throughput_mbps / airtime_fair.rate_mbps
    assert ratio[0] == pytest.approx(ratio[1])


def test_admission_refuses_the_station_that_would_push_someone_under_the_minimum():
    users = ring([0.0, 0.0], 4, 4.0)
    one = snapshot(users[:1], [[0.0, 0.0]])
    each = one.throughput_mbps[0]  # a lone station's throughput: n stations get each / n
    minimum = each / 3.5  # three stations keep it, a fourth would not
    config = WIFI.replace(min_user_rate_mbps=minimum)
    alone = snapshot(users, [[0.0, 0.0]], config)
    assert np.count_nonzero(alone.association == 0) == 3
    assert alone.in_range.all() and alone.throughput_mbps[alone.covered].min() >= minimum
    assert alone.qos_s2 == alone.qos_s1 == 0.75
    # With a second AP in range on another channel the refused station roams to it.
    two = snapshot(users, [[0.0, 0.0], [30.0, 0.0]], config, channels=[36, 40])
    assert two.users_per_uav.tolist() == [3, 1] and two.qos_s2 == 1.0
    # Without admission on rate all four join the strongest AP and everyone falls under the minimum.
    open_door = WIFI.replace(min_user_rate_mbps=minimum, ieee80211=Ieee80211Config(rate_admission=False))
    crowded = snapshot(users, [[0.0, 0.0], [30.0, 0.0]], open_door, channels=[36, 40])
    assert crowded.users_per_uav.tolist() == [4, 0] and crowded.qos_s2 == 0.0


def test_a_station_limit_caps_the_stations_under_802_11_too():
    users = ring([0.0, 0.0], 6, 4.0)
    capped = snapshot(users, [[0.0, 0.0]], WIFI.replace(station_limit=2))
    assert capped.users_per_uav.tolist() == [2]
    assert "2 stations per UAV" in capped.model


def test_incumbents_stay_while_in_range_newcomers_join_the_strongest():
    link = Association(WIFI)
    uavs, heights = np.array([[0.0, 0.0], [40.0, 0.0]]), np.full(2, 20.0)
    first = link.update(np.array([[5.0, 0.0]]), uavs, altitudes_m=heights, channels=np.array([36, 40]))
    assert first.association.tolist() == [0]
    moved = link.update(np.array([[30.0, 0.0]]), uavs, altitudes_m=heights, channels=np.array([36, 40]))
    assert moved.association.tolist() == [0] and moved.mcs[0] >= 0  # nearer UAV 1 now, still served by 0
    fresh = evaluate_coverage(np.array([[30.0, 0.0]]), uavs, WIFI, heights, np.array([36, 40]))
    assert fresh.association.tolist() == [1]
    gone = link.update(np.array([[3000.0, 0.0]]), uavs, altitudes_m=heights, channels=np.array([36, 40]))
    assert gone.association.tolist() == [-1]


def test_altitude_changes_the_link():
    users = [[40.0, 0.0]]
    low, high = snapshot(users, [[0.0, 0.0]], altitude_m=5.0), snapshot(users, [[0.0, 0.0]], altitude_m=40.0)
    # Higher up the elevation angle grows and the line of sight wins over the longer distance (urban).
    assert high.sinr_db[0] > low.sinr_db[0]


@pytest.mark.parametrize("seed", range(3))
def test_the_batch_equals_each_world_alone(seed):
    rng = np.random.default_rng(seed)
    n_worlds, n_uavs = 3, 4
    counts = rng.integers(0, 60, n_worlds)
    users = rng.uniform(0, 150, (counts.sum(), 2))
    copy = np.repeat(np.arange(n_worlds), counts)
    uavs = rng.uniform(0, 150, (n_worlds, n_uavs, 2))
    heights = rng.uniform(10, 40, (n_worlds, n_uavs))
    plan = rng.choice([36, 40], (n_worlds, n_uavs))
    batch = coverage_batch(users, copy, uavs, WIFI, altitudes_m=heights, channels=plan)
    for c in range(n_worlds):
        alone = evaluate_coverage(users[copy == c], uavs[c], WIFI, heights[c], plan[c])
        together = batch.copy(c)
        np.testing.assert_array_equal(together.association, alone.association)
        np.testing.assert_allclose(together.throughput_mbps, alone.throughput_mbps)
        np.testing.assert_allclose(together.airtime, alone.airtime)
        assert together.qos_s2 == pytest.approx(alone.qos_s2)
        assert batch.qos_s1[c] == pytest.approx(alone.qos_s1)


def test_the_paper_model_stays_the_default_and_refuses_802_11_settings():
    assert RadioConfig().propagation == "paper"
    assert evaluate_coverage(np.array([[0.0, 0.0]]), np.zeros((1, 2)), RadioConfig()).sinr_db is None
    with pytest.raises(ConfigError, match="ieee80211 applies only with propagation = '802.11'"):
        RadioConfig(ieee80211=Ieee80211Config(tx_power_dbm=10.0))
    with pytest.raises(ConfigError, match="capacity_mbps belongs to propagation = 'paper'"):
        RadioConfig(propagation="802.11", capacity_mbps=100.0)
    with pytest.raises(ValueError, match="channels apply only"):
        evaluate_coverage(np.zeros((1, 2)), np.zeros((1, 2)), RadioConfig(), channels=np.array([36]))


@pytest.mark.parametrize(("settings", "message"), [
    ({"channel_width_mhz": 30}, "channel_width_mhz = 30 is not allowed"),
    ({"frequency_ghz": 2.437, "channel_width_mhz": 40}, "channel_width_mhz = 40 is not allowed"),
    ({"channels": (36, 38)}, "channels = \\[36, 38\\]"),
    ({"frequency_ghz": 3.5}, "frequency_ghz = 3.5 is out of range"),
    ({"environment": "forest"}, "environment = 'forest' is not allowed"),
])
def test_bad_802_11_settings_name_the_field(settings, message):
    with pytest.raises(ConfigError, match=message):
        Ieee80211Config(**settings)


def test_a_channel_outside_the_usable_list_is_refused():
    with pytest.raises(ValueError, match="channels \\[52\\] are not usable"):
        snapshot([[0.0, 0.0]], [[0.0, 0.0]], channels=[52])


def test_width_and_streams_scale_the_rates():
    wide = WIFI.replace(ieee80211=Ieee80211Config(channel_width_mhz=40, spatial_streams=2))
    narrow = snapshot([[2.0, 0.0]], [[0.0, 0.0]])
    # 40 MHz: twice the data tones, 3 dB more noise and a 3 dB higher carrier-sense threshold; 2 streams.
    assert Ieee80211Config(channel_width_mhz=40).cca_threshold_dbm == -79.0
    both = snapshot([[2.0, 0.0]], [[0.0, 0.0]], wide, channels=[38])
    assert both.sinr_db[0] == pytest.approx(narrow.sinr_db[0] - 10 * np.log10(2))
    assert both.rate_mbps[0] == pytest.approx(4 * load_wifi_tables().rate_20mhz_1ss_mbps[both.mcs[0]])


def test_the_tables_loader_names_the_file_and_key(tmp_path):
    bad = tmp_path / "tables.toml"
    bad.write_text("schema = 2\n[mcs]\nrate_20mhz_1ss_mbps = [1.0, 2.0]\nmin_sinr_db = [1.0]\n"
                   "[width]\nchannel_width_mhz = [20]\ndata_subcarriers = [234]\n")
    with pytest.raises(ConfigError, match="must have equal lengths"):
        load_wifi_tables(str(bad))
    with pytest.raises(ConfigError, match="not found"):
        load_wifi_tables(str(tmp_path / "missing.toml"))
    refit = tmp_path / "refit.toml"
    shipped = load_wifi_tables().source
    text = open(shipped, encoding="utf-8").read()
    refit.write_text(re.sub(r"^efficiency = .*$", "efficiency = 0.35", text, count=1, flags=re.MULTILINE))
    refitted = WIFI.replace(ieee80211=Ieee80211Config(tables_file=str(refit)))
    scaled = snapshot([[2.0, 0.0]], [[0.0, 0.0]], refitted)
    full = snapshot([[2.0, 0.0]], [[0.0, 0.0]])
    shipped_efficiency = load_wifi_tables().mac_efficiency
    assert shipped_efficiency != 0.35
    assert scaled.throughput_mbps[0] == pytest.approx(full.throughput_mbps[0] * 0.35 / shipped_efficiency)


def test_the_802_11_model_needs_the_altitudes():
    with pytest.raises(ValueError, match="needs the UAVs' altitudes"):
        evaluate_coverage(np.zeros((1, 2)), np.zeros((1, 2)), WIFI)
    given = evaluate_coverage(np.zeros((1, 2)), np.zeros((1, 2)), WIFI.replace(altitude_m=20.0))
    assert given.sinr_db[0] == pytest.approx(snapshot([[0.0, 0.0]], [[0.0, 0.0]]).sinr_db[0])


def test_incumbents_follow_their_uav_by_id_when_the_fleet_changes():
    link = Association(WIFI)
    heights = np.full(2, 20.0)
    user = np.array([[50.0, 0.0]])
    first = link.update(user, np.array([[0.0, 0.0], [60.0, 0.0]]), uav_ids=[7, 9], altitudes_m=heights,
                        channels=np.array([36, 40]))
    assert first.association.tolist() == [1]  # UAV 9
    # UAV 7 is lost; UAV 9 is now row 0 and a new UAV 5, right above the user, row 1: the user stays on 9.
    second = link.update(user, np.array([[60.0, 0.0], [50.0, 0.0]]), uav_ids=[9, 5], altitudes_m=heights,
                         channels=np.array([40, 36]))
    assert second.association.tolist() == [0]
    assert evaluate_coverage(user, np.array([[60.0, 0.0], [50.0, 0.0]]), WIFI, heights,
                             np.array([40, 36])).association.tolist() == [1]


# Everyone joins (no admission on rate): the throughput then shows the airtime alone.
OPEN = RadioConfig(propagation="802.11", min_user_rate_mbps=0.0,
                   ieee80211=Ieee80211Config(rate_admission=False))


def clique_links(n_uavs, config=OPEN):
    """``n_uavs`` APs 10 m apart on one channel (they all hear each other), 4 users under each."""
    uavs = np.column_stack([10.0 * np.arange(n_uavs), np.zeros(n_uavs)])
    users = np.vstack([ring(uav, 4, 3.0) for uav in uavs])
    return wifi_links(users, np.zeros(len(users), np.int64), uavs[None], config,
                      altitudes_m=np.full(n_uavs, 20.0), channels=np.full(n_uavs, 36))


def without_collisions(tmp_path):
    """OPEN with the shipped tables but ``collision_time_ratio = 0``: ideal CSMA alone."""
    text = open(load_wifi_tables().source, encoding="utf-8").read()
    free = tmp_path / "free.toml"
    free.write_text(re.sub(r"^collision_time_ratio = .*$", "collision_time_ratio = 0.0", text, count=1,
                           flags=re.MULTILINE))
    return OPEN.replace(ieee80211=OPEN.ieee80211.replace(tables_file=str(free)))


def test_co_channel_aps_lose_airtime_to_collisions_as_their_number_grows(tmp_path):
    ideal_config = without_collisions(tmp_path)
    assert clique_links(1).throughput_mbps.sum() == pytest.approx(
        clique_links(1, ideal_config).throughput_mbps.sum())  # alone: nobody to collide with
    totals, shares = [], []
    for n_uavs in (2, 5, 10):
        links, ideal = clique_links(n_uavs), clique_links(n_uavs, ideal_config)
        assert ideal.collision_free.tolist() == [[1.0] * n_uavs]
        # In a clique every AP counts down with every other: n contenders, Bianchi's share each.
        share = shipped_collision_success(float(n_uavs))
        np.testing.assert_allclose(links.collision_free[0], share)
        np.testing.assert_allclose(links.airtime, ideal.airtime)  # collided transmissions take airtime too
        assert links.throughput_mbps.sum() == pytest.approx(share * ideal.throughput_mbps.sum())
        totals.append(links.throughput_mbps.sum())
        shares.append(share)
    assert totals[0] > totals[1] > totals[2]
    assert 1.0 > shares[0] > shares[1] > shares[2]
    # Bianchi, CWmin 15 and 6 doublings: a transmission among ten contenders succeeds with P_s = 0.775.
    assert collision_success(10.0, 15, 6, 1.0) == pytest.approx(0.775, abs=0.001)
    assert collision_success(1.0, 15, 6, 1.0) == 1.0


def test_the_ends_of_a_chain_rarely_collide_with_its_starved_middle():
    users = [[0.0, 5.0], [-50.0, 5.0], [50.0, 5.0]]
    uavs = np.array([[[0.0, 0.0], [-50.0, 0.0], [50.0, 0.0]]])
    chain = wifi_links(np.asarray(users), np.zeros(3, np.int64), uavs, DEAF.replace(min_user_rate_mbps=0.0),
                       altitudes_m=np.full(3, 20.0), channels=np.full(3, 36))
    rho = load_wifi_tables().access_intensity
    # The middle counts down with both ends (3 contenders); an end with the middle only while the other
    # end is silent, 1 / (1 + rho) of its own countdown.
    np.testing.assert_allclose(chain.collision_free[0], [shipped_collision_success(3.0),
                                                         shipped_collision_success(1.0 + 1.0 / (1.0 + rho)),
                                                         shipped_collision_success(1.0 + 1.0 / (1.0 + rho))])


def test_the_guard_interval_scales_every_rate():
    for guard_us, factor in ((0.8, 1.0), (1.6, 13.6 / 14.4), (3.2, 13.6 / 16.0)):
        config = WIFI.replace(ieee80211=Ieee80211Config(guard_interval_us=guard_us))
        cell = snapshot([[2.0, 0.0], [40.0, 0.0]], [[0.0, 0.0]], config)
        reference = snapshot([[2.0, 0.0], [40.0, 0.0]], [[0.0, 0.0]])
        assert cell.mcs.tolist() == reference.mcs.tolist()  # the SINR does not change, the symbols do
        np.testing.assert_allclose(cell.rate_mbps, reference.rate_mbps * factor)
        np.testing.assert_allclose(cell.throughput_mbps, reference.throughput_mbps * factor)
    assert Ieee80211Config(guard_interval_us=3.2).guard_interval_rate_factor == pytest.approx(0.85)
    with pytest.raises(ConfigError, match=r"guard_interval_us = 2.0 is not allowed: choose one of "
                                          r"\[0.8, 1.6, 3.2\]"):
        Ieee80211Config(guard_interval_us=2.0)


def test_tables_of_the_first_schema_are_refused_with_what_to_add(tmp_path):
    old = tmp_path / "old.toml"
    text = open(load_wifi_tables().source, encoding="utf-8").read()
    old.write_text(text.replace("schema = 2", "schema = 1"))
    with pytest.raises(ConfigError, match="schema = 1 has no collision model: set schema = 2 and add"):
        load_wifi_tables(str(old))
    broken = tmp_path / "broken.toml"
    broken.write_text(re.sub(r"^cw_min = .*$", "cw_min = 0", text, count=1, flags=re.MULTILINE))
    with pytest.raises(ConfigError, match=r"\[contention\] cw_min = 0 is out of range"):
        load_wifi_tables(str(broken))


@pytest.mark.parametrize("seed", range(6))
def test_an_access_point_that_is_off_is_as_if_its_uav_were_not_there(seed):
    """Users, rates and the channel plan of the UAVs left on equal those of a world without the others."""
    from uav_swarm.world.wifi.channels import plan_channels

    rng = np.random.default_rng(seed)
    radio = RadioConfig(propagation="802.11", altitude_m=10.0, min_user_rate_mbps=5.0)
    radio = radio.replace(ieee80211=radio.ieee80211.replace(rate_admission=bool(seed % 2)))
    users = rng.uniform(0.0, 200.0, (150, 2))
    uavs = rng.uniform(0.0, 200.0, (1, 10, 2))
    on = rng.random(10) < 0.6
    on[0] = True
    plan = plan_channels(uavs, radio, enabled=on)
    both = plan_channels(uavs[:, on], radio)
    np.testing.assert_array_equal(plan[:, on], both)
    copy = np.zeros(len(users), np.int64)
    masked = wifi_links(users, copy, uavs, radio, channels=plan, enabled=on)
    alone = wifi_links(users, copy, uavs[:, on], radio, channels=both)
    ids = np.flatnonzero(on)
    assert masked.association.tolist() == [-1 if k < 0 else int(ids[k]) for k in alone.association]
    np.testing.assert_allclose(masked.throughput_mbps, alone.throughput_mbps, rtol=1e-12)
    assert masked.qos_s2 == alone.qos_s2 and masked.qos_s1 == alone.qos_s1
    assert np.all(masked.users_per_uav[0][~on] == 0)
