"""Ctrl-C during ``simulate`` keeps the part flown, says so, and exits 130.

The interrupt is raised where Ctrl-C lands in a real run (inside the planner's replan, during the step
loop), at a chosen replan, so the test does not depend on timing.
"""

from __future__ import annotations

import json

import pytest

from conftest import SMALL_PAPER_TASK
from uav_swarm.cli import main
from uav_swarm.planning import planner as planner_module


def _interrupt_at(monkeypatch, kind_class: str, call: int) -> None:
    """The ``call``-th replan of planners of class ``kind_class`` raises KeyboardInterrupt (Ctrl-C)."""
    cls = getattr(planner_module, kind_class)
    original, calls = cls.plan, {"n": 0}

    def plan(self, *args, **kwargs):
        calls["n"] += 1
        if calls["n"] == call:
            raise KeyboardInterrupt
        return original(self, *args, **kwargs)

    monkeypatch.setattr(cls, "plan", plan)


@pytest.fixture()
def config(tmp_path, tiny_checkpoint):
    path = tmp_path / "sim.toml"
    scenario = SMALL_PAPER_TASK["scenario"]
    path.write_text(
        f'n_uavs = 3\nduration_s = 4.0\nreplan_every = 5\ngif_max_frames = 6\ngif_width_px = 900\n'
        f'publish_telemetry = false\ncheckpoint = "{tiny_checkpoint}"\n\n[task]\n'
        f'warmup_min_s = {SMALL_PAPER_TASK["warmup_min_s"]}\n'
        f'warmup_max_s = {SMALL_PAPER_TASK["warmup_max_s"]}\n'
        '\n[task.scenario]\n' + "".join(f"{key} = {value}\n" for key, value in scenario.items())
        + '\n[task.radio]\npropagation = "paper"\n', encoding="utf-8")
    return path


def test_ctrl_c_in_the_flown_run_keeps_its_first_seconds_and_exits_130(tmp_path, config, monkeypatch, capsys):
    # replans at steps 0 (untimed warm-up), 0, 5, 10, ...: the 5th call is the replan at step 15 (1.5 s)
    _interrupt_at(monkeypatch, "LearnedPlanner", 5)
    out = tmp_path / "run"
    assert main(["simulate", "--config", str(config), "--out", str(out)]) == 130
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert summary["interrupted"] == {"planner": "learned", "at_s": 1.5,
                                      "kept": "the flown planner's first 1.5 s"}
    assert list(summary["planners"]) == ["learned"]  # the expert's comparison never flew
    assert summary["duration_s"] == pytest.approx(1.5)
    assert (out / "qos.png").is_file() and (out / "timeseries.csv").is_file()
    assert len((out / "timeseries.csv").read_text().splitlines()) == 1 + 15
    err = capsys.readouterr().err
    assert "interrupted (Ctrl-C) at 1.5 s of the learned planner's run" in err


def test_ctrl_c_in_the_comparison_keeps_the_whole_flown_run(tmp_path, config, monkeypatch, capsys):
    _interrupt_at(monkeypatch, "ExpertPlanner", 3)
    out = tmp_path / "run"
    assert main(["simulate", "--config", str(config), "--out", str(out)]) == 130
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert list(summary["planners"]) == ["learned"]
    assert summary["interrupted"]["planner"] == "expert"
    assert summary["duration_s"] == pytest.approx(4.0)
    assert "next:" not in capsys.readouterr().out  # an interrupted run suggests nothing


def test_ctrl_c_before_any_step_writes_nothing(tmp_path, config, monkeypatch):
    _interrupt_at(monkeypatch, "LearnedPlanner", 1)
    out = tmp_path / "run"
    assert main(["simulate", "--config", str(config), "--out", str(out)]) == 130
    assert not out.exists()
