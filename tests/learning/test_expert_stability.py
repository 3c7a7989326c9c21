"""The expert self-agreement probes: exact on an equivariant expert, below 1 where the expert is not."""

from __future__ import annotations

import json

import numpy as np
import pytest

from learning.data import sample_seed
from learning.expert_stability import expert_stability
from learning.symmetry import SYMMETRIES, transform_positions
from tests.learning.blob_task import BlobConfig, BlobTask
from uav_swarm.cli import main
from uav_swarm.missions.registry import make_task


class _CornerTask(BlobTask):
    """An expert that ignores the scene's orientation: always the top-left corner area."""

    def expert(self, scene):  # noqa: ANN001, ANN201
        return np.array([[3.0, 3.0]]) if len(scene.centres_px) else np.zeros((0, 2))


def test_an_equivariant_expert_agrees_with_itself() -> None:
    report = expert_stability(BlobTask(BlobConfig(max_blobs=4)), n=21, seed=0)
    assert report["corr"] == 1.0 and report["precision"] == 1.0 and report["same_count"] == 1.0
    assert report["qos"] == report["qos_other"] == 1.0


def test_an_expert_blind_to_the_orientation_is_caught() -> None:
    report = expert_stability(_CornerTask(BlobConfig(max_blobs=3)), n=21, seed=0)
    assert report["corr"] < 0.5  # the corner moves under 6 of the 7 symmetries; empty scenes count 1


def test_jitter_below_the_match_radius_keeps_agreement_and_large_jitter_breaks_it() -> None:
    task = BlobTask(BlobConfig(max_blobs=4))
    small = expert_stability(task, n=20, seed=1, probe="jitter", scale=0.01)
    large = expert_stability(task, n=20, seed=1, probe="jitter", scale=8.0)
    assert small["corr"] == 1.0 and small["scale"] == 0.01
    assert large["corr"] < 0.8
    assert expert_stability(task, n=20, seed=1, probe="jitter", scale=8.0) == large  # same seed, same report


def test_bad_arguments_are_refused_before_any_work() -> None:
    task = BlobTask()
    with pytest.raises(ValueError, match="n = 0"):
        expert_stability(task, n=0, seed=0)
    with pytest.raises(ValueError, match="probe"):
        expert_stability(task, n=1, seed=0, probe="rotate")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="scale"):
        expert_stability(task, n=1, seed=0, probe="jitter", scale=0.0)
    with pytest.raises(ValueError, match="jitter_scene"):
        expert_stability(make_task("agp"), n=1, seed=0, probe="jitter")


@pytest.mark.parametrize("symmetry", SYMMETRIES[1:])
def test_wifi_scenes_move_as_their_rasters(symmetry: tuple[bool, bool, bool]) -> None:
    task = make_task("wifi-s1")
    scene = task.sample(np.random.default_rng(sample_seed(0, "test", 0)))
    flip_x, flip_y, transpose = symmetry
    expected = task.observe(scene)[0]
    expected = expected[:, ::-1] if flip_x else expected
    expected = expected[::-1, :] if flip_y else expected
    expected = expected.T if transpose else expected
    np.testing.assert_allclose(task.observe(task.transform_scene(scene, *symmetry))[0], expected, atol=1e-6)
    moved_users = task.to_pixels(task.transform_scene(scene, *symmetry).users_m)
    np.testing.assert_allclose(moved_users, transform_positions(task.to_pixels(scene.users_m), task.shape,
                                                                *symmetry), atol=1e-9)


@pytest.mark.parametrize("name", ["agp", "fp"])
def test_buildings_move_as_their_rasters_and_keep_an_exact_expert(name: str) -> None:
    task = make_task(name)
    scene = task.sample(np.random.default_rng(sample_seed(0, "test", 1)))
    for symmetry in SYMMETRIES[1:]:
        moved = task.transform_scene(scene, *symmetry)
        flip_x, flip_y, transpose = symmetry
        filled = task.observe(scene)[0]
        filled = filled[:, ::-1] if flip_x else filled
        filled = filled[::-1, :] if flip_y else filled
        filled = filled.T if transpose else filled
        np.testing.assert_array_equal(task.observe(moved)[0], filled)
        assert len(moved.guards_px) == len(scene.guards_px)  # an optimal cover has the same size
        assert task.qos(moved, task.expert(moved))["qos"] == 1.0


def test_cli_writes_the_report_and_refuses_a_probe_the_task_lacks(tmp_path, capsys) -> None:  # noqa: ANN001
    out = tmp_path / "deep" / "agp.json"
    assert main(["expert-stability", "--task", "agp", "--n", "3", "--seed", "5", "--out", str(out)]) == 0
    report = json.loads(out.read_text())
    assert report["task"] == "agp" and report["n"] == 3 and report["probe"] == "symmetry"
    assert report["qos_other"] == 1.0  # the moved expert, moved back, still sees the whole building
    assert "agp, symmetry: corr" in capsys.readouterr().out
    refused = tmp_path / "refused.json"
    argv = ["expert-stability", "--task", "agp", "--probe", "jitter", "--n", "3", "--out", str(refused)]
    assert main(argv) == 2
    assert not refused.exists()
    assert "jitter_scene" in capsys.readouterr().err


def test_wifi_jitter_moves_every_pedestrian_a_little_and_keeps_them_inside() -> None:
    task = make_task("wifi-s2")
    scene = task.sample(np.random.default_rng(sample_seed(0, "test", 2)))
    moved = task.jitter_scene(scene, np.random.default_rng(7), 0.05)
    again = task.jitter_scene(scene, np.random.default_rng(7), 0.05)
    step = moved.users_m - scene.users_m
    assert moved.users_m.shape == scene.users_m.shape and not moved.users_m.flags.writeable
    assert np.array_equal(moved.users_m, again.users_m)  # the same generator, the same crowd
    assert np.all(step != 0.0) and 0.03 < step.std() < 0.07
    assert moved.users_m.min() >= 0.0 and moved.users_m.max() < task.width_m
    edge = task.jitter_scene(scene, np.random.default_rng(0), 500.0)
    assert edge.users_m.min() >= 0.0 and edge.users_m.max() < task.width_m  # pushed out, clipped back
