"""Pictures and tables of a run: the QoS figure, the scene animation, the time series, a flight's track.

Drawing only: the runs come from :func:`uav_swarm.runs.simulate.run_sequence`. Runs under the 802.11 radio
(a ``radio`` :class:`~uav_swarm.runs.outputs.radio_report.RadioTrace`) add the users' SINR and MCS and each
UAV's
channel to the figure and the time series. Every file is written atomically (a temporary file in the same
folder, then ``os.replace``). Matplotlib (``Agg``) draws
the figure; the scene animation is :mod:`uav_swarm.runs.outputs.animation` (re-exported here).
"""

from __future__ import annotations

import io
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from typed_config.files import write_bytes_atomic
from uav_swarm.runs.outputs.animation import write_scene_gif
from uav_swarm.runs.outputs.radio_report import MCS_BANDS, RadioTrace
from uav_swarm.runs.service import StaticReference

__all__ = ["QosSeries", "write_qos_figure", "write_scene_gif", "write_timeseries", "write_track_figure"]


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

    traces = {kind: trace for kind, run in runs.items() if (trace := _radio(run)) is not None}
    rows = 4 if traces else 2
    figure, axes = plt.subplots(rows, 1, figsize=(9, 8 + 5 * bool(traces)), sharex=True, layout="constrained",
                                height_ratios=(3, 2, 2, 2)[:rows])
    ax_qos, ax_rate = axes[0], axes[1]
    for kind, run in runs.items():
        style = _STYLE.get(kind, {})
        served = "served with a usable rate" if kind in traces else "covered"  # 802.11: an MCS, no disc
        ax_qos.plot(run.times_s, run.qos_s1, label=f"{kind}: S1 (share {served})", **style)
        paper = getattr(run, "qos_s2_paper", None)  # the same flight under the paper's radio, if recorded
        paper = paper if paper is not None and len(paper) else None
        radio = " (admission control)" if paper is not None else ""
        ax_qos.plot(run.times_s, run.qos_s2, linestyle="--",
                    label=f"{kind}: S2 ({'served' if kind in traces else 'covered'} with >= min rate){radio}",
                    **style)
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
    ax_rate.set(xlabel="" if traces else "simulated time (s)", ylabel="mean throughput per user (Mbps)")
    ax_rate.set_ylim(bottom=0.0)
    ax_rate.legend(loc="lower right", fontsize="small")
    ax_rate.grid(alpha=0.3)
    if traces:
        _draw_radio(axes[2], axes[3], runs, traces)
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=100)
    plt.close(figure)
    write_bytes_atomic(path, buffer.getvalue())
    return path


def _radio(run: QosSeries) -> RadioTrace | None:
    """The run's 802.11 figures, if it has them."""
    trace = getattr(run, "radio", None)
    return trace if isinstance(trace, RadioTrace) and len(trace.channels) else None


def _draw_radio(ax_sinr: Any, ax_channel: Any, runs: Mapping[str, QosSeries],
                traces: Mapping[str, RadioTrace]) -> None:
    """The users' MCS bands (first run, stacked), median SINR (every run), each UAV's channel (first run)."""
    kind, trace = next(iter(traces.items()))
    times = runs[kind].times_s
    ax_sinr.stackplot(times, trace.mcs_shares.T, labels=[f"{kind}: {name}" for name, _, _ in MCS_BANDS],
                      alpha=0.35)
    ax_sinr.set(ylabel="share of users", ylim=(0.0, 1.0))
    ax_db = ax_sinr.twinx()
    for other, other_trace in traces.items():
        ax_db.plot(runs[other].times_s, other_trace.median_sinr_db, label=f"{other}: median SINR",
                   **_STYLE.get(other, {}))
    ax_db.set(ylabel="median SINR (dB)")
    handles = ax_sinr.get_legend_handles_labels()
    more = ax_db.get_legend_handles_labels()
    ax_sinr.legend(handles[0] + more[0], handles[1] + more[1], loc="lower left", fontsize="small", ncol=3)
    used = np.unique(trace.channels)  # one row per channel used, UAVs drawn side by side within it
    row = np.searchsorted(used, trace.channels)
    n_uavs = trace.channels.shape[1]
    for uav in range(n_uavs):
        ax_channel.step(times, row[:, uav] + (uav - (n_uavs - 1) / 2) * 0.6 / max(n_uavs, 1), where="post",
                        label=f"UAV {uav}")
    ax_channel.set(yticks=np.arange(len(used)), yticklabels=[str(c) for c in used],
                   ylabel=f"{kind}: channel", xlabel="simulated time (s)")
    ax_channel.legend(loc="upper right", fontsize="x-small", ncol=min(n_uavs, 5))
    ax_channel.grid(alpha=0.3)


