"""``simulate`` under the 802.11 radio: channel plan, users' SINR and MCS, airtime, co-channel sharing.

One short expert run is recorded; its figures are recomputed here from what the run recorded (the UAVs'
positions after every step, their channels) and the sequence's crowd, which walks the same whatever the UAVs
do: the association is replayed with :class:`uav_swarm.world.comms.Association` (the 802.11 model keeps its
incumbents step to step) and must give the same SINR and MCS figures, step by step and in the summary.
"""

from __future__ import annotations

import base64
import csv
import json

import numpy as np
import pytest
from foxglove_readback import conform, read_back

from conftest import SMALL_PAPER_TASK, SMALL_WIFI_TASK
from typed_config import ConfigError
from uav_swarm.cli.simulate import format_summary
from uav_swarm.env.parallel import parallel_env
from uav_swarm.runs.outputs.radio_report import MCS_BANDS, SERVICE_CLASSES, mcs_band_shares, sharing_pairs
from uav_swarm.runs.simulate import sequence_crowds, simulate
from uav_swarm.runs.simulate_config import SimulateConfig
from uav_swarm.world.comms import Association, RadioConfig
from uav_swarm.world.wifi.channels import plan_channels
from uav_swarm.world.wifi.phy import ap_pair_power_dbm

N_UAVS, REPLAN_EVERY = 4, 5
WIFI_TASK = {**SMALL_WIFI_TASK, "strategy": 2, "radio": {"propagation": "802.11"}}


def _config(**changes) -> SimulateConfig:
    return SimulateConfig.from_dict({
        "duration_s": 2.0, "n_uavs": N_UAVS, "planner": "expert", "compare_expert": False, "gif": False,
        "publish_telemetry": False, "replan_every": REPLAN_EVERY, "static_reference": False,
        "task": WIFI_TASK, **changes})


@pytest.fixture(scope="module")
def wifi_run(tmp_path_factory):
    """A 2 s expert run of 4 UAVs under the 802.11 radio, recorded for Foxglove."""
    out = tmp_path_factory.mktemp("wifi")
    config = _config()
    result = simulate(config, out / "outputs", progress=False, record=out / "run.mcap")
    return config, result, out


def _replay(config: SimulateConfig, run) -> list:
    """The coverage after every step, recomputed from the recorded positions and channels."""
    env = parallel_env(config=config.env_config())
    env.reset(seed=config.seed)
    crowds = [users for _, users, _ in sequence_crowds(config, config.dt_s)] + [run.final_pedestrians_m]
    link = Association(env.radio)
    start = np.array(env.uav_positions_m)  # at the reset the environment plans the channels itself
    link.update(crowds[0], start, altitudes_m=env.uav_altitudes_m,
                channels=plan_channels(start, env.radio, env.uav_altitudes_m))
    return [link.update(crowds[step + 1], run.uav_tracks_m[step], altitudes_m=env.uav_altitudes_m,
                        channels=run.radio.channels[step]) for step in range(config.n_steps)]


def test_the_sinr_and_mcs_figures_equal_a_replay_of_the_recorded_flight(wifi_run):
    config, result, _ = wifi_run
    run = result.runs["expert"]
    replay = _replay(config, run)
    assert np.array_equal([c.qos_s2 for c in replay], run.qos_s2)  # the same association as the run's
    medians = np.array([np.median(c.sinr_db) for c in replay])
    shares = np.array([mcs_band_shares(c.mcs) for c in replay])
    assert np.allclose(run.radio.median_sinr_db, medians, rtol=0, atol=1e-12)
    assert np.allclose(run.radio.mcs_shares, shares, rtol=0, atol=1e-12)
    assert np.allclose(run.radio.airtime, [c.airtime for c in replay], rtol=0, atol=1e-12)
    wifi = result.summary["planners"]["expert"]["wifi_80211"]
    assert wifi["median_sinr_db"] == pytest.approx(medians.mean(), abs=1e-9)
    for band, (name, _, _) in enumerate(MCS_BANDS):
        assert wifi["mcs_shares"][name] == pytest.approx(shares[:, band].mean(), abs=1e-12)
    assert wifi["final"]["mcs_shares"] == pytest.approx(shares[-1].tolist(), abs=1e-12)
    assert sum(wifi["mcs_shares"].values()) == pytest.approx(1.0)
    # "not served" is exactly the users the radio does not serve (S1 counts MCS 0 or better)
    assert np.allclose(shares[:, 0], 1.0 - run.qos_s1, atol=1e-12)


