"""The committed Foxglove layout is the one the code builds, and it shows the channels a run has."""

from __future__ import annotations

import json
from pathlib import Path

from uav_swarm.runs.outputs.foxglove_layout import layout_json
from uav_swarm.runs.outputs.recording import RUN_TOPICS

COMMITTED = Path(__file__).resolve().parents[2] / "docs" / "foxglove" / "uav-swarm-layout.json"


def _panels(node: dict) -> list[dict]:
    if node.get("type") == "panel":
        return [node]
    return [panel for item in node.get("items", []) for panel in _panels(item["content"])]


def test_the_committed_layout_is_the_built_one():
    assert COMMITTED.read_text() == layout_json()


def test_the_layout_draws_the_scene_plots_the_qos_and_tabulates_the_plan():
    panels = {p["panelType"]: p["config"] for p in _panels(json.loads(COMMITTED.read_text())["content"])}
    assert set(panels) == {"ThreeDee", "Plot", "Table"}
    three_d = panels["ThreeDee"]
    assert three_d["followTf"] == "map" and set(three_d["topics"]) <= set(RUN_TOPICS)
    assert three_d["topics"]["/pedestrians"]["colorField"] == "covered"
    plotted = [series["value"] for series in panels["Plot"]["paths"]]
    assert plotted == ["/qos.qos_s1", "/qos.qos_s2", "/qos.mean_throughput_mbps"]
    assert panels["Table"]["topicPath"] == "/plan.targets"
    assert {path.split(".")[0] for path in [*plotted, panels["Table"]["topicPath"]]} <= set(RUN_TOPICS)
