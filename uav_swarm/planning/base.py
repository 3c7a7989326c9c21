"""The planners' common ground: settings, one replan's result, the interface and the assignment step.

:class:`AssigningPlanner` is the base of every planner of :mod:`uav_swarm.planning.planner`:
subclasses propose candidate positions, the base assigns them to the UAVs (planning in motion or the
snapshot assignment; the planner module's docstring tells both).

Separation: the planners keep every target at least the minimum separation from every other, the larger
of the task's ``min_separation_m`` and the UAVs' ``[uav] min_separation_m``
(:func:`~uav_swarm.missions.wifi.task.planner_task`):
the proposals are separated by construction and the assignment keeps them so.
"""

from __future__ import annotations

import copy
import time
from abc import ABC, abstractmethod
from dataclasses import dataclass, replace
from typing import Literal, Protocol, runtime_checkable

import numpy as np

from learning.operating_points import PeakOverrides
from typed_config import Config, ConfigError, param
from uav_swarm.env.config import MAX_UAVS
from uav_swarm.missions.wifi.refine import WifiRefineConfig
from uav_swarm.missions.wifi.rule_check import RuleCheckConfig
from uav_swarm.missions.wifi.task import WifiConfig, WifiTask, planner_task
from uav_swarm.planning.assignment import assign_targets
from uav_swarm.planning.horizon import warm_up
from uav_swarm.planning.motion import MotionConfig, MotionPlanning
from uav_swarm.planning.parking import warm_up as parking_warm_up
from uav_swarm.world.separation import check_fleet_fits
from uav_swarm.world.uav import UAVConfig

__all__ = ["PlannerConfig", "PlanResult", "Planner", "AssigningPlanner", "check_n_uavs",
           "task_with_uav_separation"]


@dataclass(frozen=True)
class PlannerConfig(Config):
    """Settings shared by the planners (assignment) and of the learned planner (inference)."""

    hysteresis_m: float = param(5.0, ge=0.0, le=1000.0,
                                doc="a UAV keeps its target while a new candidate is this close (m)")
    min_gap_m: float = param(1.0, ge=0.0, le=100.0, doc="smallest distance between two UAVs' targets (m); "
                             "the minimum separation ([uav] min_separation_m) when that is larger")
    torch_threads: int = param(1, ge=0, le=256,
                               doc="learned: CPU threads of torch (the process's) and of the inference "
                               "engine (0: leave their own setting)")
    precision: Literal["auto", "float32", "bfloat16"] = param(
        "float32", doc="learned: network precision ('float32': the exact engines; 'bfloat16': eager "
        "bfloat16, within 5 % of float32; 'auto': bfloat16 where the CPU or GPU computes it natively, "
        "else float32)")
    engine: Literal["auto", "onnxruntime", "torch-jit", "torch-eager", "torch-eager-bf16"] = param(
        "auto", doc="learned: inference engine ('auto': the fastest of the precision's engines, measured at "
        "load; a named one falls back to eager torch, with a log line, when its package is missing)")
    refine: bool = param(False, doc="learned: refine the peaks on the live crowd under the strategy's rules")
    refinement: WifiRefineConfig | None = param(
        None, doc="learned: the refinement's effort ([planning.refinement]); none given: the strategy's own "
        "(uav_swarm.missions.wifi.refine.strategy_refinement)")
    operating_point: Literal["mission", "balanced"] | None = param(
        None, doc="learned: the checkpoint's peak settings, chosen for the mission's QoS or for corr + "
        "precision (None: mission where the checkpoint has it, else balanced)")
    peaks: PeakOverrides = param(PeakOverrides(), doc="learned: peak settings applied over the operating "
                                 "point's ([planning.peaks]; a value left out keeps the checkpoint's)")
    rule_check: bool = param(False, doc="learned: keep only the peaks the strategy's deployment rule "
                             "justifies on the density raster (uav_swarm.missions.wifi.rule_check)")
    rule_checking: RuleCheckConfig = param(RuleCheckConfig(), doc="learned: the rule check's threshold and "
                                           "slack ([planning.rule_checking])")
    mode: Literal["motion", "snapshot"] = param(
        "motion", doc="'motion': replans start from what the UAVs serve (uav_swarm.planning.motion); "
        "'snapshot': every replan solves the instant, then hysteresis and Hungarian on distance")
    motion: MotionConfig = param(MotionConfig(), doc="planning in motion's settings ([planning.motion])")


