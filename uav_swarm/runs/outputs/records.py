"""Record types of a run: what :mod:`~uav_swarm.runs.simulate` and :mod:`~uav_swarm.runs.flight.loop` produce.

They live below the code that draws them (:mod:`~uav_swarm.runs.outputs.plots`,
:mod:`~uav_swarm.runs.outputs.animation`),
so no drawing module imports its caller.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from uav_swarm.runs.outputs.radio_report import RadioTrace

__all__ = ["Frame", "QosTrace", "SequenceRun"]


@dataclass(frozen=True)
class Frame:
    """A snapshot of a run for the animation (all positions in metres)."""

    time_s: float
    pedestrians_m: np.ndarray
    covered: np.ndarray
    uavs_m: np.ndarray
    targets_m: np.ndarray
    peaks_m: np.ndarray
    utility: np.ndarray | None
    qos_s1: float
    qos_s2: float
    association: np.ndarray | None = None
    """``(N,)`` each pedestrian's UAV, -1 for none (the 802.11 radio; None on the paper's)."""
    channels: np.ndarray | None = None
    """``(K,)`` each UAV's channel (the 802.11 radio; None on the paper's)."""


@dataclass
class SequenceRun:
    """What one planner did over the sequence.

    Attributes:
        planner: ``"learned"`` or ``"expert"``.
        planner_name: The planner's published name.
        times_s: ``(T,)`` simulated time after each step.
        qos_s1: ``(T,)`` share of the crowd covered after each step.
        qos_s2: ``(T,)`` share covered with at least the minimum rate.
        throughput_mbps: ``(T,)`` mean user throughput (uncovered users count 0).
        latency_ms: ``(R,)`` wall time of each replan.
        target_changes: ``(R - 1,)`` UAVs whose target moved (by more than ``min_gap_m``) at each replan.
        target_jumps: ``(R - 1,)`` UAVs whose target moved by more than
            :data:`uav_swarm.runs.service.JUMP_M` at each replan.
        distance_m: Total path length of the UAVs over the run, metres.
        final_targets_m: ``(n, 2)`` the last plan.
        final_pedestrians_m: ``(N, 2)`` the crowd at the end.
        n_pedestrians: Crowd size.
        obstacles_m: ``(M, 4)`` the scenario's obstacle segments.
        frames: Snapshots for the animation (empty unless asked for).
        qos_s2_paper: ``(T,)`` strategy 2's QoS of the same UAVs judged with the paper's radio (no admission
            control), when the run flew under admission control; empty otherwise.
        association: Which radio association the run's QoS used.
        separation: How close the UAVs came (:meth:`uav_swarm.runs.separation_watch.SeparationWatch.summary`).
        uav_tracks_m: ``(T, n, 2)`` the UAVs' positions after each step.
        crowd_samples: ``(time_s, positions, velocities)`` of the crowd every ``static_every_s`` from 0, for
            the static reference (empty unless asked for).
        radio: The 802.11 radio's figures after each step (channels, SINR/MCS, airtime, co-channel sharing);
            None under the paper's radio.
        interrupted_at_s: Where Ctrl-C cut the run short (the arrays cover the steps before it); None: the
            whole sequence flew.
    """

    planner: str
    planner_name: str
    times_s: np.ndarray
    qos_s1: np.ndarray
    qos_s2: np.ndarray
    throughput_mbps: np.ndarray
    latency_ms: np.ndarray
    target_changes: np.ndarray
    final_targets_m: np.ndarray
    final_pedestrians_m: np.ndarray
    n_pedestrians: int
    obstacles_m: np.ndarray
    frames: list[Frame] = field(default_factory=list)
    target_jumps: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    distance_m: float = 0.0
    qos_s2_paper: np.ndarray = field(default_factory=lambda: np.zeros(0))
    association: str = "paper (no admission control)"
    separation: dict = field(default_factory=dict)
    uav_tracks_m: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 2)))
    crowd_samples: list[tuple[float, np.ndarray, np.ndarray]] = field(default_factory=list)
    radio: RadioTrace | None = None
    interrupted_at_s: float | None = None


@dataclass
class QosTrace:
    """QoS over time of a flight (the shape :func:`uav_swarm.runs.outputs.plots.write_qos_figure` draws)."""

    planner_name: str
    times_s: np.ndarray
    qos_s1: np.ndarray
    qos_s2: np.ndarray
    throughput_mbps: np.ndarray
