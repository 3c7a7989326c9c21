"""Peak settings a user gives are applied over a checkpoint's operating point, or refused, and recorded."""

import json
from importlib import resources
from pathlib import Path

import pytest
import torch

from learning.checkpoint import load_checkpoint, save_checkpoint
from learning.operating_points import PeakOverrides, choose_peaks
from learning.peaks import PeakConfig
from typed_config import ConfigError
from uav_swarm.cli import main

ROOT = Path(__file__).resolve().parents[2]
BALANCED = PeakConfig(threshold_abs=0.15, min_contrast=0.0)
MISSION = PeakConfig(threshold_abs=0.05, min_contrast=0.02, min_distance_px=3)


def test_the_mission_point_runs_by_default_where_the_checkpoint_has_one():
    assert choose_peaks(BALANCED, MISSION).config == MISSION
    assert choose_peaks(BALANCED, MISSION).source == "checkpoint (mission point)"
    assert choose_peaks(BALANCED, None).config == BALANCED
    chosen = choose_peaks(BALANCED, MISSION, operating_point="balanced")
    assert (chosen.config, chosen.operating_point) == (BALANCED, "balanced")
    with pytest.raises(ConfigError, match="carries no mission point"):
        choose_peaks(BALANCED, None, operating_point="mission")
    with pytest.raises(ConfigError, match="'sharp' is not allowed"):
        choose_peaks(BALANCED, MISSION, operating_point="sharp")


def test_the_users_values_apply_over_the_point_and_the_source_names_them():
    chosen = choose_peaks(BALANCED, MISSION, {"threshold_abs": 0.9}, source="config file a.toml")
    assert chosen.config == MISSION.replace(threshold_abs=0.9)
    assert chosen.source == "config file a.toml ([peaks] threshold_abs) over the checkpoint (mission point)"
    assert chosen.to_dict()["overridden"] == ["threshold_abs"]
    planner = choose_peaks(BALANCED, None, PeakOverrides(max_peaks=4), table="[planning.peaks]")
    assert planner.config == BALANCED.replace(max_peaks=4) and "[planning.peaks] max_peaks" in planner.source


@pytest.mark.parametrize(("table", "match"), [
    ({"threshold": 0.2}, r"unknown key\(s\) \['peaks\.threshold'\] \(did you mean 'peaks\.threshold_rel'"),
    ({"min_distance_px": 0}, r"\[peaks\].*min_distance_px = 0 is out of range"),
    ({"threshold_rel": 2.0}, r"\[peaks\].*threshold_rel = 2.0 is out of range"),
])
def test_a_value_that_cannot_apply_is_refused_naming_it(table, match):
    with pytest.raises(ConfigError, match=match):
        choose_peaks(BALANCED, MISSION, table)


def test_a_value_another_setting_fixes_is_refused():
    fixed = {"threshold_abs": (0.2, "the rule check ([rule_check])")}
    assert choose_peaks(BALANCED, MISSION, fixed=fixed).config.threshold_abs == 0.2
    with pytest.raises(ConfigError, match=r"\[peaks\] threshold_abs = 0.05 cannot apply: the rule check"):
        choose_peaks(BALANCED, MISSION, {"threshold_abs": 0.05}, fixed=fixed)


def _agp_config(tmp_path: Path, name: str, peaks: str) -> Path:
    path = tmp_path / f"{name}.toml"
    path.write_text((ROOT / "configs/tasks/agp.toml").read_text() + f"\n[peaks]\n{peaks}\n")
    return path


def _evaluate(tmp_path: Path, name: str, checkpoint: Path, *options: str) -> dict:
    out = tmp_path / name
    assert main(["evaluate", "--task", "agp", "--checkpoint", str(checkpoint), "--n", "6", "--seed", "41",
                 "--data", str(tmp_path / "test-data"), "--out", str(out), "--workers", "1",
                 "--examples", "0",
                 *options]) == 0
    return json.loads((out / "results.json").read_text())


def _shipped_agp() -> Path:
    return Path(str(resources.files("uav_swarm") / "checkpoints" / "agp.pt"))


