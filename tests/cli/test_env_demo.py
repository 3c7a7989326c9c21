"""Smoke test of ``uav-swarm env-demo`` and its scripted placement."""

import numpy as np
import pytest
from PIL import Image

from uav_swarm.cli import main
from uav_swarm.cli.env_demo import greedy_targets_m


@pytest.mark.slow
def test_env_demo_writes_a_png_and_a_summary(tmp_path, capsys):
    argv = ["env-demo", "--out", str(tmp_path / "demo"), "--steps", "8", "--n-uavs", "2", "--seed", "3"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "2 UAVs" in out and "8 steps" in out and "final QoS S1" in out
    with Image.open(tmp_path / "demo" / "env_demo.png") as image:
        assert image.size[0] > 600 and image.mode in ("RGB", "RGBA")
    assert [p.name for p in (tmp_path / "demo").iterdir()] == ["env_demo.png"]  # no temp file left


def test_env_demo_rejects_too_many_uavs(tmp_path, capsys):
    assert main(["env-demo", "--out", str(tmp_path), "--n-uavs", "11"]) == 2
    assert "argument --n-uavs: 11 is out of range: allowed >= 1 and <= 10" in capsys.readouterr().err


def test_greedy_targets_cover_the_two_clusters():
    density = np.zeros((20, 20))
    density[2, 3] = 30  # cluster A, around (17.5, 12.5) m on a 100 m area (5 m pixels)
    density[15, 16] = 20  # cluster B, around (82.5, 77.5) m
    density[3, 3] = 5
    targets = greedy_targets_m(density, 100.0, 100.0, 2, radius_m=10.0)
    clusters = np.array([[17.5, 12.5], [17.5, 17.5], [82.5, 77.5]])  # pixel centres of the crowd
    distance = np.linalg.norm(clusters[:, None, :] - targets[None, :, :], axis=2)
    assert np.all(distance.min(axis=1) <= 10.0)  # every pedestrian is covered by one of the 2 UAVs
