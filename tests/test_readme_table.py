"""The README's table is what ``make demo`` prints: a fresh run of the demo equals it to the printed digit.

``make demo`` runs ``uav-swarm simulate`` with its defaults (seed 0, 180 s, 10 UAVs, the learned planner
and the expert on the same crowd). This test runs the same, into ``tmp_path``, renders the table as the
command prints it and compares it with the README's block (which ``tests/test_committed_results.py``
holds equal to ``results/simulate/``), line for line, with the planning times left out: they are the
machine's wall time. The learned planner's engine is pinned to the one the README's last line names, so
the network's float32 outputs are those of the committed run whatever engine is fastest here.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
_TIMES = re.compile(r"^(\S+(?:\s+\S+){5})\s+\S+\s+\S+$")  # a row: planner, five figures, p50, p95


def _readme_block() -> list[str]:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    start = text.index("planner  QoS S1 mean")
    return text[start:text.index("```", start)].splitlines()


def without_planning_times(lines: list[str]) -> list[str]:
    """The table's lines with the planning times (wall time, the machine's) left out.

    Examples:
        >>> without_planning_times(["learned   0.996  0.934   0.007  0.000   1.21   10.00   14.38",
        ...                         "learned / expert: S2 0.540; expert / learned planning time 47.784x"])
        ['learned 0.996 0.934 0.007 0.000 1.21', 'learned / expert: S2 0.540']
    """
    kept = []
    for line in lines:
        row = _TIMES.match(line) if not line.startswith(("planner", "-", " ")) and ":" not in line else None
        if row:
            line = " ".join(row.group(1).split())
        kept.append(line.split("; expert / learned planning time")[0])
    return kept


def test_the_readme_block_names_its_engine_and_its_run():
    block = _readme_block()
    assert block[0].startswith("planner") and block[-1].startswith("learned network:")
    assert re.search(r", (\S+) engine, float32$", block[-1])


@pytest.mark.slow
@pytest.mark.timeout(7200)  # a hang guard only: the run is 2 x 1800 steps, minutes on a busy machine
def test_a_fresh_demo_run_prints_the_readme_table(tmp_path):
    from uav_swarm.cli.simulate import format_summary
    from uav_swarm.runs.simulate import simulate
    from uav_swarm.runs.simulate_config import SimulateConfig

    block = _readme_block()
    engine = re.search(r", (\S+) engine, float32$", block[-1]).group(1)
    default = SimulateConfig()
    config = default.replace(publish_telemetry=False, gif=False,
                             planning=default.planning.replace(engine=engine))
    summary = simulate(config, tmp_path, progress=False).summary
    assert without_planning_times(format_summary(summary).splitlines()) == without_planning_times(block)