@dataclass(frozen=True)
class PlanResult:
    """One replan.

    Attributes:
        targets_m: ``(n, 2)`` float64 target of each UAV, metres, at least the planner's ``min_gap_m`` apart
            (the minimum separation).
        peaks_m: ``(k, 2)`` float64 candidate positions the planner proposed, best first, ``k <= n``.
        utility: ``(h, w)`` float32 utility map (row 0 = South) of the learned planner, None otherwise.
        candidate_index: ``(n,)`` index into ``peaks_m`` of each UAV's target, -1 where it holds (fallback).
        kept: ``(n,)`` True where the UAV kept its previous target (snapshot: hysteresis) or kept
            following its users (motion).
        latency_ms: Wall time of the whole replan, milliseconds.
        option: ``"snapshot"``, or in motion ``"hybrid"`` (kept UAVs follow their users, the others go
            to new proposals) or ``"fresh"`` (every UAV re-solved).
        engine: The learned planner's inference engine (``learning.engines.ENGINES``), None otherwise.
    """

    targets_m: np.ndarray
    peaks_m: np.ndarray
    utility: np.ndarray | None
    candidate_index: np.ndarray
    kept: np.ndarray
    latency_ms: float
    option: str = "snapshot"
    engine: str | None = None

    @property
    def serving(self) -> np.ndarray:
        """``(n,)`` True where the plan gives the UAV users (a proposal, or its own users followed).

        The others are spares (parked or holding); under admission on rate (802.11) their access points stay
        off.
        """
        return (np.asarray(self.candidate_index) >= 0) | np.asarray(self.kept, dtype=bool)


@runtime_checkable
class Planner(Protocol):
    """Turns the crowd and the UAV positions into one target per UAV.

    Attributes:
        name: Short name, published with each plan (``cnn-peaks-hungarian``, ``expert-hungarian``).
        n_uavs: Number of UAVs planned for.
    """

    name: str
    n_uavs: int

    def plan(self, pedestrians_m: np.ndarray, uav_positions_m: np.ndarray,
             pedestrian_velocities_m_s: np.ndarray | None = None) -> PlanResult:
        """Plan for the crowd ``pedestrians_m`` ``(N, 2)`` and the UAVs at ``uav_positions_m`` ``(n, 2)``.

        ``pedestrian_velocities_m_s`` ``(N, 2)`` tells how the crowd walks (default: at rest).
        """
        ...

    def reset(self) -> None:
        """Forget the previous targets (a new sequence starts)."""
        ...


def check_n_uavs(n_uavs: int) -> int:
    """``n_uavs`` when ``1 <= n_uavs <= 10``.

    Raises:
        ConfigError: Out of range.
    """
    if isinstance(n_uavs, bool) or not isinstance(n_uavs, (int, np.integer)) or not 1 <= n_uavs <= MAX_UAVS:
        raise ConfigError(f"n_uavs = {n_uavs!r} is out of range: allowed 1 <= n_uavs <= {MAX_UAVS}")
    return int(n_uavs)


def task_with_uav_separation(task_config: WifiConfig, uav_config: UAVConfig, n_uavs: int) -> WifiConfig:
    """The task config of a run whose ``[uav] min_separation_m`` is the one minimum (simulate, fly).

    A task left at the default minimum takes the UAVs'; a task minimum the user set to another value is
    refused, as is a minimum ``n_uavs`` UAVs cannot keep in the area.

    Raises:
        ConfigError: The two minima differ, or the fleet cannot keep the minimum (the field named).
    """
    wanted = uav_config.min_separation_m
    scenario = task_config.scenario
    check_fleet_fits(n_uavs, wanted, scenario.width_m, scenario.height_m)
    if task_config.min_separation_m != wanted:
        if task_config.min_separation_m != WifiConfig().min_separation_m:
            raise ConfigError(
                f"task.min_separation_m = {task_config.min_separation_m:g} differs from "
                f"uav.min_separation_m = {wanted:g}: set the minimum once, in [uav] min_separation_m "
                "(allowed: task.min_separation_m absent or equal to it)")
        task_config = task_config.replace(min_separation_m=wanted)
    return task_config


