"""Fixtures shared across test folders."""

from __future__ import annotations

import os
import sys

import pytest

from learning.data import generate_dataset
from learning.model import ModelConfig
from learning.train import TrainConfig, train
from uav_swarm.missions.registry import TaskFactory

SMALL_WIFI_TASK = {"warmup_min_s": 1.0, "warmup_max_s": 2.0,
                   "scenario": {"n_groups_min": 2, "n_groups_max": 3, "group_size_min": 35,
                                "group_size_max": 45}}
"""A fast Wi-Fi task config: few groups, short warm-up (64 px raster over 200 m, as shipped)."""

SMALL_PAPER_TASK = {**SMALL_WIFI_TASK, "radio": {"propagation": "paper"}}
""":data:`SMALL_WIFI_TASK` on the paper's radio, which ``simulate`` and ``fly`` fly only when told."""


@pytest.fixture(scope="session")
def small_wifi_task() -> dict:
    """The config dict of :data:`SMALL_WIFI_TASK` (a fresh copy)."""
    return {**SMALL_WIFI_TASK, "scenario": dict(SMALL_WIFI_TASK["scenario"])}


@pytest.fixture(scope="session")
def tiny_checkpoint(tmp_path_factory, small_wifi_task):
    """A wifi-s1 checkpoint trained for 2 steps on 16 small scenes (64 px raster, 200 m area)."""
    root = tmp_path_factory.mktemp("tiny-ckpt")
    generate_dataset(TaskFactory("wifi-s1", small_wifi_task), n=16, seed=0, out_dir=root / "data", workers=1,
                     progress=False)
    result = train(root / "data", root / "run", model_config=ModelConfig(arch="unet", width=4, depth=2),
                   train_config=TrainConfig(max_steps=2, batch_size=4, device="cpu", torch_threads=1),
                   progress=False)
    return result.best_checkpoint


_EXIT_STATUS = pytest.StashKey[int]()


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """Remember the session's exit status for :func:`pytest_unconfigure`."""
    session.config.stash[_EXIT_STATUS] = int(exitstatus)


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config: pytest.Config) -> None:
    """End the process with the session's exit status once a Ray driver has run in it.

    After ``ray.shutdown()`` the driver's gRPC threads stay alive, and tearing the interpreter
    down under them crashed one CI run with a segmentation fault after every test had passed
    (a known class of gRPC shutdown races). Everything is reported by now; exiting without
    finalisation keeps the status honest and the crash out.
    """
    if "ray" in sys.modules and _EXIT_STATUS in config.stash:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(config.stash[_EXIT_STATUS])
