"""The missions' refiners as evaluation and the command line meet them."""

from __future__ import annotations

import json

import numpy as np
import pytest

from learning.checkpoint import load_checkpoint
from learning.evaluate import evaluate
from learning.task import Refiner
from typed_config import ConfigError
from uav_swarm.cli import main
from uav_swarm.missions.monitoring.guard_repair import RepairConfig
from uav_swarm.missions.registry import TaskFactory, build_refiner, build_task, load_settings
from uav_swarm.planning.planner import default_checkpoint


def test_every_task_has_a_refiner_configured_by_its_refine_table(tmp_path):
    for name in ("wifi-s1", "wifi-s2", "agp", "fp"):
        refiner = build_refiner(build_task(name))
        assert isinstance(refiner, Refiner)
    refiner = build_refiner(build_task("fp"), {"move_radius_px": 3.0})
    assert refiner.config == RepairConfig(move_radius_px=3.0)
    settings = tmp_path / "fp.toml"
    settings.write_text("[refine]\nmove_stride_px = 0\n")
    with pytest.raises(ConfigError, match=r"\[refine\].*move_stride_px"):
        load_settings("fp", settings)
    with pytest.raises(ConfigError, match="grid_step_m"):
        build_refiner(build_task("wifi-s1"), {"grid_step_m": -1.0})


def test_the_guard_refiner_sees_every_witness_and_solve_is_the_exact_expert():
    task = build_task("agp")
    refiner = build_refiner(task)
    rng = np.random.default_rng(21)
    for _ in range(3):
        scene = task.sample(rng)
        assert task.qos(scene, refiner.refine(scene, np.zeros((0, 2))))["qos"] == 1.0
        np.testing.assert_array_equal(np.sort(refiner.solve(scene), axis=0), np.sort(scene.guards_px, axis=0))


@pytest.fixture(scope="module")
def agp_refined(tmp_path_factory):
    """``evaluate --refine`` of the shipped Art Gallery network on 6 held-out buildings."""
    out = tmp_path_factory.mktemp("agp-refine")
    checkpoint = default_checkpoint("agp")
    factory = TaskFactory("agp", load_checkpoint(checkpoint).task_config)
    summary = evaluate(checkpoint, factory, 6, 91, out, n_examples=0, workers=1, progress=False,
                       refiner=build_refiner(factory()))
    return out, summary


def test_evaluation_reports_learned_refined_and_expert_side_by_side(agp_refined):
    out, summary = agp_refined
    for row in ("learned", "refined"):
        assert {"corr", "precision", "qos", "qos_relative", "n_positions", "time_median_ms",
                "time_p95_ms"} <= set(summary[row])
    assert summary["refined"]["qos"] == 1.0 and summary["refined"]["qos_relative"] == 1.0
    assert summary["refined"]["n_positions"] >= summary["expert"]["n_positions"]  # the expert is optimal
    assert summary["learned"]["corr"] == summary["corr"]  # the headline figures stay the learned ones
    samples = json.loads((out / "results.json").read_text())["samples"]
    for sample in samples:
        assert sample["refined"]["qos"]["qos"] == 1.0
        assert sample["refined"]["time_ms"] >= sample["learned"]["time_ms"] > 0
        assert sample["expert_time_ms"] > 0
    times = np.array([s["refined"]["time_ms"] for s in samples])
    assert summary["refined"]["time_median_ms"] == pytest.approx(np.median(times))
    assert "| refined |" in (out / "results.md").read_text()


def test_the_command_line_refines_with_the_settings_file(tmp_path, capsys):
    settings = tmp_path / "agp.toml"
    settings.write_text("[refine]\nmove_radius_px = 4.0\n")
    out = tmp_path / "eval"
    assert main(["evaluate", "--task", "agp", "--checkpoint", str(default_checkpoint("agp")), "--n", "3",
                 "--seed", "92", "--out", str(out), "--examples", "0", "--workers", "1", "--refine",
                 "--config", str(settings)]) == 0
    assert "| refined |" in capsys.readouterr().out
    assert json.loads((out / "summary.json").read_text())["refined"]["qos"] == 1.0
