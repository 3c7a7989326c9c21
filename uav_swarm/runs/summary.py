"""The results summary of a run, for ``summary.json``: one module for ``simulate`` and ``fly``.

Both jobs report the same figures of their flown QoS (mean and min of QoS S1 and S2, mean throughput, the
association that judged them), the same service figures (:mod:`uav_swarm.runs.service`: flown over static
reference, target jumps, metres per UAV-minute) and the same static reference record, sampled during the
run every ``static_every_s`` (the crowd walks the same whatever the UAVs do). ``simulate`` adds the
planning latency and churn of each planner and the learned / expert ratios; ``fly`` adds its vehicles'
outcomes (:meth:`uav_swarm.runs.flight.loop.Flight.summary`).

Examples:
    >>> import numpy as np
    >>> qos_figures(np.array([0.5, 1.0]), np.array([0.25, 0.5]), np.array([2.0, 4.0]))["min_qos_s1"]
    0.5
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from uav_swarm.runs.outputs.radio_report import radio_summary
from uav_swarm.runs.outputs.records import QosTrace, SequenceRun
from uav_swarm.runs.service import StaticReference, flight_figures, metres_per_uav_minute

if TYPE_CHECKING:
    from uav_swarm.planning.base import Planner
    from uav_swarm.runs.fly_config import FlyConfig
    from uav_swarm.runs.simulate_config import SimulateConfig

__all__ = ["qos_figures", "summarise_run", "ratios_learned_over_expert", "reference_record",
           "summarise_flight", "planner_names"]


def planner_names(planner: Planner) -> dict[str, str]:
    """What a planner ran, for ``summary.json``: the learned network's ``checkpoint``, the ``expert``.

    The shipped checkpoint is named by its package path (the same on every machine).
    """
    from learning.checkpoint import checkpoint_label
    from uav_swarm.planning.planner import ExpertPlanner, LearnedPlanner, default_checkpoint

    if isinstance(planner, LearnedPlanner):
        path = planner.checkpoint_path
        shipped = path.resolve() == default_checkpoint(path.stem).resolve()
        return {"checkpoint": f"uav_swarm/checkpoints/{path.name} (shipped)" if shipped
                else checkpoint_label(path)}
    if isinstance(planner, ExpertPlanner):
        return {"expert": planner.task.expert_name}
    return {}


def qos_figures(qos_s1: np.ndarray, qos_s2: np.ndarray, throughput_mbps: np.ndarray) -> dict[str, float]:
    """Mean and min QoS S1 and S2 and the mean throughput over a run's records."""
    return {"mean_qos_s1": float(qos_s1.mean()), "min_qos_s1": float(qos_s1.min()),
            "mean_qos_s2": float(qos_s2.mean()), "min_qos_s2": float(qos_s2.min()),
            "mean_throughput_mbps": float(throughput_mbps.mean())}


def summarise_run(run: SequenceRun, config: SimulateConfig | None = None,
                  reference: StaticReference | None = None) -> dict[str, Any]:
    """Mean/min QoS S1 and S2, mean throughput, median/p95 latency, churn and service figures of one run.

    With the run's ``config`` and the sequence's static ``reference``: the strategy's flown QoS over the
    static reference, target jumps per replan and metres flown per UAV-minute
    (:mod:`uav_swarm.runs.service`). Under the 802.11 radio, ``wifi_80211``: channels, SINR/MCS, airtime
    and co-channel sharing (:func:`uav_swarm.runs.outputs.radio_report.radio_summary`).
    """
    changes = float(run.target_changes.mean()) if run.target_changes.size else 0.0
    figures: dict[str, float | None] = {}
    if config is not None:
        flown = run.qos_s1 if config.task.strategy == 1 else run.qos_s2
        figures = {
            "flown_qos": float(flown.mean()),
            "static_reference_qos": None if reference is None else reference.mean,
            "flown_over_static": (float(flown.mean()) / reference.mean
                                  if reference is not None and reference.mean > 0 else None),
            "target_jumps_per_replan": float(run.target_jumps.mean()) if run.target_jumps.size else 0.0,
            "metres_per_uav_minute": metres_per_uav_minute(
                run.distance_m, config.n_uavs, float(run.times_s[-1]) if run.times_s.size else 0.0),
        }
    return {**figures, "planner": run.planner_name,
            **qos_figures(run.qos_s1, run.qos_s2, run.throughput_mbps),
            "median_latency_ms": float(np.median(run.latency_ms)),
            "p95_latency_ms": float(np.percentile(run.latency_ms, 95)),
            "n_replans": int(run.latency_ms.size), "n_pedestrians": run.n_pedestrians,
            "mean_target_changes_per_replan": changes, "association": run.association,
            **({"mean_qos_s2_paper_radio": float(run.qos_s2_paper.mean())} if run.qos_s2_paper.size else {}),
            "separation": run.separation,
            **({"wifi_80211": radio_summary(run.radio, config.dt_s, config.task.radio)}
               if run.radio is not None and config is not None else {})}


def ratios_learned_over_expert(learned: dict[str, Any], expert: dict[str, Any]) -> dict[str, float | None]:
    """Learned / expert mean QoS and throughput, and expert / learned median planning time."""
    def ratio(a: float, b: float) -> float | None:
        return float(a / b) if b > 0 else None

    return {
        "mean_qos_s1": ratio(learned["mean_qos_s1"], expert["mean_qos_s1"]),
        "mean_qos_s2": ratio(learned["mean_qos_s2"], expert["mean_qos_s2"]),
        "mean_throughput_mbps": ratio(learned["mean_throughput_mbps"], expert["mean_throughput_mbps"]),
        "expert_over_learned_median_latency": ratio(expert["median_latency_ms"],
                                                    learned["median_latency_ms"]),
    }


def reference_record(reference: StaticReference, strategy: int) -> dict[str, Any]:
    """The static reference as ``summary.json`` keeps it: its mean, instants and QoS, the experts."""
    return {"mean_qos": reference.mean, "every_s": reference.every_s, "experts": list(reference.experts),
            "strategy": strategy, "times_s": reference.times_s.tolist(), "qos": reference.qos.tolist()}


def summarise_flight(trace: QosTrace, config: FlyConfig, n_uavs: int,
                     plans: list[dict[int, tuple[float, float]]], track: list[dict],
                     crowd_samples: list[tuple[float, np.ndarray, np.ndarray]]) -> dict[str, Any]:
    """A flight's QoS and service figures, and its static reference (the crowd sampled in flight)."""
    duration_s = float(trace.times_s[-1])
    flown = trace.qos_s1 if config.task.strategy == 1 else trace.qos_s2
    service, reference = flight_figures(flown, plans, track, crowd_samples, config.task, n_uavs, duration_s,
                                        config.static_every_s, config.uav.altitudes_m(n_uavs))
    return {"duration_s": duration_s, "planner": trace.planner_name,
            **qos_figures(trace.qos_s1, trace.qos_s2, trace.throughput_mbps),
            "association": config.task.radio.association_name, "service": service,
            "static_reference": reference_record(reference, config.task.strategy)}
