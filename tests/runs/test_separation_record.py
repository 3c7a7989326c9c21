"""A simulated run's separation figures against an independent recomputation, and the recording's circles."""

from __future__ import annotations

import json

import numpy as np
import pytest
from foxglove_readback import read_back
from scipy.spatial.distance import pdist, squareform

from uav_swarm.cli.simulate import format_summary
from uav_swarm.runs.simulate import simulate
from uav_swarm.runs.simulate_config import SimulateConfig

MIN_SEPARATION_M = 70.0  # wide, so that a short run of a few UAVs flies close to it and is held


def recompute(times_s, tracks_m, min_separation_m):
    """Closest pair, conflicts (a pair entering below the minimum) and time below it, from positions alone."""
    closest, pair, when, conflicts, below_s = np.inf, None, None, 0, 0.0
    previous = None
    for index, (t_s, positions) in enumerate(zip(times_s, tracks_m, strict=True)):
        distances = pdist(positions)
        k = int(np.argmin(distances))
        if distances[k] < closest:
            square = squareform(distances + 1.0)  # + 1: the diagonal stays 0, never the minimum
            np.fill_diagonal(square, np.inf)
            first, second = np.unravel_index(int(np.argmin(square)), square.shape)
            closest, pair, when = float(distances[k]), sorted([int(first), int(second)]), float(t_s)
        below = distances < min_separation_m
        conflicts += int(np.count_nonzero(below if previous is None else below & ~previous))
        if index and below.any():
            below_s += float(t_s - times_s[index - 1])
        previous = below
    return closest, pair, when, conflicts, below_s


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("sim")
    config = SimulateConfig.from_dict({
        "duration_s": 4.0, "n_uavs": 4, "planner": "expert", "compare_expert": False, "gif": False,
        "publish_telemetry": False, "seed": 3, "uav": {"min_separation_m": MIN_SEPARATION_M}})
    result = simulate(config, out, progress=False, record=out / "run.mcap")
    return result, out


def test_the_summary_equals_an_independent_recomputation_from_the_positions(run):
    result, out = run
    flown = result.runs["expert"]
    separation = json.loads((out / "summary.json").read_text())["planners"]["expert"]["separation"]
    assert flown.uav_tracks_m.shape == (40, 4, 2)
    closest, pair, when, conflicts, below_s = recompute(flown.times_s, flown.uav_tracks_m, MIN_SEPARATION_M)
    assert separation["min_separation_m"] == MIN_SEPARATION_M
    assert separation["closest_m"] == pytest.approx(closest, abs=1e-3)
    assert separation["closest_pair"] == pair and separation["closest_t_s"] == pytest.approx(when)
    assert separation["conflicts"] == conflicts == 0 and closest >= MIN_SEPARATION_M  # held apart
    assert separation["time_below_min_s"] == pytest.approx(below_s, abs=1e-6)
    assert separation["holds"] == separation["transition_holds"] + separation["guard_holds"] > 0
    table = format_summary(result.summary)
    assert f"closest pair {closest:.2f} m (UAVs {pair[0]} and {pair[1]}" in table
    assert f"{conflicts} conflicts" in table and f"{separation['holds']} holds" in table


def test_the_recording_draws_each_uav_s_circle_and_marks_the_conflicts(run):
    result, out = run
    topics = read_back(out / "run.mcap")["topics"]
    tracks = result.runs["expert"].uav_tracks_m
    swarm = [m for m in topics["/scene"]["messages"] if any(e["id"] == "separation" for e in m["entities"])]
    assert len(swarm) == len(tracks)
    for message, positions in zip(swarm, tracks, strict=True):
        entities = {e["id"]: e for e in message["entities"]}
        circles = entities["separation"]["cylinders"]
        assert len(circles) == 4
        assert {c["size"]["x"] for c in circles} == {MIN_SEPARATION_M}  # diameter = the minimum
        centres = np.array([[c["pose"]["position"]["x"], c["pose"]["position"]["y"]] for c in circles])
        np.testing.assert_allclose(centres, positions)
        close = squareform(pdist(positions) < MIN_SEPARATION_M)
        red = np.array([c["color"]["r"] > 0.8 and c["color"]["g"] < 0.2 for c in circles])
        np.testing.assert_array_equal(red, close.any(axis=1))
        lines = entities["conflicts"].get("lines", [])
        assert sum(len(line["points"]) for line in lines) == 2 * int(np.triu(close, 1).sum())
    states = topics["/uav/0/state"]["messages"]
    assert all(s["nearest_uav_m"] >= 0 and isinstance(s["separation_held"], bool) for s in states)
