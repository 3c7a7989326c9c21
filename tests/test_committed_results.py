"""The committed demo run (`results/simulate/`, what the README shows) has what docs/simulate.md promises.

`make demo` writes `out/simulate/`; the committed copy is that output of the current code. When the summary's
keys change, regenerate it (README, "Reproduce the picture") rather than editing this list.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RUN = ROOT / "results" / "simulate"
PAGE = (ROOT / "docs" / "simulate.md").read_text(encoding="utf-8")

PER_PLANNER = ("mean_qos_s1", "min_qos_s1", "mean_qos_s2", "min_qos_s2", "mean_throughput_mbps",
               "median_latency_ms", "p95_latency_ms", "n_replans", "mean_target_changes_per_replan",
               "flown_qos", "static_reference_qos", "flown_over_static", "target_jumps_per_replan",
               "metres_per_uav_minute", "association", "separation")
TOP_LEVEL = ("static_reference", "ratios_learned_over_expert", "checkpoint", "expert", "config")


def _summary() -> dict:
    return json.loads((RUN / "summary.json").read_text(encoding="utf-8"))


def test_the_page_promises_these_keys():
    promised = set(re.findall(r"`([a-z_0-9]+)`", PAGE))
    assert set(PER_PLANNER) | set(TOP_LEVEL) <= promised


def test_the_committed_summary_has_every_promised_key():
    summary = _summary()
    missing_top = [key for key in TOP_LEVEL if key not in summary]
    missing = {planner: [key for key in PER_PLANNER if key not in figures]
               for planner, figures in summary["planners"].items()}
    assert not missing_top and not any(missing.values()), (
        f"results/simulate/summary.json lacks {missing_top} and {missing}: regenerate it with make demo")


def test_the_committed_run_is_the_demos_run():
    summary = _summary()
    assert set(summary["planners"]) == {"learned", "expert"}
    assert (summary["n_uavs"], summary["seed"], round(summary["duration_s"])) == (10, 0, 180)
    for name in ("qos.png", "scene.gif", "timeseries.csv", "summary.json"):
        assert (RUN / name).is_file(), name
    # today's default: the 802.11 radio, its shipped strategy-1 network and its expert
    from uav_swarm.runs.simulate_config import SimulateConfig

    default = SimulateConfig().task
    assert summary["config"]["task"]["radio"]["propagation"] == default.radio.propagation == "802.11"
    assert summary["checkpoint"] == "uav_swarm/checkpoints/wifi-s1-80211.pt (shipped)"
    assert summary["expert"] == "802.11 expert (strategy 1, the 802.11 radio without admission on rate)"


def _printed_blocks(text: str, header: str) -> list[list[str]]:
    """Every fenced block of a page that starts with the table's header, as lines."""
    blocks = []
    for start in (m.start() for m in re.finditer(re.escape(header + "\n"), text)):
        blocks.append(text[start:text.index("```", start)].splitlines())
    return blocks


@pytest.mark.parametrize(("page", "run"), [("README.md", "simulate"), ("docs/simulate.md", "simulate"),
                                           ("docs/simulate.md", "simulate-s2")])
def test_the_pages_print_the_committed_runs_as_the_command_does(page, run):
    """Word for word and in the command's order (rows, then the lines below the table)."""
    from uav_swarm.cli.simulate import format_summary

    summary = json.loads((ROOT / "results" / run / "summary.json").read_text(encoding="utf-8"))
    lines = format_summary(summary).splitlines()
    blocks = _printed_blocks((ROOT / page).read_text(encoding="utf-8"), lines[0])
    assert lines in blocks, f"{page}: paste format_summary of results/{run}/summary.json"
