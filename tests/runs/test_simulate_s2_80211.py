"""``configs/simulate/wifi-s2-80211.toml``: strategy 2 under the 802.11 radio, as a network engineer runs it.

The config must load to what the shipped strategy-2 802.11 network learned (the 802.11 radio with admission
on rate, the task file's radio), fly that network, and a short run must print why its QoS S2 is what it is.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from learning.checkpoint import load_checkpoint
from typed_config import load_toml
from uav_swarm.cli import main
from uav_swarm.missions.wifi.task import WifiConfig
from uav_swarm.planning.planner import default_checkpoint
from uav_swarm.runs.simulate_config import load_simulate_config
from uav_swarm.world.radio_config import RadioConfig

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / "configs/simulate/wifi-s2-80211.toml"


def test_the_config_flies_strategy_2_on_the_radio_the_shipped_network_learned():
    config = load_simulate_config(CONFIG)
    trained = load_toml(WifiConfig, ROOT / "configs/tasks/wifi-s2-80211.toml", section="task")
    radio = config.task.radio
    assert config.task.strategy == 2 and config.planner == "learned" and not config.planning.refine
    assert radio.propagation == "802.11" and radio.ieee80211.admits_on_rate
    assert radio.min_user_rate_mbps == 5.0
    assert radio.radio_and_admission == trained.radio.radio_and_admission
    assert radio.replace(ieee80211=radio.ieee80211.replace(channels=())) == trained.radio  # the same radio
    assert radio.ieee80211.usable_channels == trained.radio.ieee80211.usable_channels
    assert radio.altitude_m == config.uav.alt_m == trained.radio.altitude_m
    shipped = load_checkpoint(default_checkpoint("wifi-s2-80211")).task_config
    learned = RadioConfig.from_dict(shipped["radio"]).for_strategy(int(shipped["strategy"]))
    assert learned.replace(ieee80211=learned.ieee80211.replace(channels=radio.ieee80211.channels)) == radio


def test_a_short_run_names_the_network_and_says_why_s2_is_lower(tmp_path, capsys):
    out, planner = tmp_path / "out", "learned"
    argv = ["simulate", "--config", str(CONFIG), "--out", str(out), "--duration-s", "2", "--n-uavs", "4",
            "--planner", planner, "--no-expert", "--no-telemetry", "--no-gif", "-q"]
    assert main(argv) == 0, capsys.readouterr().err
    printed = capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    figures = summary["planners"][planner]
    assert summary["checkpoint"] == "uav_swarm/checkpoints/wifi-s2-80211.pt (shipped)"
    assert figures["association"] == "802.11 (airtime fairness, admission on rate (5 Mbps))"
    shares = figures["wifi_80211"]["rate_bar"]["shares"]
    assert sum(shares.values()) == pytest.approx(1.0)
    assert shares["at the rate bar"] == pytest.approx(figures["mean_qos_s2"], abs=1e-12)
    assert shares["at the rate bar"] + shares["below the rate bar"] == pytest.approx(figures["mean_qos_s1"],
                                                                                    abs=1e-12)
    line = next(row for row in printed.splitlines() if "against the 5 Mbps bar" in row)
    assert f"{shares['refused']:.0%} in range but refused on rate" in line
    assert "strategy 2 refuses users that strategy 1 would serve" in line


class _SpareLeavingPlanner:
    """Four UAVs: the first three fly to fixed points over the crowd, the fourth is given no users."""

    name = "spare-leaving"
    n_uavs = 4

    def plan(self, pedestrians_m, uavs_m, velocities_m_s=None):
        import numpy as np

        from uav_swarm.planning.base import PlanResult

        targets = np.array([[60.0, 60.0], [100.0, 100.0], [140.0, 140.0], [100.0, 40.0]])
        return PlanResult(targets_m=targets, peaks_m=targets[:3], utility=None,
                          candidate_index=np.array([0, 1, 2, -1]), kept=np.zeros(4, bool), latency_ms=0.0)

    def reset(self):
        pass


def test_a_uav_the_plan_gives_no_users_keeps_its_access_point_off():
    """The spare serves nobody and shares airtime with nobody; the UAVs that serve keep their users."""
    import numpy as np

    from uav_swarm.runs.simulate import run_sequence

    config = load_simulate_config(CONFIG).replace(n_uavs=4, duration_s=3.0, gif=False,
                                                  publish_telemetry=False, static_reference=False)
    run = run_sequence(config, _SpareLeavingPlanner(), "expert")
    trace = run.radio
    assert trace is not None and trace.stations.shape[1] == 4
    assert np.all(trace.stations[:, 3] == 0)  # off: nobody joins it
    assert np.all(trace.airtime[:, 3] == 0.0)
    assert not trace.sharing[:, 3, :].any() and not trace.sharing[:, :, 3].any()
    assert trace.stations[-1, :3].sum() > 0  # the others serve
