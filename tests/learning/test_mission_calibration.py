"""The mission operating point: chosen on the validation split by QoS under corr and precision floors."""

import json

import numpy as np
import pytest

from learning import mission_calibration
from learning.checkpoint import load_checkpoint
from learning.mission_calibration import (
    MissionGrid,
    calibrate_mission,
    choose_mission_point,
    margins,
    pareto_front,
    promised_columns,
)
from learning.peaks import PeakConfig
from learning.train import TrainConfig, split_indices
from typed_config import ConfigError
from uav_swarm.cli import main
from uav_swarm.missions.registry import build_task

PAPER = {"corr": 0.75, "precision": 0.75}
GRID = MissionGrid(thresholds=(0.0, 0.05, 5.0), contrasts=(0.0,), distances_px=(2, 3))


def _row(corr, precision, qos):
    return {"corr": corr, "precision": precision, "qos": qos}


def test_the_rule_takes_the_best_qos_above_the_floors_and_never_falls_below_the_balanced_point():
    balanced = _row(0.80, 0.70, 0.50)  # precision under the paper's 0.75: its own 0.70 is the floor
    rows = [_row(0.90, 0.69, 0.95), _row(0.74, 0.90, 0.90), _row(0.85, 0.72, 0.70), _row(0.87, 0.71, 0.70)]
    assert choose_mission_point(rows, PAPER, balanced) is rows[3]  # QoS tie: higher corr + precision
    assert choose_mission_point(rows[:2], PAPER, balanced) is balanced
    assert [r["precision"] for r in pareto_front([balanced, *rows])] == [0.69, 0.9]


def _spread(row, se):
    return {**row, "qos_relative": row["qos"], "corr_se": se, "precision_se": se, "qos_relative_se": se}


def test_the_margin_keeps_out_a_point_whose_validation_lead_is_within_its_spread():
    paper = {**PAPER, "qos": 0.9}
    balanced = _spread(_row(0.80, 0.76, 0.50), 0.0)  # over both floors: the floors are the paper's
    close = _spread(_row(0.90, 0.755, 0.95), 0.01)  # precision 0.5 points over the paper's, se 1 point
    clear = _spread(_row(0.90, 0.80, 0.94), 0.01)
    assert choose_mission_point([close, clear], paper, balanced) is close  # no margin: the best QoS
    assert choose_mission_point([close, clear], paper, balanced, margin_z=2.0) is clear
    assert margins(clear, 2.0)["precision"] == pytest.approx(2.0 * np.sqrt(2.0) * 0.01)
    assert promised_columns(close, paper, 0.0) == ["corr", "precision", "qos"]
    assert promised_columns(close, paper, 2.0) == ["corr", "qos"]
    assert promised_columns(clear, paper, 2.0) == ["corr", "precision", "qos"]
    assert promised_columns(clear, paper, 5.0) == ["corr"]


def test_a_point_promising_more_of_the_papers_columns_wins_over_a_higher_qos():
    paper = {**PAPER, "qos": 0.9}
    balanced = _row(0.70, 0.70, 0.50)  # under both floors: the floors are its own
    corr_only = {**_row(0.90, 0.72, 0.99), "qos_relative": 0.99}
    whole_row = {**_row(0.80, 0.76, 0.91), "qos_relative": 0.91}
    assert choose_mission_point([corr_only, whole_row], paper, balanced) is whole_row
    assert choose_mission_point([corr_only], paper, balanced) is corr_only


def test_a_grid_outside_the_peak_ranges_is_refused():
    with pytest.raises(ConfigError, match="distances_px"):
        MissionGrid(distances_px=(0,))
    with pytest.raises(ConfigError, match="regions"):
        MissionGrid(regions=("inside",))


def test_the_grid_tries_each_region_at_each_point():
    grid = MissionGrid(thresholds=(0.1, 0.2), contrasts=(0.0,), distances_px=(2,), regions=("any", "filled"))
    configs = grid.configs(PeakConfig(min_contrast=0.05))
    assert [(c.region, c.threshold_abs) for c in configs] == [
        ("any", 0.1), ("any", 0.2), ("filled", 0.1), ("filled", 0.2)]


