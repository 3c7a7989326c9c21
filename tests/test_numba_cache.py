"""numba's compiled kernels are cached in the user's cache folder, never in the installed package."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "uav_swarm"
COMPILE = "from uav_swarm.planning.horizon import warm_up; warm_up()"


def _cached_in_package() -> set[Path]:
    return {*PACKAGE.rglob("*.nbi"), *PACKAGE.rglob("*.nbc")}


@pytest.mark.parametrize("first", ["", "import numba; "], ids=["package first", "numba first"])
def test_kernels_are_cached_under_the_user_cache_folder(tmp_path, first):
    before = _cached_in_package()
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env.update(XDG_CACHE_HOME=str(tmp_path / "cache"), HOME=str(tmp_path), PYTHONPATH=str(ROOT))
    subprocess.run([sys.executable, "-c", first + COMPILE], env=env, check=True, timeout=300)
    cached = list((tmp_path / "cache" / "uav-swarm" / "numba").rglob("*.nbi"))
    assert any("horizon" in path.name for path in cached), cached
    assert _cached_in_package() == before


def test_a_cache_folder_the_user_names_is_kept(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "mine"), "PYTHONPATH": str(ROOT)}
    subprocess.run([sys.executable, "-c", COMPILE], env=env, check=True, timeout=300)
    assert list((tmp_path / "mine").rglob("*.nbi"))


def test_the_crowds_pair_forces_are_cached_too(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env.update(XDG_CACHE_HOME=str(tmp_path / "cache"), HOME=str(tmp_path), PYTHONPATH=str(ROOT))
    step = ("import numpy as np; from uav_swarm.world.crowd import CrowdConfig, CrowdSim; "
            "from uav_swarm.world.scenario import random_scenario; rng = np.random.default_rng(0); "
            "CrowdSim(random_scenario(rng), CrowdConfig(), rng).step()")
    before = _cached_in_package()
    subprocess.run([sys.executable, "-c", step], env=env, check=True, timeout=300)
    cached = list((tmp_path / "cache" / "uav-swarm" / "numba").rglob("*.nbi"))
    assert any("pair_forces" in path.name for path in cached), cached
    assert _cached_in_package() == before
