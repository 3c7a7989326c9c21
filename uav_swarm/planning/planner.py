"""The placement planner: a crowd in, one target per UAV out (metres).

Two planners share one interface (:class:`Planner`) and one assignment step:

- :class:`LearnedPlanner` (``"learned"``, the product): the crowd's density raster
  (:func:`uav_swarm.missions.wifi.task.crowd_raster`, exactly the network's training input) ->
  the utility network of a checkpoint -> the local maxima of the utility map
  (:func:`learning.peaks.find_peaks` with the checkpoint's peak settings: its mission operating point
  where it has one, ``PlannerConfig.operating_point`` and ``[planning.peaks]`` over it, recorded in
  ``LearnedPlanner.peak_choice``; at most ``n`` UAVs, the ``n`` highest kept, at least the minimum
  separation apart) -> metres.
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
2. **Hungarian.** The other candidates go to the other UAVs with the least sum of squared travel
   distances (paths that do not cross where an exchange would shorten them).
3. **Fallback.** With fewer candidates than UAVs (the expert justifies a UAV only by more than
   ``min_group_size`` users; the network's peaks must pass the checkpoint's thresholds), the spare
   UAVs *hold their current position*, nudged off any other UAV's target so that targets stay
   pairwise distinct. With no candidate at all every UAV holds.

Latency: the learned planner runs its network on the fastest engine the machine has
(:func:`learning.inference.select_engine`, chosen at load by measuring among ONNX Runtime when
installed, a traced TorchScript graph and eager torch, all equal to eager float32 within 1e-3 per pixel;
``PlannerConfig.engine`` names one instead), named in ``PlanResult.engine`` and in ``uav-swarm
simulate``'s summary. ``PlannerConfig.torch_threads`` (default 1, the fastest on a shared CPU) sets the
process's torch threads and the engine's; ``precision = "bfloat16"`` (or ``"auto"`` where the processor
computes bfloat16 natively) runs eager bfloat16 instead, faster on such CPUs but not equal to float32
(:data:`learning.inference.BFLOAT16_TOLERANCE`). Many worlds are planned in one forward pass by
:func:`uav_swarm.planning.batch.plan_batch`.

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
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from learning.operating_points import choose_peaks
from learning.peaks import find_peaks
from typed_config import ConfigError
from uav_swarm.env.config import MAX_UAVS
from uav_swarm.missions.wifi.refine import refine_placement, strategy_refinement
from uav_swarm.missions.wifi.relocation import warm_up as relocation_warm_up
from uav_swarm.missions.wifi.rule_check import WifiRuleCheck
from uav_swarm.missions.wifi.task import WifiConfig, WifiTask, crowd_raster, planner_task
from uav_swarm.missions.wifi.warm_start import replan_expert
from uav_swarm.planning.base import (
    AssigningPlanner,
    Planner,
    PlannerConfig,
    PlanResult,
    check_n_uavs,
)
from uav_swarm.world.radio_config import RadioConfig
from uav_swarm.world.uav import UAVConfig

__all__ = ["PLANNER_KINDS", "PlannerConfig", "PlanResult", "Planner", "AssigningPlanner", "LearnedPlanner",
           "ExpertPlanner", "make_planner", "make_planners", "default_checkpoint", "shipped_checkpoint_name",
           "check_n_uavs"]

logger = logging.getLogger(__name__)

PLANNER_KINDS = ("learned", "expert")
"""The planners :func:`make_planner` builds."""

_RASTER_FIELDS = ("size_px", "density_scale")
_AREA_FIELDS = ("width_m", "height_m")


class ExpertPlanner(AssigningPlanner):
    """The Wi-Fi expert optimiser for at most ``n_uavs`` UAVs, then the shared assignment.

    Args:
        n_uavs: Number of UAVs, 1 to 10 (the expert's ``max_uavs`` is capped to it).
        task_config: The Wi-Fi task (strategy, radio, expert settings); default ``WifiConfig()``.
        config: Mode, hysteresis and target gap.
        uav_config: The UAVs' speed and acceleration limits (planning in motion).
        task: The task already built for ``n_uavs`` UAVs (another planner's, to compare with it), in place
            of ``task_config``.
    """

    name = "expert-hungarian"

    def __init__(self, n_uavs: int, task_config: WifiConfig | None = None,
                 config: PlannerConfig | None = None, uav_config: UAVConfig | None = None, *,
                 task: WifiTask | None = None) -> None:
        if task is None:
            task = planner_task(task_config, check_n_uavs(n_uavs),
                                min_separation_m=_uav_separation_m(uav_config))
        super().__init__(n_uavs, config, task, uav_config)
        self.replans = replan_expert(self.task)

    def propose(self, pedestrians_m: np.ndarray, velocities_m_s: np.ndarray | None = None
                ) -> tuple[np.ndarray, None]:
        """The expert's placement (metres) of the crowd, warm-started from the last ([task.expert.replan])."""
        if len(pedestrians_m) == 0:
            return np.zeros((0, 2)), None
        return self.replans.place(pedestrians_m, velocities_m_s), None

    def reset(self) -> None:
        """Forget the previous targets and the last placement: a new sequence starts."""
        super().reset()
        self.replans = replan_expert(self.task)


def _uav_separation_m(uav_config: UAVConfig | None) -> float:
    """The UAVs' minimum separation a planner's placements keep too (0 without a UAV config)."""
    return 0.0 if uav_config is None else uav_config.min_separation_m


def default_checkpoint(task_name: str = "wifi-s1") -> Path:
    """Where the shipped checkpoint of ``task_name`` lives (``uav_swarm/checkpoints/<task>.pt``)."""
    return Path(str(importlib.resources.files("uav_swarm").joinpath("checkpoints", f"{task_name}.pt")))


def shipped_checkpoint_name(task_config: WifiConfig) -> str:
    """The shipped checkpoint a task flies by default.

    ``wifi-s1-80211`` and ``wifi-s2-80211`` under the 802.11 radio (the 802.11 expert's networks,
    :mod:`uav_swarm.missions.wifi.ieee80211_expert`); ``wifi-s2-ac`` for strategy 2 under admission control
    (the capacitated expert's, :mod:`uav_swarm.missions.wifi.capacitated`); else the task's name
    (``wifi-s1``, ``wifi-s2``: the paper's radio).
    """
    if task_config.radio.propagation == "802.11":
        return f"wifi-s{task_config.strategy}-80211"
    admission = task_config.strategy == 2 and task_config.radio.max_stations is not None
    return "wifi-s2-ac" if admission else f"wifi-s{task_config.strategy}"


def _missing_checkpoint_message(path: Path, task_name: str, shipped: str) -> str:
    config = f"configs/tasks/{shipped}.toml"
    return (f"no checkpoint at {path}: the shipped {shipped} checkpoint is not installed. Train one "
            f"(uav-swarm dataset --task {task_name} --config {config} --n 5000 --seed 1 "
            f"--out runs/{shipped}/data; "
            f"uav-swarm train --task {task_name} --data runs/{shipped}/data --out runs/{shipped}/train "
            f"--config {config}) and copy runs/{shipped}/train/best.pt to {path}, "
            "or pass --checkpoint PATH (or use --planner expert)")


def _check_radio(path: Path, trained: dict[str, Any], task_config: WifiConfig, shipped: str, *,
                 from_shipped: bool) -> None:
    """Refuse a network trained for another radio or admission than the task flies, in one line.

    Raises:
        learning.checkpoint.CheckpointError: The checkpoint's task was on another radio or admission.
    """
    from learning.checkpoint import CheckpointError

    try:
        radio = RadioConfig.from_dict(trained.get("radio", {})).for_strategy(int(trained.get("strategy", 1)))
    except (ConfigError, TypeError, ValueError) as exc:
        raise CheckpointError(f"{path}: its radio is not a valid RadioConfig: {exc}") from None
    flown = task_config.radio
    if radio.radio_and_admission != flown.radio_and_admission:
        fix = ("train one for it" if from_shipped else "leave --checkpoint out (the shipped one for this "
               f"task is uav_swarm/checkpoints/{shipped}.pt)")
        raise CheckpointError(f"{path}: trained for {radio.radio_and_admission}, this run flies strategy "
                              f"{task_config.strategy} on {flown.radio_and_admission}: {fix}, or set "
                              "[task.radio] to what the network was trained for")


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
        ConfigError: ``n_uavs`` out of range, a relocation refinement on strategy 1, or peak settings that
            cannot apply (``[planning.peaks]``, ``operating_point``).
        learning.checkpoint.CheckpointError: The checkpoint is missing (the message says how to train
            one), corrupt, trained on another task, or on another raster (size, density scale, area).
    """

    name = "cnn-peaks-hungarian"

    def __init__(self, n_uavs: int, task_config: WifiConfig | None = None,
                 checkpoint: str | Path | None = None, config: PlannerConfig | None = None,
                 uav_config: UAVConfig | None = None) -> None:
        import torch

        from learning.checkpoint import CheckpointError, load_checkpoint
        from learning.inference import select_engine
        from learning.precision import resolve_precision

        n_uavs = check_n_uavs(n_uavs)  # before anything is loaded
        task_config = WifiConfig() if task_config is None else task_config
        shipped = shipped_checkpoint_name(task_config)
        task_name = f"wifi-s{task_config.strategy}"  # the task's name, checked against the checkpoint's
        path = default_checkpoint(shipped) if checkpoint in (None, "") else Path(checkpoint)
        if not path.is_file():
            if checkpoint in (None, ""):
                raise CheckpointError(_missing_checkpoint_message(path, task_name, shipped))
            raise CheckpointError(f"checkpoint not found: {path} (--checkpoint)")
        ckpt = load_checkpoint(path, task_name=task_name)
        trained = ckpt.task_config
        _check_radio(path, trained, task_config, shipped, from_shipped=checkpoint in (None, ""))
        velocity = bool(trained.get("velocity_channels", False))
        if velocity != task_config.velocity_channels:  # the raster is the network's: take its channels
            logger.info("%s was trained with velocity_channels = %s: the planner's raster follows", path,
                        velocity)
        super().__init__(n_uavs, config, planner_task(task_config, n_uavs,
                                                      min_separation_m=_uav_separation_m(uav_config),
                                                      velocity_channels=velocity), uav_config)
        task_config = self.task.config
        side = task_config.size_px
        self.refinement = self.config.refinement or strategy_refinement(task_config.strategy)
        """The refinement's settings: ``[planning.refinement]``, else the strategy's own."""
        if self.config.refine:
            self.refinement.check_rules(self.task.rules, "[planning.refinement]")
            relocation_warm_up()  # strategy 2's relocation search: compiled once, before the first replan
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
        self.min_separation_px = task_config.min_separation_m * side / task_config.scenario.width_m
        """The peaks' minimum separation in raster pixels (the task's, at least the UAVs')."""
        fixed = {} if self._check is None else {
            "threshold_abs": (self._check.threshold_abs, "the rule check ([planning.rule_checking])")}
        self.peak_choice = choose_peaks(ckpt.peak_config, ckpt.mission_peak_config, self.config.peaks,
                                        operating_point=self.config.operating_point,
                                        source="the planner config", table="[planning.peaks]", fixed=fixed)
        """The peak settings that run and their source (:class:`learning.operating_points.PeakChoice`)."""
        self.peak_config = self.peak_choice.config
        self.precision = resolve_precision(self.config.precision, next(ckpt.model.parameters()).device)
        engines = None if self.config.engine == "auto" else (self.config.engine,)
        self.engine_choice = select_engine(ckpt.model, (self.task.channels, side, side), self.precision,
                                           self.config.torch_threads, engines)
        """The inference engine, the candidates' timings and why others were skipped."""
        self.engine = self.engine_choice.name

    def utility_map(self, raster: np.ndarray) -> np.ndarray:
        """The ``(h, w)`` float32 utility map of one ``(C, h, w)`` raster, on the chosen engine."""
        return self.utility_maps(np.asarray(raster, dtype=np.float32)[None])[0]

    def utility_maps(self, rasters: np.ndarray) -> np.ndarray:
        """The ``(B, h, w)`` float32 utility maps of ``(B, C, h, w)`` rasters in one forward pass."""
        return self.engine_choice.engine.maps(np.ascontiguousarray(rasters, dtype=np.float32))

    def propose(self, pedestrians_m: np.ndarray, velocities_m_s: np.ndarray | None = None
                ) -> tuple[np.ndarray, np.ndarray]:
        """The ``n_uavs`` highest peaks of the utility map (metres), refined if configured, and the map."""
        return self.propose_batch([pedestrians_m], [velocities_m_s])[0]

    def propose_batch(self, pedestrians_m: list[np.ndarray], velocities_m_s: list[np.ndarray | None]
                      ) -> list[tuple[np.ndarray, np.ndarray]]:
        """:meth:`propose` for several crowds, their rasters in one forward pass of the network."""
        rasters = np.stack([crowd_raster(peds, self.task.config, vels)
                            for peds, vels in zip(pedestrians_m, velocities_m_s, strict=True)])
        maps = self.utility_maps(rasters)  # (B, h, w)
        out = []
        for peds, raster, utility in zip(pedestrians_m, rasters, maps, strict=True):
            peaks_px = find_peaks(utility, self.peak_config, max_peaks=self.n_uavs,
                                  min_separation_px=self.min_separation_px)
            if self._check is not None:
                peaks_px = self._check(raster, peaks_px)
            peaks_m = self.task.to_metres(peaks_px)
            if self.config.refine and self.task.config.radio.propagation == "802.11":
                peaks_m = self.task.refine_80211(peds, peaks_m, self.n_uavs)
            elif self.config.refine:
                task = self.task
                peaks_m = refine_placement(peds, peaks_m, task.rules, task.width_m, task.height_m,
                                           self.refinement)
            out.append((peaks_m, utility))
        return out


def make_planner(kind: str, n_uavs: int = MAX_UAVS, task_config: WifiConfig | None = None, *,
                 checkpoint: str | Path | None = None, config: PlannerConfig | None = None,
                 uav_config: UAVConfig | None = None) -> Planner:
    """Build a planner by name: :func:`make_planners` of one kind.

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
    return make_planners((kind,), n_uavs, task_config, checkpoint=checkpoint, config=config,
                         uav_config=uav_config)[kind]


def make_planners(kinds: Sequence[str], n_uavs: int = MAX_UAVS, task_config: WifiConfig | None = None, *,
                  checkpoint: str | Path | None = None, config: PlannerConfig | None = None,
                  uav_config: UAVConfig | None = None) -> dict[str, Planner]:
    """Build planners by name in one trip: one task, built once, shared by all (the flown and the compared).

    The learned planner (when asked for) loads and checks its checkpoint, builds the task for its raster
    (:func:`~uav_swarm.missions.wifi.task.planner_task`), its refinement, rule check and engine; the
    expert then plans for that same task (the raster's velocity channels are the network's, which the
    expert does not read). The arguments are :func:`make_planner`'s.

    Examples:
        >>> planners = make_planners(["expert"], n_uavs=3)
        >>> list(planners), planners["expert"].task.rules.max_uavs
        (['expert'], 3)

    Raises:
        ConfigError: An unknown kind or ``n_uavs`` out of range (checked before anything is loaded).
        learning.checkpoint.CheckpointError: See :class:`LearnedPlanner`.
    """
    for kind in kinds:
        if kind not in PLANNER_KINDS:
            raise ConfigError(f"planner = {kind!r} is not allowed: choose one of {list(PLANNER_KINDS)}")
    check_n_uavs(n_uavs)
    planners: dict[str, Planner] = {}
    task = None
    if "learned" in kinds:
        learned = LearnedPlanner(n_uavs, task_config, checkpoint, config, uav_config)
        planners["learned"], task = learned, learned.task
    if "expert" in kinds:
        planners["expert"] = ExpertPlanner(n_uavs, task_config, config, uav_config, task=task)
    return {kind: planners[kind] for kind in kinds}
