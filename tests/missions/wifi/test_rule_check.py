"""The Wi-Fi deployment rule checked on learned placements from the density raster alone."""

from __future__ import annotations

import json

import numpy as np
import pytest

from learning.task import PlacementCheck
from typed_config import ConfigError
from uav_swarm.cli import main
from uav_swarm.missions.registry import build_rule_check, build_task, load_settings
from uav_swarm.missions.wifi.rule_check import RuleCheckConfig, drop_unjustified, raster_users
from uav_swarm.missions.wifi.rules import CoverageRules
from uav_swarm.missions.wifi.task import WifiConfig, WifiTask
from uav_swarm.planning.planner import default_checkpoint

S1 = CoverageRules(radius_m=30.0, min_users=31, max_users=None, max_uavs=10, exclusive=True)
S2 = CoverageRules(radius_m=30.0, min_users=31, max_users=40, max_uavs=10, exclusive=False)


def group(centre, n, rng, spread=3.0):
    return np.asarray(centre) + rng.normal(0.0, spread, (n, 2))


def test_a_uav_over_a_small_group_is_dropped_and_a_justified_one_kept():
    rng = np.random.default_rng(0)
    users = np.vstack([group((50, 50), 45, rng), group((150, 150), 20, rng)])
    uavs = np.array([[150.0, 150.0], [50.0, 50.0]])
    np.testing.assert_array_equal(drop_unjustified(users, uavs, S1, 0), [[50.0, 50.0]])
    np.testing.assert_array_equal(drop_unjustified(users, uavs, S1, 11), uavs)  # 20 >= 31 - 11
    assert drop_unjustified(users, np.zeros((0, 2)), S1, 0).shape == (0, 2)


def test_strategy_1_counts_exclusive_users_and_strategy_2_served_users():
    rng = np.random.default_rng(1)
    users = group((100, 100), 60, rng, spread=2.0)
    twins = np.array([[98.0, 100.0], [102.0, 100.0]])  # both cover the whole group
    # S1: neither covers anyone alone -> the least justified is dropped, then the other is alone
    assert len(drop_unjustified(users, twins, S1, 0)) == 1
    # S2: each serves its nearer half (about 30 each); with 10 users of slack both stand
    served = drop_unjustified(users, twins, S2, 10)
    assert len(served) == 2


def test_the_least_justified_uav_goes_first_and_the_order_is_kept():
    rng = np.random.default_rng(2)
    users = np.vstack([group((40, 40), 50, rng), group((100, 100), 28, rng), group((160, 160), 35, rng)])
    uavs = np.array([[160.0, 160.0], [100.0, 100.0], [40.0, 40.0]])
    np.testing.assert_array_equal(drop_unjustified(users, uavs, S1, 0), [[160.0, 160.0], [40.0, 40.0]])


def test_raster_users_recover_the_crowd_at_pixel_centres():
    task = WifiTask(WifiConfig(strategy=1))
    scene = task.sample(np.random.default_rng(4))
    pixels, counts = raster_users(task.observe(scene), task.config.density_scale)
    assert counts.sum() == len(scene.users_m)
    inside = task.to_pixels(scene.users_m)
    rounded = {tuple(p) for p in np.rint(inside).astype(int)}
    assert {tuple(p) for p in pixels.astype(int)} == rounded


def test_the_check_keeps_a_subset_of_the_proposals_and_the_experts_placement():
    task = build_task("wifi-s1")
    check = build_rule_check(task)
    assert isinstance(check, PlacementCheck)
    rng = np.random.default_rng(5)
    for _ in range(3):
        scene = task.sample(rng)
        expert = task.expert(scene)
        observation = task.observe(scene)
        noise = rng.uniform(0, 63, (6, 2))  # peaks over random places, mostly unjustified
        proposals = np.vstack([expert, noise])
        kept = check(observation, proposals)
        assert {tuple(np.round(p, 6)) for p in kept} <= {tuple(np.round(p, 6)) for p in proposals}
        assert len(check(observation, expert)) == len(expert)  # the expert's UAVs all pass


def test_the_rule_check_table_is_validated_and_only_wifi_has_one(tmp_path):
    check = build_rule_check(build_task("wifi-s2"), {"threshold_abs": 0.15, "slack_users": 2})
    assert check.config == RuleCheckConfig(threshold_abs=0.15, slack_users=2)
    assert check.settings() == {"threshold_abs": 0.15, "slack_users": 2}
    settings = tmp_path / "s1.toml"
    settings.write_text("[rule_check]\nslack_users = -1\n")
    with pytest.raises(ConfigError, match=r"\[rule_check\].*slack_users"):
        load_settings("wifi-s1", settings)
    settings.write_text("[rule_check]\nslack_users = 1\n")
    with pytest.raises(ConfigError, match="no rule check"):
        load_settings("agp", settings)
    with pytest.raises(TypeError, match="no rule check"):
        build_rule_check(build_task("agp"))


def test_evaluate_with_the_rule_check_keeps_only_justified_peaks(tmp_path, capsys):
    settings = tmp_path / "s1.toml"
    settings.write_text("[rule_check]\nthreshold_abs = 0.05\nslack_users = 0\n")
    plain, checked = tmp_path / "plain", tmp_path / "checked"
    common = ["evaluate", "--task", "wifi-s1", "--checkpoint", str(default_checkpoint("wifi-s1")), "--n", "6",
              "--seed", "93", "--examples", "0", "--workers", "1", "--config", str(settings)]
    assert main([*common, "--out", str(plain)]) == 0
    assert main([*common, "--out", str(checked), "--data", str(plain / "test-data"), "--rule-check"]) == 0
    summary = json.loads((checked / "summary.json").read_text())
    assert summary["check"] == {"threshold_abs": 0.05, "slack_users": 0}
    task = build_task("wifi-s1")
    kept_counts = {}
    for sample in json.loads((checked / "results.json").read_text())["samples"]:
        scene = task.sample(np.random.default_rng(sample["seed"]))
        pixels, counts = raster_users(task.observe(scene), task.config.density_scale)
        users = np.repeat(task.to_metres(pixels), counts, axis=0)
        kept = task.to_metres(np.asarray(sample["predicted"]).reshape(-1, 2))
        kept_counts[sample["seed"]] = len(kept)
        # every kept UAV is justified on the raster: dropping nothing more
        np.testing.assert_allclose(drop_unjustified(users, kept, task.rules, 0), kept)
    assert sum(kept_counts.values()) > 0


def test_evaluate_refuses_the_rule_check_for_a_task_without_one(tmp_path, capsys):
    out = tmp_path / "agp"
    assert main(["evaluate", "--task", "agp", "--checkpoint", str(default_checkpoint("agp")), "--n", "2",
                 "--seed", "94", "--examples", "0", "--workers", "1", "--out", str(out), "--rule-check"]) == 2
    assert "no rule check" in capsys.readouterr().err
    assert not out.exists()  # refused before any scene was generated
