"""Pictures and tables of the main job: the QoS figure, the scene animation, the time series.

Drawing only: the runs come from :func:`uav_swarm.runs.simulate.run_sequence`. Every file is written
atomically (a temporary file in the same folder, then ``os.replace``). Matplotlib (``Agg``) draws
the figure; the scene animation is :mod:`uav_swarm.runs.animation` (re-exported here).
"""

from __future__ import annotations

import io
from collections.abc import Mapping
from pathlib import Path
from typing import Protocol

import numpy as np

from typed_config.files import write_bytes_atomic
from uav_swarm.runs.animation import write_scene_gif
from uav_swarm.runs.service import StaticReference

__all__ = ["QosSeries", "write_qos_figure", "write_scene_gif", "write_timeseries"]


class QosSeries(Protocol):
    """A run's QoS over time: a simulated run (:class:`uav_swarm.runs.simulate.SequenceRun`) or a flight."""

    planner_name: str
    times_s: np.ndarray
    qos_s1: np.ndarray
    qos_s2: np.ndarray
    throughput_mbps: np.ndarray

_STYLE = {"learned": {"color": "tab:blue"}, "expert": {"color": "tab:orange"}}


def write_qos_figure(runs: Mapping[str, QosSeries], path: Path, reference: StaticReference | None = None,
                     strategy: int = 1) -> Path:
    """QoS S1 and S2 over time (top) and mean user throughput over time (bottom), every planner.

    With a ``reference`` the static reference (the expert's placement of each instant's crowd,
    judged as if reached) is drawn beside the flown curves, as the ``strategy``'s QoS.

    Returns:
        ``path``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, (ax_qos, ax_rate) = plt.subplots(2, 1, figsize=(9, 8), sharex=True, layout="constrained",
                                             height_ratios=(3, 2))
    for kind, run in runs.items():
        style = _STYLE.get(kind, {})
        ax_qos.plot(run.times_s, run.qos_s1, label=f"{kind}: S1 (share covered)", **style)
        paper = getattr(run, "qos_s2_paper", None)  # the same flight under the paper's radio, if recorded
        paper = paper if paper is not None and len(paper) else None
        radio = " (admission control)" if paper is not None else ""
        ax_qos.plot(run.times_s, run.qos_s2, linestyle="--",
                    label=f"{kind}: S2 (covered with >= min rate){radio}", **style)
        if paper is not None:
            ax_qos.plot(run.times_s, paper, linestyle=":", label=f"{kind}: S2, paper's radio",
                        **style)
        ax_rate.plot(run.times_s, run.throughput_mbps, label=f"{kind} ({run.planner_name})", **style)
    if reference is not None and reference.qos.size:
        ax_qos.plot(reference.times_s, reference.qos, linestyle="none", marker="D", color="black",
                    label=f"static reference: S{strategy} of the expert's placement, as if reached")
    ax_qos.set(ylabel="QoS", ylim=(0.0, 1.02), title="Dynamic sequence: QoS over time")
    # Below the QoS panel, not over it: with both radios drawn the curves fill the panel.
    ax_qos.legend(loc="upper center", bbox_to_anchor=(0.5, -0.03), fontsize="small", ncol=2, frameon=False)
    ax_qos.grid(alpha=0.3)
    ax_rate.set(xlabel="simulated time (s)", ylabel="mean throughput per user (Mbps)")
    ax_rate.set_ylim(bottom=0.0)
    ax_rate.legend(loc="lower right", fontsize="small")
    ax_rate.grid(alpha=0.3)
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=100)
    plt.close(figure)
    write_bytes_atomic(path, buffer.getvalue())
    return path


def write_timeseries(runs: Mapping[str, QosSeries], path: Path) -> Path:
    """``planner,time_s,qos_s1,qos_s2,mean_throughput_mbps`` one row per step and planner."""
    lines = ["planner,time_s,qos_s1,qos_s2,mean_throughput_mbps"]
    for kind, run in runs.items():
        for row in zip(run.times_s, run.qos_s1, run.qos_s2, run.throughput_mbps, strict=True):
            lines.append(f"{kind},{row[0]:.2f},{row[1]:.6f},{row[2]:.6f},{row[3]:.6f}")
    write_bytes_atomic(path, ("\n".join(lines) + "\n").encode())
    return path
