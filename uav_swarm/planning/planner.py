"""The placement planner: a crowd in, one target per UAV out (metres).

Two planners share one interface (:class:`Planner`) and one assignment step:

- :class:`LearnedPlanner` (``"learned"``, the product): the crowd's density raster
  (:func:`uav_swarm.missions.wifi.task.crowd_raster`, exactly the network's training input) ->
  the utility network of a checkpoint -> the local maxima of the utility map
  (:func:`learning.peaks.find_peaks` with the checkpoint's peak settings; at most ``n`` UAVs,
  the ``n`` highest kept) -> metres.
  With ``PlannerConfig.refine`` the peaks are then refined on the live crowd
  (:func:`uav_swarm.missions.wifi.refine.refine_placement`: drop, split, add, merge, centre under
  the strategy's rules, for at most ``n`` UAVs); the planner is then named
  ``cnn-peaks-refine-hungarian``. With ``PlannerConfig.rule_check`` the peaks (extracted at the
  check's threshold) are first kept only where the strategy's deployment rule justifies them on the
  same density raster (:mod:`uav_swarm.missions.wifi.rule_check`), and ``-rulecheck`` joins the name.
- :class:`ExpertPlanner` (``"expert"``, the reference): the Wi-Fi expert optimiser
  (:meth:`uav_swarm.missions.wifi.task.WifiTask.expert_placement_m`) for at most ``n`` UAVs.

Both planners propose a placement of the crowd; how the UAVs get there depends on
``PlannerConfig.mode``:

- ``"motion"`` (the default): planning in motion (:mod:`uav_swarm.planning.motion`): UAVs keep
  following the users they serve while the rule holds, free UAVs take the proposals that no kept UAV
  covers, assigned by time to reach, and a fresh assignment of every UAV replaces that only when it
  serves more over the next seconds (the crowd predicted from the pedestrians' velocities, the UAVs'
  speed and acceleration limits). Under a user cap, spare UAVs park away from every user.
- ``"snapshot"``: every replan assigns the proposal of the instant, as below.

Snapshot assignment (:func:`uav_swarm.planning.assignment.assign_targets`), the same for both:

1. **Hysteresis (no churn).** A UAV whose previous target is within ``hysteresis_m`` of a new
   candidate keeps its previous target, so small crowd motion does not reshuffle the swarm.
2. **Hungarian.** The other candidates go to the other UAVs with the least total travel distance.
3. **Fallback.** With fewer candidates than UAVs (the expert justifies a UAV only by more than
   ``min_group_size`` users; the network's peaks must pass the checkpoint's thresholds), the spare
   UAVs *hold their current position*, nudged off any other UAV's target so that targets stay
   pairwise distinct. With no candidate at all every UAV holds.

Latency: a learned replan (raster, network, peaks, Hungarian) reuses one preallocated input tensor
(channels-last), runs under :func:`torch.inference_mode` and allocates only the small raster and
utility arrays; ``PlannerConfig.torch_threads`` (default 1, the fastest on a shared CPU) sets the
process's torch threads and ``precision = "auto"`` (the default) runs the network in bfloat16 where
the processor computes it natively (:mod:`learning.precision`), which halves its time, and in
float32 elsewhere.

Examples:
    >>> planner = make_planner("expert", n_uavs=2)
    >>> crowd = np.concatenate([np.full((40, 2), 50.0), np.full((40, 2), 150.0)])
    >>> result = planner.plan(crowd, np.array([[140.0, 140.0], [60.0, 60.0]]))
    >>> result.targets_m.round(1).tolist()
    [[150.0, 150.0], [50.0, 50.0]]
"""

from __future__ import annotations

import importlib.resources
import logging
import time
from abc import ABC, abstractmethod
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Literal, Protocol, runtime_checkable

import numpy as np