def test_the_rate_bar_accounts_for_every_user_and_the_table_says_why_s2_is_lower(wifi_run):
    config, result, _ = wifi_run
    run = result.runs["expert"]
    replay = _replay(config, run)
    bar = config.task.radio.min_user_rate_mbps
    expected = []
    for c in replay:  # recomputed user by user from the replayed association
        served, fast = c.association >= 0, c.throughput_mbps >= bar
        expected.append([np.mean(~served & ~c.in_range), np.mean(~served & c.in_range),
                         np.mean(served & ~fast), np.mean(served & fast)])
    expected = np.array(expected)
    assert np.allclose(run.radio.service, expected, rtol=0, atol=1e-12)
    assert np.allclose(run.radio.service[:, 3], run.qos_s2, atol=1e-12)  # QoS S2: at the bar
    assert np.allclose(run.radio.service[:, 2:].sum(axis=1), run.qos_s1, atol=1e-12)  # S1: served
    assert np.array_equal(run.radio.stations, [c.users_per_uav for c in replay])
    rate_bar = result.summary["planners"]["expert"]["wifi_80211"]["rate_bar"]
    assert rate_bar["rate_bar_mbps"] == bar and rate_bar["admission_on_rate"] is True
    for c, name in enumerate(SERVICE_CLASSES):
        assert rate_bar["shares"][name] == pytest.approx(expected[:, c].mean(), abs=1e-12)
    table = format_summary(result.summary)
    refused = f"{rate_bar['shares']['refused']:.0%} in range but refused on rate"
    assert f"expert against the {bar:g} Mbps bar" in table and refused in table


def test_the_channel_plan_changes_only_at_replans_and_uses_the_usable_channels(wifi_run):
    config, result, _ = wifi_run
    channels = result.runs["expert"].radio.channels
    assert channels.shape == (config.n_steps, N_UAVS)
    assert set(np.unique(channels).tolist()) <= set(config.task.radio.ieee80211.usable_channels)
    changed = np.nonzero(np.any(np.diff(channels, axis=0) != 0, axis=1))[0] + 1
    assert all(step % REPLAN_EVERY == 0 for step in changed)
    wifi = result.summary["planners"]["expert"]["wifi_80211"]
    assert wifi["channels_final"] == channels[-1].tolist()
    assert wifi["channel_changes"] == int(np.count_nonzero(np.diff(channels, axis=0)))


def test_the_co_channel_pairs_are_those_on_one_channel_that_hear_each_other(wifi_run):
    config, result, _ = wifi_run
    run = result.runs["expert"]
    wifi = config.task.radio.ieee80211
    altitudes = config.uav.altitudes_m(N_UAVS)
    seconds: dict[tuple[int, int], float] = {}
    for step in range(config.n_steps):
        power = ap_pair_power_dbm(run.uav_tracks_m[step][None], altitudes[None], wifi)[0]
        for i in range(N_UAVS):
            for j in range(i + 1, N_UAVS):
                sharing = run.radio.channels[step, i] == run.radio.channels[step, j] and \
                    power[i, j] >= wifi.cca_threshold_dbm
                assert bool(run.radio.sharing[step, i, j]) == bool(sharing)
                if sharing:
                    seconds[(i, j)] = seconds.get((i, j), 0.0) + config.dt_s
    reported = result.summary["planners"]["expert"]["wifi_80211"]["co_channel_pairs"]
    assert {tuple(p["uavs"]): p["seconds"] for p in reported} == pytest.approx(seconds)


def test_the_outputs_show_the_radio_channels_and_sinr(wifi_run):
    config, result, out = wifi_run
    run = result.runs["expert"]
    with (out / "outputs" / "timeseries.csv").open() as stream:
        rows = list(csv.DictReader(stream))
    assert len(rows) == config.n_steps
    assert [int(rows[-1][f"channel_uav{k}"]) for k in range(N_UAVS)] == run.radio.channels[-1].tolist()
    assert float(rows[3]["median_sinr_db"]) == pytest.approx(run.radio.median_sinr_db[3], abs=1e-3)
    summary = json.loads((out / "outputs" / "summary.json").read_text())
    assert summary["radio"].startswith("radio: 802.11, urban air-to-ground")
    table = format_summary(summary)
    assert summary["radio"] in table and "expert 802.11: median SINR" in table
    states = read_back(out / "run.mcap")["topics"]
    last = {k: states[f"/uav/{k}/state"]["messages"][-1] for k in range(N_UAVS)}
    assert [last[k]["wifi_channel"] for k in range(N_UAVS)] == run.radio.channels[-1].tolist()
    assert [last[k]["airtime_share"] for k in range(N_UAVS)] == pytest.approx(run.radio.airtime[-1])
    qos = states["/qos"]["messages"][-1]
    assert qos["median_sinr_db"] == pytest.approx(run.radio.median_sinr_db[-1])
    assert qos["co_channel_pairs"] == int(run.radio.sharing[-1].sum())


