"""Choosing the rule check's settings on the validation split (``uav-swarm calibrate-check``)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from learning.check_calibration import calibrate_check
from uav_swarm.cli import main
from uav_swarm.missions.registry import TaskFactory, build_rule_check

GRID = [{"threshold_abs": t, "slack_users": s} for t in (0.0, 0.05) for s in (0, 30)]


def data_of(checkpoint: str) -> Path:
    return Path(checkpoint).parent.parent / "data"  # the tiny checkpoint's training data (conftest)


@pytest.fixture(scope="module")
def task(small_wifi_task):
    return TaskFactory("wifi-s1", small_wifi_task)()


def test_every_point_is_scored_and_the_choice_follows_the_rule(tiny_checkpoint, task):
    report = calibrate_check(tiny_checkpoint, task, data_of(tiny_checkpoint),
                             lambda s: build_rule_check(task, s), GRID, qos_floor=0.0)
    assert report["n_validation"] == 2  # 10 % of the 16 training scenes, as training split them
    assert [(r["threshold_abs"], r["slack_users"]) for r in report["rows"]] == [
        (g["threshold_abs"], g["slack_users"]) for g in GRID]
    assert 0.0 < report["expert_qos"] <= 1.0
    best = max(report["rows"], key=lambda r: r["corr"] + r["precision"])
    assert report["chosen"]["corr"] + report["chosen"]["precision"] == best["corr"] + best["precision"]
    by_point = {(r["threshold_abs"], r["slack_users"]): r for r in report["rows"]}
    for threshold in (0.0, 0.05):  # a stricter check keeps fewer UAVs
        assert by_point[threshold, 0]["n_predicted"] <= by_point[threshold, 30]["n_predicted"]
    assert "corr" in report["unchecked"] and report["unchecked"]["threshold_abs"] > 0


def test_an_unreachable_floor_chooses_the_best_qos(tiny_checkpoint, task):
    report = calibrate_check(tiny_checkpoint, task, data_of(tiny_checkpoint),
                             lambda s: build_rule_check(task, s), GRID, qos_floor=1.5)
    assert report["chosen"]["qos_relative"] == max(r["qos_relative"] for r in report["rows"])


def test_the_command_writes_the_report_and_refuses_bad_input(tiny_checkpoint, small_wifi_task, tmp_path,
                                                             capsys):
    settings = tmp_path / "s1.toml"
    scenario = small_wifi_task["scenario"]
    top = "".join(f"{k} = {v}\n" for k, v in small_wifi_task.items() if k != "scenario")
    nested = "".join(f"{k} = {v}\n" for k, v in scenario.items())
    settings.write_text("[task]\n" + top + "[task.scenario]\n" + nested)
    common = ["calibrate-check", "--task", "wifi-s1", "--config", str(settings), "--checkpoint",
              str(tiny_checkpoint), "--data", str(data_of(tiny_checkpoint)), "--thresholds", "0.0", "0.05",
              "--slacks", "0", "30"]
    out = tmp_path / "report.json"
    assert main([*common, "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    report = json.loads(out.read_text())
    assert len(report["rows"]) == 4 and "**chosen**" in printed and "[rule_check]" in printed
    bad = tmp_path / "bad.json"
    assert main([*common, "--out", str(bad), "--qos-floor", "0"]) == 2
    assert main([*common[:-4], "--thresholds", "-1", "--out", str(bad)]) == 2
    assert "argument --thresholds: -1 is out of range" in capsys.readouterr().err
    assert main([*common[:3], "--checkpoint", str(tiny_checkpoint), "--data", str(data_of(tiny_checkpoint)),
                 "--out", str(bad)]) == 2  # the shipped [task] defaults: not the data's config
    assert "another config" in capsys.readouterr().err
    assert not bad.exists()
