"""The checkpoints shipped in the package load and beat a trivial baseline on fresh scenes."""

from importlib import resources

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

from learning.checkpoint import CheckpointError, load_checkpoint
from learning.data import sample_seed
from learning.inference import predict_positions
from learning.metrics import MATCH_FRACTION, aggregate, score_sample
from uav_swarm.missions.registry import build_task

SHIPPED = ("wifi-s1", "wifi-s1-80211", "wifi-s2", "wifi-s2-groups", "wifi-s2-ac", "wifi-s2-80211", "agp",
           "fp")
"""Shipped files; ``wifi-s2-*`` are strategy 2 with other experts (group expert; admission control), and
``*-80211`` the 802.11 radio's expert's."""
N_SCENES = 12


def _shipped(name: str):
    return resources.files("uav_swarm") / "checkpoints" / f"{name}.pt"


def _densest_pixels(raster: np.ndarray, k: int) -> np.ndarray:
    """The trivial baseline: the k highest pixels of the blurred first input channel (no suppression)."""
    smooth = gaussian_filter(raster[0].astype(np.float64), sigma=2.0)
    flat = np.argsort(smooth, axis=None, kind="stable")[::-1][:k]
    rows, cols = np.unravel_index(flat, smooth.shape)
    return np.stack([cols, rows], axis=1).astype(np.float64)


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_checkpoint_loads_and_beats_the_densest_pixels_baseline(name):
    path = _shipped(name)
    assert path.is_file(), f"the package must ship {name}.pt"
    task_name = name if name in ("agp", "fp") else name[:7]  # wifi-s1-80211 is a wifi-s1 network
    ckpt = load_checkpoint(path, task_name=task_name)
    task = build_task(task_name, ckpt.task_config)
    assert ckpt.input_shape == (task.channels, *task.shape)
    eps = MATCH_FRACTION * task.mission_dimension_px
    learned, baseline, learned_qos, baseline_qos = [], [], [], []
    for index in range(N_SCENES):  # the "val" seed namespace: never in training nor in the test set
        scene = task.sample(np.random.default_rng(sample_seed(12345, "val", index)))
        raster, expert = task.observe(scene), task.expert(scene)
        predicted = predict_positions(ckpt.model, raster, 10, ckpt.peak_config)
        trivial = _densest_pixels(raster, len(expert))
        learned.append(score_sample(expert, predicted, eps))
        baseline.append(score_sample(expert, trivial, eps))
        learned_qos.append(task.qos(scene, predicted)["qos"])
        baseline_qos.append(task.qos(scene, trivial)["qos"])
    ours, theirs = aggregate(learned), aggregate(baseline)
    assert ours["corr"] > theirs["corr"]
    assert ours["precision"] > theirs["precision"]
    assert np.mean(learned_qos) >= np.mean(baseline_qos)


def test_a_shipped_checkpoint_refuses_another_task():
    with pytest.raises(CheckpointError, match="trained on task 'wifi-s1', not 'agp'"):
        load_checkpoint(_shipped("wifi-s1"), task_name="agp")


MISSION_POINTS = ("wifi-s1", "wifi-s2", "agp", "fp")
"""Shipped files that carry a mission operating point (``uav-swarm calibrate-mission``)."""


@pytest.mark.parametrize("name", MISSION_POINTS)
def test_a_shipped_mission_point_meets_its_floors_and_serves_at_least_the_balanced_point(name):
    ckpt = load_checkpoint(_shipped(name))
    assert ckpt.mission_peak_config is not None
    record = ckpt.payload["mission_calibration"]
    mission, balanced, floors = record["mission"], record["balanced"], record["floors"]
    none = {"corr": 0.0, "precision": 0.0}  # a point chosen before the margin carries no margins
    mission_margin, balanced_margin = mission.get("margins", none), balanced.get("margins", none)
    assert mission["qos"] >= balanced["qos"]
    for column in ("corr", "precision"):
        assert mission[column] - mission_margin[column] >= floors[column] - 1e-12
    floor = min(record["paper"]["corr"], balanced["corr"] - balanced_margin["corr"])
    assert floors["corr"] == pytest.approx(floor)