def test_the_foxglove_scene_shows_each_uav_s_channel_and_whom_it_serves(wifi_run):
    config, result, out = wifi_run
    run = result.runs["expert"]
    topics = read_back(out / "run.mcap")["topics"]
    scene = topics["/scene"]["messages"][-1]
    assert not conform(scene, "foxglove.SceneUpdate")
    entities = {entity["id"]: entity for entity in scene["entities"]}
    assert not entities["coverage"].get("cylinders")  # no coverage disc under 802.11
    texts = [text["text"] for text in entities["channels"]["texts"]]
    cloud = topics["/pedestrians"]["messages"][-1]
    assert [field["name"] for field in cloud["fields"]] == ["x", "y", "z", "covered", "uav"]
    points = np.frombuffer(base64.b64decode(cloud["data"]), "<f4").reshape(-1, 5)
    served = [int(np.count_nonzero(points[:, 4] == k)) for k in range(N_UAVS)]
    channels = run.radio.channels[-1]
    assert texts == [f"UAV {k}, ch {channels[k]}, {served[k]} users" for k in range(N_UAVS)]
    lines = entities["service"].get("lines", [])
    assert sum(len(line["points"]) for line in lines) == 2 * sum(served)  # one line per user served
    assert sum(served) == int(np.count_nonzero(points[:, 3]))  # every user served, no other


def test_one_channel_puts_every_pair_that_hears_each_other_on_shared_airtime(tmp_path):
    task = {**WIFI_TASK, "radio": {"propagation": "802.11", "ieee80211": {"channels": [36]}}}
    result = simulate(_config(task=task, duration_s=0.5), tmp_path, progress=False)
    run = result.runs["expert"]
    assert np.all(run.radio.channels == 36)
    wifi = result.summary["planners"]["expert"]["wifi_80211"]
    assert wifi["channels_used"] == [36] and wifi["channel_changes"] == 0
    # 20 dBm APs 10 m up hear each other far beyond a 200 m area: every pair of APs on takes turns, every
    # step; a UAV the plan gives no users keeps its AP off and shares with none
    assert all(p["seconds"] == pytest.approx(0.5) and p["channels"] == [36] for p in wifi["co_channel_pairs"])
    rng = np.random.default_rng(0)
    uavs = rng.uniform(0.0, 200.0, (N_UAVS, 2))
    radio = RadioConfig.from_dict(task["radio"])
    heights = np.full(N_UAVS, 10.0)
    every = sharing_pairs(uavs, np.full(N_UAVS, 36), radio, heights)
    assert int(every.sum()) == N_UAVS * (N_UAVS - 1) // 2
    on = np.arange(N_UAVS) != 2
    some = sharing_pairs(uavs, np.full(N_UAVS, 36), radio, heights, on)
    assert int(some.sum()) == (N_UAVS - 1) * (N_UAVS - 2) // 2 and not some[2].any() and not some[:, 2].any()


def test_the_paper_radio_reports_no_802_11_figures(tmp_path):
    result = simulate(_config(task=SMALL_PAPER_TASK, duration_s=0.3), tmp_path, progress=False)
    assert result.runs["expert"].radio is None
    assert "wifi_80211" not in result.summary["planners"]["expert"]
    assert result.summary["radio"].startswith("radio: the paper's")
    header = (tmp_path / "timeseries.csv").read_text().splitlines()[0]
    assert header == "planner,time_s,qos_s1,qos_s2,mean_throughput_mbps"


def test_the_802_11_radio_flies_at_the_uav_altitude():
    config = _config(uav={"alt_m": 15.0})
    assert config.task.radio.altitude_m == 15.0
    assert config.task.radio.station_limit is None  # admission on rate is the 802.11 model's own
    assert config.env_config().radio.altitude_m == 0.0  # the environment gives each UAV its own altitude


@pytest.mark.parametrize(("changes", "message"), [
    ({"task": {**WIFI_TASK, "radio": {"propagation": "802.11", "altitude_m": 20.0}}},
     "SimulateConfig.task.radio.altitude_m = 20.0 differs from uav.alt_m = 10.0"),
    ({"task": {**SMALL_WIFI_TASK, "radio": {"propagation": "paper", "altitude_m": 20.0}}},
     "SimulateConfig.task.radio.altitude_m = 20.0: the paper's radio flies at uav.alt_m"),
], ids=["802.11-other-altitude", "paper-altitude"])
def test_a_radio_altitude_the_run_would_not_fly_is_refused_in_one_line(changes, message):
    with pytest.raises(ConfigError, match=message) as error:
        _config(**changes)
    assert "\n" not in str(error.value)
