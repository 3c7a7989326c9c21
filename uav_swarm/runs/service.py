"""What a flying swarm delivers, against what a snapshot promises: the service figures of a run.

- **Static reference**: every ``every_s`` seconds, the expert's placement of that instant's crowd,
  judged with the radio model as if the UAVs were already there (so it depends on the crowd alone).
  For strategy 2 under admission control it is the capacitated expert
  (:mod:`uav_swarm.missions.wifi.capacitated`); on the paper's radio the better of the group expert and the
  search expert of :mod:`uav_swarm.missions.wifi.expert`; for strategy 1 the search expert.
- **Flown / static**: the mean QoS the UAVs delivered over the run divided by the mean static reference.
- **Target jumps**: UAVs whose target moved more than ``JUMP_M`` between two replans (a walking group
  moves about 1.3 m in a second, so following it is not a jump).
- **Metres flown per UAV-minute**: the UAVs' path length, per UAV and minute of flight.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from uav_swarm.missions.wifi.task import WifiConfig, WifiTask
from uav_swarm.world.comms import evaluate_coverage
from uav_swarm.world.wifi.channels import plan_channels

__all__ = ["JUMP_M", "StaticReference", "static_reference", "reference_qos", "target_jumps",
           "metres_per_uav_minute", "flight_figures"]

JUMP_M = 5.0
"""A target that moves more than this between two replans has jumped (metres)."""

@dataclass(frozen=True)
class StaticReference:
    """The expert's placements of the crowd at regular instants, judged as if reached.

    Attributes:
        times_s: ``(R,)`` the instants.
        qos: ``(R,)`` the strategy's QoS of the best expert placement at each instant.
        experts: The experts compared (``"search"``, ``"groups"``).
        every_s: Seconds between two instants.
    """

    times_s: np.ndarray
    qos: np.ndarray
    experts: tuple[str, ...]
    every_s: float

    @property
    def mean(self) -> float:
        """Mean QoS over the instants (0 when there is none)."""
        return float(self.qos.mean()) if self.qos.size else 0.0


def _experts(task_config: WifiConfig, n_uavs: int) -> dict[str, WifiTask]:
    """The strategy's experts for ``n_uavs`` UAVs.

    Strategy 2 under admission control: the capacitated expert; on the paper's radio: the group and the
    search expert; strategy 1: the search expert. Under the 802.11 radio: its own expert (``auto``).
    """
    if task_config.radio.propagation == "802.11":
        methods: tuple[str, ...] = ("auto",)
    elif task_config.strategy == 2:
        admission = task_config.radio.max_stations is not None
        methods = ("capacitated",) if admission else ("groups", "search")
    else:
        methods = ("search",)
    tasks = {}
    for method in methods:
        expert = task_config.expert.replace(method=method, max_uavs=min(task_config.expert.max_uavs, n_uavs))
        tasks[method] = WifiTask(task_config.replace(expert=expert))
    return tasks


def reference_qos(users_m: np.ndarray, velocities_m_s: np.ndarray, task_config: WifiConfig, n_uavs: int,
                  altitudes_m: np.ndarray | None = None) -> float:
    """The strategy's QoS of the best expert placement of one crowd, judged as if reached.

    The 802.11 radio judges each placement with the UAVs at ``altitudes_m`` ((n_uavs,), the first ones
    used) on the channels :func:`~uav_swarm.world.wifi.channels.plan_channels` gives them.
    """
    best = 0.0
    wifi = task_config.radio.propagation == "802.11"
    for task in _experts(task_config, n_uavs).values():
        placement = task.expert_placement_m(users_m, velocities_m_s)
        heights = None if altitudes_m is None else np.asarray(altitudes_m, np.float64)[:len(placement)]
        channels = plan_channels(placement, task_config.radio, heights) if wifi else None
        coverage = evaluate_coverage(users_m, placement, task_config.radio, heights if wifi else None,
                                     channels)
        best = max(best, float(coverage.qos_s1 if task_config.strategy == 1 else coverage.qos_s2))
    return best


def static_reference(crowds: Iterable[tuple[float, np.ndarray, np.ndarray]], task_config: WifiConfig,
                     n_uavs: int, every_s: float, altitudes_m: np.ndarray | None = None) -> StaticReference:
    """The static reference of ``(time_s, users_m, velocities_m_s)`` crowds (module docstring).

    ``altitudes_m``: (n_uavs,) the UAVs' altitudes, which the 802.11 radio needs.
    """
    times, qos = [], []
    for time_s, users_m, velocities_m_s in crowds:
        times.append(time_s)
        qos.append(reference_qos(users_m, velocities_m_s, task_config, n_uavs, altitudes_m))
    return StaticReference(np.array(times), np.array(qos), tuple(_experts(task_config, n_uavs)), every_s)


def target_jumps(targets_m: np.ndarray) -> np.ndarray:
    """``(R - 1,)`` UAVs whose target moved over :data:`JUMP_M` at each replan of ``(R, n, 2)`` targets."""
    targets_m = np.asarray(targets_m, dtype=np.float64)
    if len(targets_m) < 2:
        return np.zeros(0, dtype=np.int64)
    moved = np.linalg.norm(np.diff(targets_m, axis=0), axis=-1)
    return np.count_nonzero(moved > JUMP_M, axis=1)


def metres_per_uav_minute(distance_m: float, n_uavs: int, duration_s: float) -> float:
    """Path length per UAV and minute of flight."""
    return float(distance_m / max(n_uavs, 1) / max(duration_s / 60.0, 1e-9))


def flight_figures(flown_qos: np.ndarray, plans: list[dict[int, tuple[float, float]]],
                   track: list[dict], crowd_samples: list[tuple[float, np.ndarray, np.ndarray]],
                   task_config: WifiConfig, n_uavs: int, duration_s: float, every_s: float,
                   altitudes_m: np.ndarray | None = None) -> tuple[dict[str, float | None], StaticReference]:
    """The service figures of a live flight (``uav-swarm fly``), as ``simulate`` reports them.

    Args:
        flown_qos: ``(T,)`` the strategy's QoS recorded over the flight.
        plans: Each replan's targets by UAV id.
        track: The recorded vehicle positions (``uav_id``, ``time_s``, ``x_m``, ``y_m`` rows).
        crowd_samples: The crowd every ``every_s``, for the static reference.
        task_config: The Wi-Fi task (strategy, radio, experts).
        n_uavs: Vehicles flown.
        duration_s: Flight time.
        every_s: Seconds between two crowd samples.
        altitudes_m: (n_uavs,) the vehicles' cruise altitudes (the 802.11 radio's static reference).

    Returns:
        The figures, and the static reference they were judged against.
    """
    reference = static_reference(crowd_samples, task_config, n_uavs, every_s, altitudes_m)
    jumps = [sum(1 for uav, xy in after.items() if uav in before
                 and np.hypot(xy[0] - before[uav][0], xy[1] - before[uav][1]) > JUMP_M)
             for before, after in zip(plans[:-1], plans[1:], strict=True)]
    distance = 0.0
    for uav in {row["uav_id"] for row in track}:
        path = np.array([(row["x_m"], row["y_m"]) for row in sorted(track, key=lambda r: r["time_s"])
                         if row["uav_id"] == uav])
        distance += float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum()) if len(path) > 1 else 0.0
    flown = float(np.mean(flown_qos)) if len(flown_qos) else 0.0
    return {"flown_qos": flown, "static_reference_qos": reference.mean,
            "flown_over_static": flown / reference.mean if reference.mean > 0 else None,
            "target_jumps_per_replan": float(np.mean(jumps)) if jumps else 0.0,
            "metres_per_uav_minute": metres_per_uav_minute(distance, n_uavs, duration_s)}, reference