def write_timeseries(runs: Mapping[str, QosSeries], path: Path) -> Path:
    """``planner,time_s,qos_s1,qos_s2,mean_throughput_mbps`` one row per step and planner.

    Under the 802.11 radio also: the users' median SINR, their share per MCS band, the co-channel pairs
    sharing airtime, and each UAV's channel and airtime share (:mod:`uav_swarm.runs.outputs.radio_report`).
    """
    traces = {kind: _radio(run) for kind, run in runs.items()}
    n_uavs = max((t.channels.shape[1] for t in traces.values() if t is not None), default=0)
    header = ["planner", "time_s", "qos_s1", "qos_s2", "mean_throughput_mbps"]
    if n_uavs:
        bands = [name.replace("MCS ", "mcs_").replace("-", "_").replace(" ", "_") for name, _, _ in MCS_BANDS]
        header += ["median_sinr_db", *(f"share_{band}" for band in bands), "co_channel_pairs",
                   *(f"channel_uav{k}" for k in range(n_uavs)), *(f"airtime_uav{k}" for k in range(n_uavs))]
    lines = [",".join(header)]
    for kind, run in runs.items():
        trace = traces[kind]
        rows = zip(run.times_s, run.qos_s1, run.qos_s2, run.throughput_mbps, strict=True)
        for step, row in enumerate(rows):
            line = f"{kind},{row[0]:.2f},{row[1]:.6f},{row[2]:.6f},{row[3]:.6f}"
            if trace is not None:
                line += "," + ",".join([f"{trace.median_sinr_db[step]:.3f}",
                                        *(f"{v:.6f}" for v in trace.mcs_shares[step]),
                                        str(int(trace.sharing[step].sum())),
                                        *(str(int(c)) for c in trace.channels[step]),
                                        *(f"{v:.6f}" for v in trace.airtime[step])])
            elif n_uavs:
                line += "," * (len(header) - 5)
            lines.append(line)
    write_bytes_atomic(path, ("\n".join(lines) + "\n").encode())
    return path


def write_track_figure(track: Sequence[Mapping[str, Any]], crowd_m: np.ndarray | None,
                       area_m: tuple[float, float], path: Path) -> Path:
    """A flight seen from above: each vehicle's path, its first point (home) and last target, the crowd.

    Args:
        track: ``fly``'s track rows (``uav_id``, ``x_m``, ``y_m``, ``target_x_m``, ``target_y_m``; local
            East/North metres from the bridge's home), in time order.
        crowd_m: ``(N, 2)`` the crowd at the last instant sampled in flight (None: not drawn).
        area_m: The crowd's area (width, height), drawn as a rectangle from the origin.
        path: The PNG written (atomically).

    Returns:
        ``path``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, ax = plt.subplots(figsize=(8, 8), layout="constrained")
    ax.add_patch(plt.Rectangle((0.0, 0.0), *area_m, fill=False, linestyle=":", color="grey",
                               label="crowd area"))
    if crowd_m is not None and len(crowd_m):
        ax.scatter(crowd_m[:, 0], crowd_m[:, 1], s=4, color="grey", alpha=0.5, label="crowd (last sample)")
    ax.plot([0.0], [0.0], marker="*", markersize=14, color="black", linestyle="none", label="bridge home")
    for uav in sorted({row["uav_id"] for row in track}):
        rows = [row for row in track if row["uav_id"] == uav and row["x_m"] is not None]
        if not rows:
            continue
        xy = np.array([(row["x_m"], row["y_m"]) for row in rows], dtype=float)
        line = ax.plot(xy[:, 0], xy[:, 1], linewidth=1.2, label=f"UAV {uav} (vehicle {rows[0]['system_id']})")
        color = line[0].get_color()
        ax.plot(*xy[0], marker="^", color=color, linestyle="none")
        targets = [row for row in rows if row.get("target_x_m") is not None]
        if targets:
            ax.plot(targets[-1]["target_x_m"], targets[-1]["target_y_m"], marker="x", markersize=9,
                    color=color, linestyle="none")
    ax.plot([], [], marker="^", color="black", linestyle="none", label="first position (home)")
    ax.plot([], [], marker="x", color="black", linestyle="none", label="last target")
    ax.set(xlabel="East (m)", ylabel="North (m)", title="Flight from above: paths, homes, targets",
           aspect="equal")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small")
    ax.grid(alpha=0.3)
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=100)
    plt.close(figure)
    write_bytes_atomic(path, buffer.getvalue())
    return path