def test_calibration_scores_the_validation_split_and_resumes_from_its_cache(tiny_checkpoint, tmp_path,
                                                                              monkeypatch):
    ckpt = load_checkpoint(tiny_checkpoint)
    task = build_task("wifi-s1", ckpt.task_config)
    report = calibrate_mission(ckpt, task, PAPER, tmp_path / "cache", grid=GRID, progress=False)
    _, val = split_indices(ckpt.payload["data"]["n"], TrainConfig.from_dict(ckpt.payload["train_config"]))
    assert report["n_validation"] == len(val) >= 1
    assert len(report["rows"]) == 6 and report["floors"]["corr"] <= PAPER["corr"]
    unreachable = [r for r in report["rows"] if r["threshold_abs"] == 5.0]
    assert all(r["n_predicted"] == 0 and r["qos"] == 0.0 for r in unreachable)  # no peak that high
    assert report["mission"]["qos"] >= report["balanced"]["qos"]
    assert all(0.0 <= r["qos_relative"] for r in report["rows"])
    assert all(r["corr_se"] >= 0.0 and r["precision_se"] >= 0.0 and r["qos_relative_se"] >= 0.0
               for r in report["rows"])
    assert report["margin_z"] == 2.0
    for point in ("mission", "balanced"):
        row = report[point]
        assert row["promises"] == promised_columns(row, PAPER, 2.0)
        assert row["margins"]["corr"] == pytest.approx(2.0 * np.sqrt(2.0) * row["corr_se"])
    with pytest.raises(ValueError, match="margin_z"):
        calibrate_mission(ckpt, task, PAPER, tmp_path / "cache", grid=GRID, margin_z=-1.0, progress=False)

    def no_generation(*args, **kwargs):
        raise AssertionError("the cached validation scenes must be reused")

    monkeypatch.setattr(mission_calibration, "generate_samples", no_generation)
    again = calibrate_mission(ckpt, task, PAPER, tmp_path / "cache", grid=GRID, progress=False)
    assert again["rows"] == report["rows"]


def test_the_command_writes_the_report_and_a_checkpoint_carrying_both_points(tiny_checkpoint, tmp_path,
                                                                            capsys):
    out, written = tmp_path / "points", tmp_path / "both.pt"
    assert main(["calibrate-mission", "--task", "wifi-s1", "--checkpoint", str(tiny_checkpoint),
                 "--out", str(out), "--thresholds", "0.0", "0.05", "--contrasts", "0.0",
                 "--distances-px", "2", "--margin-z", "1.5",
                 "--write-checkpoint", str(written)]) == 0
    report = json.loads((out / "calibration.json").read_text())
    assert "| mission |" in (out / "front.md").read_text() and "| balanced |" in capsys.readouterr().out
    both = load_checkpoint(written)
    mission = both.mission_peak_config
    assert mission is not None and mission.threshold_abs == report["mission"]["threshold_abs"]
    assert both.peak_config == load_checkpoint(tiny_checkpoint).peak_config
    record = both.payload["mission_calibration"]
    assert record["floors"] == report["floors"] and record["margin_z"] == 1.5
    assert record["mission"]["promises"] == report["mission"]["promises"]
    assert "| promises |" in (out / "front.md").read_text()
    original = load_checkpoint(tiny_checkpoint).model.state_dict()
    for name, value in both.model.state_dict().items():
        np.testing.assert_array_equal(value.numpy(), original[name].numpy())
    assert main(["calibrate-mission", "--task", "wifi-s1", "--checkpoint", str(tiny_checkpoint),
                 "--out", str(tmp_path / "never"), "--distances-px", "0"]) == 2
    assert "distances_px" in capsys.readouterr().err and not (tmp_path / "never").exists()
    assert main(["calibrate-mission", "--task", "wifi-s1", "--checkpoint", str(tiny_checkpoint),
                 "--out", str(tmp_path / "never"), "--margin-z", "-1"]) == 2
    assert "--margin-z" in capsys.readouterr().err and not (tmp_path / "never").exists()