def test_evaluate_applies_a_peaks_table_and_summary_names_what_ran(tmp_path):
    low = _evaluate(tmp_path, "low", _shipped_agp(), "--config",
                    str(_agp_config(tmp_path, "low", "threshold_abs = 0.05")))
    high = _evaluate(tmp_path, "high", _shipped_agp(), "--config",
                     str(_agp_config(tmp_path, "high", "threshold_abs = 0.9")))
    placements = [[s["predicted"] for s in run["samples"]] for run in (low, high)]
    assert placements[0] != placements[1]
    assert low["summary"]["n_predicted"] > high["summary"]["n_predicted"]
    for run, threshold in ((low, 0.05), (high, 0.9)):
        peaks = run["summary"]["peaks"]
        assert peaks["settings"]["threshold_abs"] == threshold == run["peak_config"]["threshold_abs"]
        assert peaks["source"].startswith("config file ") and "([peaks] threshold_abs)" in peaks["source"]
        assert peaks["overridden"] == ["threshold_abs"]


def test_evaluate_runs_the_mission_point_unless_asked_for_the_balanced_one(tmp_path):
    payload = torch.load(_shipped_agp(), map_location="cpu", weights_only=True)
    payload["peak_config"] = BALANCED.to_dict()
    payload["peak_config_mission"] = MISSION.to_dict()
    both = tmp_path / "both.pt"
    save_checkpoint(both, payload)
    assert load_checkpoint(both).mission_peak_config == MISSION
    default = _evaluate(tmp_path, "default", both)["summary"]["peaks"]
    balanced = _evaluate(tmp_path, "balanced", both, "--operating-point", "balanced")["summary"]["peaks"]
    assert (default["operating_point"], default["settings"]) == ("mission", MISSION.to_dict())
    assert default["source"] == "checkpoint (mission point)"
    assert (balanced["operating_point"], balanced["settings"]) == ("balanced", BALANCED.to_dict())
    del payload["peak_config_mission"]
    single = tmp_path / "single.pt"
    save_checkpoint(single, payload)
    assert main(["evaluate", "--task", "agp", "--checkpoint", str(single), "--n", "2", "--seed", "41",
                 "--out", str(tmp_path / "refused"), "--operating-point", "mission"]) == 2
    assert not (tmp_path / "refused").exists()


def test_evaluate_refuses_a_bad_peaks_value_and_writes_nothing(tmp_path, capsys):
    config = _agp_config(tmp_path, "bad", "min_distance_px = 0")
    assert main(["evaluate", "--task", "agp", "--checkpoint", str(_shipped_agp()), "--n", "2", "--seed", "41",
                 "--out", str(tmp_path / "bad"), "--config", str(config)]) == 2
    assert "min_distance_px" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()


def test_evaluate_says_which_columns_the_point_promises_and_whether_they_held(tmp_path):
    payload = torch.load(_shipped_agp(), map_location="cpu", weights_only=True)
    assert "promises" not in payload["mission_calibration"]["mission"]  # calibrated before the margin
    unmargined = _evaluate(tmp_path, "unmargined", _shipped_agp())["summary"]["promises"]
    assert unmargined["columns"] == [] and "without a margin" in unmargined["basis"]
    payload["peak_config_mission"] = MISSION.to_dict()
    payload["mission_calibration"] = {  # a corr no row misses and a precision no row reaches
        "paper": {"corr": 0.0, "precision": 1.01, "qos": 0.97}, "margin_z": 2.0, "n_validation": 10,
        "mission": {"promises": ["corr", "precision"]}, "balanced": {"promises": []}}
    promising = tmp_path / "promising.pt"
    save_checkpoint(promising, payload)
    summary = _evaluate(tmp_path, "mission", promising)["summary"]
    promises = summary["promises"]
    assert promises["columns"] == ["corr", "precision"] and promises["margin_z"] == 2.0
    assert promises["held"]["corr"] == {"value": summary["corr"], "met": True}
    assert promises["held"]["precision"] == {"value": summary["precision"], "met": False}
    line = (tmp_path / "mission" / "results.md").read_text()
    assert "Promises (the mission point's validation figures less 2.0 standard errors" in line
    assert "precision >= 101.0 %" in line and "MISSED" in line
    balanced = _evaluate(tmp_path, "balanced", promising, "--operating-point", "balanced")["summary"]
    assert balanced["promises"]["columns"] == []
    given = _evaluate(tmp_path, "given", promising, "--config",
                      str(_agp_config(tmp_path, "given", "threshold_abs = 0.05")))["summary"]["promises"]
    assert given["columns"] == [] and "differ from the calibrated point" in given["basis"]
