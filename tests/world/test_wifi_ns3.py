"""Opt-in: the 802.11 model against ns-3 on two small scenes (``pytest -m ns3``).

Deselected by default (``-m "not sitl and not ns3"`` in pyproject's addopts). ns-3 is the PyPI ``ns3``
package (the ``radio-calibration`` extra), never a test dependency: give a Python that has it in
``NS3_PYTHON`` (it may live in its own virtual environment), or run pytest in one; without either the test is
skipped. ns-3 runs in a subprocess (``benchmarks/radio/ns3/ns3_scene.py``: an abort inside ns-3 must not end
pytest) on two UAVs 10 m apart, two users each, first on one channel and then on two, with the model's own
path loss, so that only ns-3's MAC and PHY are compared with the model's shipped tables; and five APs on one
channel (they collide) at ns-3's default 3.2 us guard interval, given to the model as ``guard_interval_us``::

    NS3_PYTHON=/path/to/ns3-venv/bin/python pytest -m ns3 tests/world/test_wifi_ns3.py
"""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
BENCH = REPO / "benchmarks" / "radio_ns3"

pytestmark = pytest.mark.ns3


def _ns3_python() -> str | None:
    if os.environ.get("NS3_PYTHON"):
        return os.environ["NS3_PYTHON"]
    return sys.executable if importlib.util.find_spec("ns") is not None else None


NS3_PYTHON = _ns3_python()


def _pair(name: str, channels: list[int]) -> dict:
    return {"name": name, "family": "test", "split": "test", "width_mhz": 20, "warmup_s": 0.4,
            "measure_s": 0.6,
            "uavs_m": [[0.0, 0.0, 10.0], [10.0, 0.0, 10.0]], "channels": channels,
            "users_m": [[-6.0, 3.0], [-2.0, -8.0], [14.0, 5.0], [17.0, -2.0]], "serving_uav": [0, 0, 1, 1]}


@pytest.mark.skipif(NS3_PYTHON is None, reason="no ns3: set NS3_PYTHON to a Python with the PyPI ns3 package")
def test_co_channel_aps_share_the_medium_in_ns3_as_in_the_model(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(BENCH))  # the calibration's own job writer and model runner
    from model_eval import load_ns3, model_scene
    from run_ns3 import job_of

    scenes = [_pair("one-channel", [36, 36]), _pair("two-channels", [36, 40])]
    command = [NS3_PYTHON, str(BENCH / "ns3_scene.py")]
    for scene in scenes:
        job = tmp_path / f"{scene['name']}.job.json"
        job.write_text(json.dumps(job_of(scene, [1])), encoding="utf-8")
        command += [str(job), str(tmp_path / f"{scene['name']}.json")]
    subprocess.run(command, check=True, capture_output=True, timeout=540)

    totals = {}
    for scene in scenes:
        ns3 = load_ns3(tmp_path / f"{scene['name']}.json", scene)
        model = model_scene(scene)
        ns3_ap = ns3.ap_mbps.mean(axis=0)
        # the calibration's bound on each AP: 15 %, or 5 Mbps under 33 Mbps
        bound = np.where(ns3_ap < 33.0, np.maximum(0.15 * ns3_ap, 5.0), 0.15 * ns3_ap)
        assert np.all(np.abs(model.ap_mbps - ns3_ap) <= bound), (scene["name"], ns3_ap, model.ap_mbps)
        totals[scene["name"]] = (ns3_ap.sum(), model.ap_mbps.sum())
    # one channel: the two APs take turns (about one AP's throughput together); two: each has its own
    for which in (0, 1):
        assert totals["one-channel"][which] < 0.6 * totals["two-channels"][which]


@pytest.mark.skipif(NS3_PYTHON is None, reason="no ns3: set NS3_PYTHON to a Python with the PyPI ns3 package")
def test_five_co_channel_aps_collide_in_ns3_as_in_the_model_at_its_default_guard_interval(tmp_path,
                                                                                          monkeypatch):
    monkeypatch.syspath_prepend(str(BENCH))
    from model_eval import load_ns3, model_scene
    from run_ns3 import job_of

    uavs = [[0.0, 0.0, 10.0], [25.0, 0.0, 12.0], [0.0, 25.0, 14.0], [25.0, 25.0, 16.0], [50.0, 12.0, 18.0]]
    offsets = [[-3.0, 2.0], [2.0, -3.0], [3.0, 3.0]]
    scene = {"name": "five", "family": "test", "split": "test", "width_mhz": 20, "warmup_s": 0.4,
             "measure_s": 0.6, "uavs_m": uavs, "channels": [36] * 5,
             "users_m": [[x + dx, y + dy] for x, y, _ in uavs for dx, dy in offsets],
             "serving_uav": [k for k in range(5) for _ in offsets]}
    job = tmp_path / "five.job.json"
    job.write_text(json.dumps(job_of(scene, [1], guard_interval_ns=3200)), encoding="utf-8")
    subprocess.run([NS3_PYTHON, str(BENCH / "ns3_scene.py"), str(job), str(tmp_path / "five.json")],
                   check=True, capture_output=True, timeout=540)
    ns3_total = load_ns3(tmp_path / "five.json", scene).ap_mbps.sum(axis=1).mean()
    model = model_scene(scene, guard_interval_us=3.2)
    assert model.ap_mbps.sum() == pytest.approx(ns3_total, rel=0.10)  # the calibration's bound on a scene
    ideal_csma = model_scene(scene, str(BENCH / "tables-ideal-csma.toml"), guard_interval_us=3.2)
    assert ideal_csma.ap_mbps.sum() > model.ap_mbps.sum()  # without collisions the model says more