class AssigningPlanner(ABC):
    """Base of the planners: subclasses propose candidates, this class assigns them (module docstring).

    Args:
        n_uavs: Number of UAVs, 1 to 10.
        config: Mode (motion or snapshot), hysteresis and target gap.
        task: The Wi-Fi task whose rules and radio planning in motion judges with (its expert's
            ``max_uavs`` at most ``n_uavs``: :func:`~uav_swarm.missions.wifi.task.planner_task`); default
            ``WifiConfig()``'s for ``n_uavs`` UAVs and ``uav_config``'s minimum separation.
        uav_config: The UAVs' speed and acceleration limits and minimum separation; default ``UAVConfig()``.

    Raises:
        ConfigError: ``n_uavs`` out of range.
    """

    name = "planner"

    def __init__(self, n_uavs: int, config: PlannerConfig | None = None, task: WifiTask | None = None,
                 uav_config: UAVConfig | None = None) -> None:
        self.n_uavs = check_n_uavs(n_uavs)
        self.config = config or PlannerConfig()
        self._previous: np.ndarray | None = None
        if task is None:
            task = planner_task(None, self.n_uavs, min_separation_m=uav_config.min_separation_m if uav_config
                                else 0.0)
        self.task = task
        """The Wi-Fi task the planner proposes for and judges with."""
        task_config = task.config
        scenario = task_config.scenario
        self.min_gap_m = max(self.config.min_gap_m, task_config.min_separation_m)
        """Smallest distance between two targets: ``min_gap_m``, or the minimum separation when larger."""
        self._area_m = np.array([scenario.width_m, scenario.height_m])
        self.motion = MotionPlanning(
            self.n_uavs, replace(task.rules, max_uavs=min(task.rules.max_uavs, self.n_uavs)),
            task_config.radio, task_config.strategy, (scenario.width_m, scenario.height_m), uav_config,
            self.config.motion, self.min_gap_m)
        if self.config.mode == "motion":
            warm_up()  # the horizon's compiled loop, loaded now rather than at the first replan
            parking_warm_up()  # and the spares' parking search

    @abstractmethod
    def propose(self, pedestrians_m: np.ndarray, velocities_m_s: np.ndarray | None = None
                ) -> tuple[np.ndarray, np.ndarray | None]:
        """At most ``n_uavs`` candidate positions ``(k, 2)`` in metres, best first, and the utility map."""

    def reset(self) -> None:
        """Forget the previous targets and what each UAV serves: a new sequence starts."""
        self._previous = None
        self.motion.reset()

    def fork(self) -> AssigningPlanner:
        """A planner of another world: the same settings and network, a sequence state of its own (reset)."""
        twin = copy.copy(self)
        twin.motion = copy.deepcopy(self.motion)
        twin.reset()
        return twin

    def plan(self, pedestrians_m: np.ndarray, uav_positions_m: np.ndarray,
             pedestrian_velocities_m_s: np.ndarray | None = None) -> PlanResult:
        """Propose candidates for the crowd and assign them to the UAVs (see the module docstring).

        Args:
            pedestrians_m: ``(N, 2)`` pedestrian positions, metres (``N`` may be 0).
            uav_positions_m: ``(n_uavs, 2)`` current UAV positions, metres.
            pedestrian_velocities_m_s: ``(N, 2)`` pedestrian velocities, m/s; default at rest (planning in
                motion then follows the users without leading them).

        Raises:
            ValueError: An array of the wrong shape.
        """
        start = time.perf_counter()
        peds, vels, uavs = self._checked(pedestrians_m, uav_positions_m, pedestrian_velocities_m_s)
        candidates, utility = self.propose(peds, vels)
        return self._settle(peds, vels, uavs, candidates, utility, start)

    def _checked(self, pedestrians_m: np.ndarray, uav_positions_m: np.ndarray,
                 pedestrian_velocities_m_s: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(pedestrians, velocities, uavs)`` as float64 arrays of the shapes :meth:`plan` documents."""
        uavs = np.asarray(uav_positions_m, dtype=np.float64)
        if uavs.shape != (self.n_uavs, 2):
            raise ValueError(f"uav_positions_m must have shape ({self.n_uavs}, 2), got {uavs.shape}")
        peds = np.asarray(pedestrians_m, dtype=np.float64)
        if peds.size == 0:
            peds = peds.reshape(0, 2)
        if peds.ndim != 2 or peds.shape[1] != 2:
            raise ValueError(f"pedestrians_m must have shape (N, 2), got {peds.shape}")
        if pedestrian_velocities_m_s is None:
            vels = np.zeros_like(peds)
        else:
            vels = np.asarray(pedestrian_velocities_m_s, dtype=np.float64).reshape(-1, 2)
            if vels.shape != peds.shape or not np.all(np.isfinite(vels)):
                raise ValueError(f"pedestrian_velocities_m_s must be finite with shape {peds.shape}, "
                                 f"got {vels.shape}")
        return peds, vels, uavs

    def _settle(self, peds: np.ndarray, vels: np.ndarray, uavs: np.ndarray, candidates: np.ndarray,
                utility: np.ndarray | None, start: float) -> PlanResult:
        """Assign the proposed ``candidates`` (motion or snapshot) and remember the targets."""
        candidates = np.asarray(candidates, dtype=np.float64).reshape(-1, 2)[:self.n_uavs]
        if self.config.mode == "motion":
            moved = self.motion.plan(peds, vels, uavs, candidates)
            targets, index, kept, option = moved.targets_m, moved.candidate_index, moved.kept, moved.option
        else:
            cfg = self.config
            assignment = assign_targets(uavs, candidates, self._previous, hysteresis_m=cfg.hysteresis_m,
                                        min_gap_m=self.min_gap_m, upper_m=self._area_m)
            targets, index, kept, option = (assignment.targets_m, assignment.candidate_index, assignment.kept,
                                            "snapshot")
        self._previous = targets.copy()
        latency_ms = (time.perf_counter() - start) * 1e3
        return PlanResult(targets, candidates, utility, index, kept, latency_ms, option,
                          getattr(self, "engine", None))
