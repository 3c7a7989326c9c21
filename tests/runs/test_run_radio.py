"""The radio a run flies: 802.11 unless told, tasks that mean what they say, networks that match the radio."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from learning.checkpoint import load_checkpoint
from typed_config import ConfigError
from uav_swarm.cli import main
from uav_swarm.missions.registry import make_task
from uav_swarm.planning.planner import default_checkpoint, shipped_checkpoint_name
from uav_swarm.runs import radio_altitude
from uav_swarm.runs.fly_config import FlyConfig
from uav_swarm.runs.simulate_config import SimulateConfig, load_simulate_config
from uav_swarm.world.comms import evaluate_coverage

ROOT = Path(__file__).resolve().parents[2]
BRIDGE = str(ROOT / "configs" / "bridge" / "ardupilot_sitl_10.toml")


def test_simulate_and_fly_fly_the_802_11_radio_unless_told():
    for config in (load_simulate_config(None, {}), FlyConfig.from_dict({"bridge_config": BRIDGE}),
                   SimulateConfig()):
        radio = config.task.radio
        assert (radio.propagation, radio.altitude_m) == ("802.11", config.uav.alt_m)
        assert radio.ieee80211.rate_admission is False  # strategy 1: a usable rate, nobody refused on rate
        assert shipped_checkpoint_name(config.task) == "wifi-s1-80211"
    two = SimulateConfig.from_dict({"task": {"strategy": 2}, "uav": {"alt_m": 15.0}})
    assert two.task.radio.ieee80211.rate_admission is True and two.task.radio.altitude_m == 15.0
    assert shipped_checkpoint_name(two.task) == "wifi-s2-80211"
    paper = SimulateConfig.from_dict({"task": {"strategy": 2, "radio": {"propagation": "paper"}}})
    assert paper.task.radio.association_name == "admission control (40 stations per UAV)"
    assert shipped_checkpoint_name(paper.task) == "wifi-s2-ac"


def test_a_value_given_is_applied_or_refused_never_dropped():
    given = SimulateConfig.from_dict({"task": {"radio": {"ieee80211": {"rate_admission": True}}}})
    assert given.task.radio.ieee80211.rate_admission is True
    with pytest.raises(ConfigError, match="range_m belongs to propagation = 'paper': set propagation = "
                                          "'paper' for it") as error:
        SimulateConfig.from_dict({"task": {"radio": {"range_m": 40.0}}})
    assert "\n" not in str(error.value)
    with pytest.raises(ConfigError, match="station_limit = 'auto' .* belongs to propagation = 'paper'"):
        SimulateConfig.from_dict({"task": {"strategy": 2, "radio": {"station_limit": "auto"}}})


def test_strategy_1_under_802_11_serves_every_user_with_a_usable_rate():
    """The README's one line (`propagation = "802.11"`) counts the users with a usable rate."""
    config = SimulateConfig.from_dict({"task": {"radio": {"propagation": "802.11"}}})
    users = np.random.default_rng(3).normal(100.0, 6.0, (200, 2))  # 200 users under one UAV
    cov = evaluate_coverage(users, np.array([[100.0, 100.0]]), config.task.radio, np.array([10.0]))
    assert cov.qos_s1 == 1.0 and cov.in_range.all()
    admitted = config.task.radio.replace(ieee80211=config.task.radio.ieee80211.replace(rate_admission=True))
    assert evaluate_coverage(users, np.array([[100.0, 100.0]]), admitted, np.array([10.0])).qos_s1 < 0.5


@pytest.mark.parametrize(("toml", "flags", "message"), [
    ("", ["--checkpoint", "{shipped}/wifi-s1.pt"],
     "wifi-s1.pt: trained for the paper's radio without admission control, this run flies strategy 1 on the "
     "802.11 radio without admission on rate: leave --checkpoint out (the shipped one for this task is "
     "uav_swarm/checkpoints/wifi-s1-80211.pt)"),
    ('[task]\nstrategy = 2\n[task.radio]\npropagation = "paper"\n', ["--checkpoint", "{shipped}/wifi-s2.pt"],
     "wifi-s2.pt: trained for the paper's radio without admission control, this run flies strategy 2 on the "
     "paper's radio with admission control (40 stations per UAV)"),
    ("[task]\nstrategy = 2\n[task.radio.ieee80211]\nrate_admission = false\n", [],
     "wifi-s2-80211.pt: trained for the 802.11 radio with admission on rate, this run flies strategy 2 on "
     "the 802.11 radio without admission on rate: train one for it"),
    ("[task]\nstrategy = 2\n", ["--checkpoint", "{shipped}/wifi-s1-80211.pt"],
     "wifi-s1-80211.pt: trained on task 'wifi-s1', not 'wifi-s2'"),
], ids=["radio", "admission-control", "admission-on-rate", "strategy"])
def test_a_network_trained_for_another_radio_strategy_or_admission_is_refused_in_one_line(
        tmp_path, capsys, toml, flags, message):
    config = tmp_path / "run.toml"
    config.write_text(toml, encoding="utf-8")
    shipped = str(default_checkpoint().parent)
    out = tmp_path / "never"
    argv = ["simulate", "--out", str(out), "--config", str(config), "--no-telemetry", "--quiet"]
    assert main(argv + [flag.format(shipped=shipped) for flag in flags]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not out.exists()


@pytest.mark.parametrize("run_default", ["802.11", "paper"])
@pytest.mark.parametrize("name", ["wifi-s1", "wifi-s2", "agp", "fp"])
def test_the_papers_learning_table_stays_on_the_papers_radio_whatever_the_runs_default(
        monkeypatch, run_default, name):
    """`evaluate` builds each row's task from its task file and the shipped network must match it."""
    monkeypatch.setattr(radio_altitude, "RUN_PROPAGATION", run_default)
    task = make_task(name, ROOT / "configs" / "tasks" / f"{name}.toml")
    load_checkpoint(default_checkpoint(name), task_name=name, task_config=task.config)  # equal, or it raises
    radio = getattr(task.config, "radio", None)
    assert radio is None or radio.propagation == "paper"
    assert SimulateConfig.from_dict({}).task.radio.propagation == run_default  # the runs did move