from learning.peaks import find_peaks
from typed_config import Config, ConfigError, param
from uav_swarm.env.config import MAX_UAVS
from uav_swarm.missions.wifi.refine import WifiRefineConfig, refine_placement, strategy_refinement
from uav_swarm.missions.wifi.rule_check import RuleCheckConfig, WifiRuleCheck
from uav_swarm.missions.wifi.task import WifiConfig, WifiTask, coverage_rules, crowd_raster
from uav_swarm.planning.assignment import assign_targets
from uav_swarm.planning.motion import MotionConfig, MotionPlanning
from uav_swarm.world.uav import UAVConfig

if TYPE_CHECKING:
    import torch

__all__ = ["PLANNER_KINDS", "PlannerConfig", "PlanResult", "Planner", "AssigningPlanner", "LearnedPlanner",
           "ExpertPlanner", "make_planner", "default_checkpoint", "shipped_checkpoint_name", "check_n_uavs"]

logger = logging.getLogger(__name__)

PLANNER_KINDS = ("learned", "expert")
"""The planners :func:`make_planner` builds."""

_RASTER_FIELDS = ("size_px", "density_scale")
_AREA_FIELDS = ("width_m", "height_m")


@dataclass(frozen=True)
class PlannerConfig(Config):
    """Settings shared by the planners (assignment) and of the learned planner (inference)."""

    hysteresis_m: float = param(5.0, ge=0.0, le=1000.0,
                                doc="a UAV keeps its target while a new candidate is this close (m)")
    min_gap_m: float = param(1.0, ge=0.0, le=100.0, doc="smallest distance between two UAVs' targets (m)")
    torch_threads: int = param(1, ge=0, le=256,
                               doc="learned: torch CPU threads for the process (0: leave torch's setting)")
    precision: Literal["auto", "float32", "bfloat16"] = param(
        "auto", doc="learned: network precision ('auto': bfloat16 where the CPU or GPU computes it natively, "
        "about 2x faster; float32 elsewhere)")
    refine: bool = param(False, doc="learned: refine the peaks on the live crowd under the strategy's rules")
    refinement: WifiRefineConfig | None = param(
        None, doc="learned: the refinement's effort ([planning.refinement]); none given: the strategy's own "
        "(uav_swarm.missions.wifi.refine.strategy_refinement)")
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
        targets_m: ``(n, 2)`` float64 target of each UAV, metres, pairwise distinct.
        peaks_m: ``(k, 2)`` float64 candidate positions the planner proposed, best first, ``k <= n``.
        utility: ``(h, w)`` float32 utility map (row 0 = South) of the learned planner, None otherwise.
        candidate_index: ``(n,)`` index into ``peaks_m`` of each UAV's target, -1 where it holds (fallback).
        kept: ``(n,)`` True where the UAV kept its previous target (snapshot: hysteresis) or kept
            following its users (motion).
        latency_ms: Wall time of the whole replan, milliseconds.
        option: ``"snapshot"``, or in motion ``"hybrid"`` (kept UAVs follow their users, the others go
            to new proposals) or ``"fresh"`` (every UAV re-solved).
    """

    targets_m: np.ndarray
    peaks_m: np.ndarray
    utility: np.ndarray | None
    candidate_index: np.ndarray
    kept: np.ndarray
    latency_ms: float
    option: str = "snapshot"


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


class AssigningPlanner(ABC):
    """Base of the planners: subclasses propose candidates, this class assigns them (module docstring).

    Args:
        n_uavs: Number of UAVs, 1 to 10.
        config: Mode (motion or snapshot), hysteresis and target gap.
        task_config: The Wi-Fi task whose rules and radio planning in motion judges with; default
            ``WifiConfig()``.
        uav_config: The UAVs' speed and acceleration limits; default ``UAVConfig()``.

    Raises:
        ConfigError: ``n_uavs`` out of range.
    """

    name = "planner"

    def __init__(self, n_uavs: int, config: PlannerConfig | None = None,
                 task_config: WifiConfig | None = None, uav_config: UAVConfig | None = None) -> None:
        self.n_uavs = check_n_uavs(n_uavs)
        self.config = config or PlannerConfig()
        self._previous: np.ndarray | None = None
        task_config = task_config or WifiConfig()
        scenario = task_config.scenario
        self.motion = MotionPlanning(
            self.n_uavs, coverage_rules(task_config, max_uavs=min(task_config.expert.max_uavs, self.n_uavs)),
            task_config.radio, task_config.strategy, (scenario.width_m, scenario.height_m), uav_config,
            self.config.motion, self.config.min_gap_m)

    @abstractmethod
    def propose(self, pedestrians_m: np.ndarray, velocities_m_s: np.ndarray | None = None
                ) -> tuple[np.ndarray, np.ndarray | None]:
        """At most ``n_uavs`` candidate positions ``(k, 2)`` in metres, best first, and the utility map."""

    def reset(self) -> None:
        """Forget the previous targets and what each UAV serves: a new sequence starts."""
        self._previous = None
        self.motion.reset()

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
        candidates, utility = self.propose(peds, vels)
        candidates = np.asarray(candidates, dtype=np.float64).reshape(-1, 2)[:self.n_uavs]
        if self.config.mode == "motion":
            moved = self.motion.plan(peds, vels, uavs, candidates)
            targets, index, kept, option = moved.targets_m, moved.candidate_index, moved.kept, moved.option
        else:
            cfg = self.config
            assignment = assign_targets(uavs, candidates, self._previous, hysteresis_m=cfg.hysteresis_m,
                                        min_gap_m=cfg.min_gap_m)
            targets, index, kept, option = (assignment.targets_m, assignment.candidate_index, assignment.kept,
                                            "snapshot")
        self._previous = targets.copy()
        latency_ms = (time.perf_counter() - start) * 1e3
        return PlanResult(targets, candidates, utility, index, kept, latency_ms, option)


class ExpertPlanner(AssigningPlanner):
    """The Wi-Fi expert optimiser for at most ``n_uavs`` UAVs, then the shared assignment.

    Args:
        n_uavs: Number of UAVs, 1 to 10 (the expert's ``max_uavs`` is capped to it).
        task_config: The Wi-Fi task (strategy, radio, expert settings); default ``WifiConfig()``.
        config: Mode, hysteresis and target gap.
        uav_config: The UAVs' speed and acceleration limits (planning in motion).
    """

    name = "expert-hungarian"

    def __init__(self, n_uavs: int, task_config: WifiConfig | None = None,
                 config: PlannerConfig | None = None, uav_config: UAVConfig | None = None) -> None:
        task_config = task_config or WifiConfig()
        super().__init__(n_uavs, config, task_config, uav_config)
        expert = task_config.expert.replace(max_uavs=min(task_config.expert.max_uavs, self.n_uavs))
        self.task = WifiTask(task_config.replace(expert=expert))

    def propose(self, pedestrians_m: np.ndarray, velocities_m_s: np.ndarray | None = None
                ) -> tuple[np.ndarray, None]:
        """The expert's placement (metres) of the crowd."""
        if len(pedestrians_m) == 0:
            return np.zeros((0, 2)), None
        return self.task.expert_placement_m(pedestrians_m, velocities_m_s), None


def default_checkpoint(task_name: str = "wifi-s1") -> Path:
    """Where the shipped checkpoint of ``task_name`` lives (``uav_swarm/checkpoints/<task>.pt``)."""
    return Path(str(importlib.resources.files("uav_swarm").joinpath("checkpoints", f"{task_name}.pt")))


def shipped_checkpoint_name(task_config: WifiConfig) -> str:
    """The shipped checkpoint a task flies by default: ``wifi-s2-ac`` for strategy 2 under admission control.

    That network learned the capacitated expert (:mod:`uav_swarm.missions.wifi.capacitated`); the others
    are the task's name (``wifi-s1``, ``wifi-s2``: the paper's radio).
    """
    admission = task_config.strategy == 2 and task_config.radio.max_stations is not None
    return "wifi-s2-ac" if admission else f"wifi-s{task_config.strategy}"


def _missing_checkpoint_message(path: Path, task_name: str) -> str:
    return (f"no checkpoint at {path}: the shipped {task_name} checkpoint is not installed. Train one "
            f"(uav-swarm dataset --task {task_name} --n 5000 --seed 1 --out runs/{task_name}/data; "
            f"uav-swarm train --task {task_name} --data runs/{task_name}/data --out runs/{task_name}/train "
            f"--config configs/tasks/{task_name}.toml) and copy runs/{task_name}/train/best.pt to {path}, "
            "or pass --checkpoint PATH (or use --planner expert)")


class LearnedPlanner(AssigningPlanner):
    """Utility network -> peaks -> Hungarian (see the module docstring).

    Args:
        n_uavs: Number of UAVs, 1 to 10.
        task_config: The Wi-Fi task whose raster the planner builds (``size_px``, ``density_scale``,
            the area); it must match the checkpoint's. Default ``WifiConfig()``.
        checkpoint: A ``.pt`` file from ``uav-swarm train``; default the shipped
            ``uav_swarm/checkpoints/wifi-s<strategy>.pt`` (``wifi-s2-ac.pt`` under admission control).
        config: Assignment and inference settings.
        uav_config: The UAVs' speed and acceleration limits (planning in motion).

    Raises:
        ConfigError: ``n_uavs`` out of range, or a relocation refinement on strategy 1.
        learning.checkpoint.CheckpointError: The checkpoint is missing (the message says how to train
            one), corrupt, trained on another task, or on another raster (size, density scale, area).
    """

    name = "cnn-peaks-hungarian"

    def __init__(self, n_uavs: int, task_config: WifiConfig | None = None,
                 checkpoint: str | Path | None = None, config: PlannerConfig | None = None,
                 uav_config: UAVConfig | None = None) -> None:
        task_config = task_config or WifiConfig()
        super().__init__(n_uavs, config, task_config, uav_config)
        import torch

        from learning.checkpoint import CheckpointError, load_checkpoint
        from learning.precision import resolve_precision

        self.task = WifiTask(task_config)
        task_name = self.task.name
        self.refinement = self.config.refinement or strategy_refinement(task_config.strategy)
        """The refinement's settings: ``[planning.refinement]``, else the strategy's own."""
        if self.config.refine:
            self.refinement.check_rules(self.task.rules, "[planning.refinement]")
        shipped = shipped_checkpoint_name(task_config)
        path = default_checkpoint(shipped) if checkpoint in (None, "") else Path(checkpoint)
        if not path.is_file():
            if checkpoint in (None, ""):
                raise CheckpointError(_missing_checkpoint_message(path, task_name))
            raise CheckpointError(f"checkpoint not found: {path} (--checkpoint)")
        side = task_config.size_px
        ckpt = load_checkpoint(path, task_name=task_name)
        trained = ckpt.task_config
        velocity = bool(trained.get("velocity_channels", False))
        if velocity != task_config.velocity_channels:  # the raster is the network's: take its channels
            task_config = task_config.replace(velocity_channels=velocity)
            self.task = WifiTask(task_config)
            logger.info("%s was trained with velocity_channels = %s: the planner's raster follows", path,
                        velocity)
        if tuple(ckpt.input_shape) != (self.task.channels, side, side):
            raise CheckpointError(f"{path}: trained on inputs of shape {tuple(ckpt.input_shape)}, not "
                                  f"{(self.task.channels, side, side)} (the planner's raster)")
        for name in _RASTER_FIELDS:
            if name in trained and trained[name] != getattr(task_config, name):
                raise CheckpointError(f"{path}: trained with {name} = {trained[name]!r}, the planner's "
                                      f"raster has {name} = {getattr(task_config, name)!r}")
        for name in _AREA_FIELDS:
            value = trained.get("scenario", {}).get(name)
            if value is not None and value != getattr(task_config.scenario, name):
                raise CheckpointError(f"{path}: trained on an area with scenario.{name} = {value!r}, the "
                                      f"planner's area has {getattr(task_config.scenario, name)!r}")
        if self.config.torch_threads > 0:
            torch.set_num_threads(self.config.torch_threads)
        self.checkpoint = ckpt
        self.checkpoint_path = path
        self.name = ("cnn-peaks" + ("-rulecheck" if self.config.rule_check else "")
                     + ("-refine" if self.config.refine else "") + "-hungarian")
        self._check = WifiRuleCheck(self.task, self.config.rule_checking) if self.config.rule_check else None
        self._rules = coverage_rules(task_config, max_uavs=min(task_config.expert.max_uavs, self.n_uavs))
        self.peak_config = ckpt.peak_config
        if self._check is not None:
            self.peak_config = self.peak_config.replace(threshold_abs=self._check.threshold_abs)
        self.precision = resolve_precision(self.config.precision, next(ckpt.model.parameters()).device)
        dtype = torch.bfloat16 if self.precision == "bfloat16" else torch.float32
        self._model = ckpt.model.eval().to(dtype=dtype, memory_format=torch.channels_last)
        self._input: torch.Tensor = torch.zeros((1, self.task.channels, side, side), dtype=dtype).contiguous(
            memory_format=torch.channels_last)  # (1, C, h, w), reused by every replan
        self._inference_mode = torch.inference_mode
        self._from_numpy = torch.from_numpy

    def utility_map(self, raster: np.ndarray) -> np.ndarray:
        """The ``(h, w)`` float32 utility map of one ``(C, h, w)`` raster (no autograd, input reused)."""
        with self._inference_mode():
            self._input.copy_(self._from_numpy(raster)[None])  # (1, C, h, w)
            return self._model(self._input)[0, 0].float().numpy()  # (h, w)

    def propose(self, pedestrians_m: np.ndarray, velocities_m_s: np.ndarray | None = None
                ) -> tuple[np.ndarray, np.ndarray]:
        """The ``n_uavs`` highest peaks of the utility map (metres), refined if configured, and the map."""
        raster = crowd_raster(pedestrians_m, self.task.config, velocities_m_s)
        utility = self.utility_map(raster)
        peaks_px = find_peaks(utility, self.peak_config, max_peaks=self.n_uavs)
        if self._check is not None:
            peaks_px = self._check(raster, peaks_px)
        peaks_m = self.task.to_metres(peaks_px)
        if self.config.refine:
            peaks_m = refine_placement(pedestrians_m, peaks_m, self._rules, self.task.width_m,
                                       self.task.height_m, self.refinement)
        return peaks_m, utility


def make_planner(kind: str, n_uavs: int = MAX_UAVS, task_config: WifiConfig | None = None, *,
                 checkpoint: str | Path | None = None, config: PlannerConfig | None = None,
                 uav_config: UAVConfig | None = None) -> Planner:
    """Build a planner by name.

    Args:
        kind: ``"learned"`` or ``"expert"``.
        n_uavs: Number of UAVs, 1 to 10.
        task_config: The Wi-Fi task (raster, area, radio, expert); default ``WifiConfig()``.
        checkpoint: The learned planner's checkpoint (default: the shipped one); unused by the expert.
        config: Assignment and inference settings.
        uav_config: The UAVs' speed and acceleration limits, for planning in motion; default ``UAVConfig()``.

    Raises:
        ConfigError: Unknown ``kind`` or ``n_uavs`` out of range (checked before anything is loaded).
        learning.checkpoint.CheckpointError: See :class:`LearnedPlanner`.
    """
    if kind not in PLANNER_KINDS:
        raise ConfigError(f"planner = {kind!r} is not allowed: choose one of {list(PLANNER_KINDS)}")
    check_n_uavs(n_uavs)
    if kind == "learned":
        return LearnedPlanner(n_uavs, task_config, checkpoint, config, uav_config)
    return ExpertPlanner(n_uavs, task_config, config, uav_config)
