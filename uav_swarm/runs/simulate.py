"""The main job: fly the planner over a dynamic crowd sequence and compare it with the expert.

:func:`simulate` runs ``uav_swarm_v0`` in waypoint mode for ``duration_s`` of simulated time,
replanning every ``replan_every`` steps with the configured planner (:mod:`uav_swarm.planning.planner`),
and records per step the QoS of both strategies and the mean user throughput, and per replan the
planning latency. One untimed replan before the first step compiles and loads what the planner needs
(numba kernels, the network's first call), so the latencies are those of a warm planner. The same
sequence is then flown with the expert planner: the environment is reset
with the same seed, and the crowd does not react to the UAVs, so both planners face the same crowd.

While the flown planner runs, UAV states, plans and QoS are published over Zenoh
(:class:`bridge.telemetry.SwarmPublisher`, loopback only, multicast scouting off). Positions are
East-North-Up metres from the home, which is the area's South-West corner ``(0, 0)``, at the
simulated flight altitude ``uav.alt_m``.

Outputs in ``out_dir`` (:mod:`uav_swarm.runs.outputs.plots` draws the pictures):

- ``qos.png``: QoS S1 and S2 and mean user throughput over time, both planners on one figure (802.11: the
  users' median SINR and MCS shares, and each UAV's channel, of the flown planner);
- ``scene.gif``: the flown planner's run (UAVs, coverage discs, pedestrians; utility map panel);
- ``summary.json`` (atomic): per planner mean/min QoS S1 and S2, mean throughput, median/p95
  planning latency; learned/expert ratios; the resolved config; the learned planner's checkpoint
  (``checkpoint``), its peak settings and their source (``peaks``); the expert that ran (``expert``);
  which radio ran (``radio``) and, under the 802.11 radio, each planner's channels, SINR/MCS shares,
  airtime and co-channel sharing (``wifi_80211``, :mod:`uav_swarm.runs.outputs.radio_report`);
- ``timeseries.csv``: the per-step values of every run (802.11: median SINR, MCS shares, channels, airtime);
- ``missions/vehicle_<id>.plan``: each UAV's mission to its final target (QGroundControl files);
  with a bridge config that lists vehicles, the missions are also uploaded
  (:class:`bridge.flight.fleet.Fleet`).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from tqdm.auto import tqdm

from uav_swarm.env.parallel import parallel_env
from uav_swarm.planning.planner import LearnedPlanner, Planner, make_planners
from uav_swarm.runs.outputs.fanout import RunOutputs
from uav_swarm.runs.outputs.radio_report import RadioLog, radio_line, telemetry_fields
from uav_swarm.runs.outputs.records import Frame, SequenceRun
from uav_swarm.runs.separation_watch import SeparationWatch
from uav_swarm.runs.service import static_reference, target_jumps
from uav_swarm.runs.simulate_config import SimulateConfig
from uav_swarm.runs.simulate_missions import final_plans, load_bridge, upload_plans, write_plan_files
from uav_swarm.runs.summary import (
    planner_names,
    ratios_learned_over_expert,
    reference_record,
    summarise_run,
)
from uav_swarm.world.comms import evaluate_coverage
from uav_swarm.world.wifi.channels import plan_channels

if TYPE_CHECKING:
    from bridge.telemetry.schema import Plan, Qos, UavState
    from uav_swarm.runs.outputs.live_view import LiveView
    from uav_swarm.runs.steering import OperatorTargets

__all__ = ["SimulationResult", "run_sequence", "sequence_crowds", "simulate"]

logger = logging.getLogger(__name__)


@dataclass
class SimulationResult:
    """The runs of :func:`simulate`, its summary and the files written."""

    runs: dict[str, SequenceRun]
    summary: dict[str, Any]
    files: list[Path]


def _telemetry(env: Any, targets_m: np.ndarray, altitudes_m: np.ndarray, step: int,
               guard: tuple[np.ndarray, np.ndarray], radio_log: RadioLog | None
               ) -> tuple[list[UavState], Qos]:
    """The UAVs' states and the QoS after ``step``, as telemetry publishes and a recording keeps them.

    ``guard``: each UAV's distance to its nearest other UAV and whether it is held (SeparationWatch.observe).
    Under the 802.11 radio, each UAV's channel, airtime and stations and the users' median SINR too.
    """
    from bridge.telemetry.schema import Qos, UavState

    stamp_s = time.time()
    positions, velocities = env.uav_positions_m, env.uav_velocities_m_s
    nearest, held = guard
    cov = env.coverage
    wifi_uavs, wifi_qos = telemetry_fields(cov, None if radio_log is None else radio_log.latest_pairs)
    states = [UavState(
        stamp_s=stamp_s, seq=step, source="sim", uav_id=uav_id,
        position_enu_m=(float(positions[uav_id, 0]), float(positions[uav_id, 1]), float(altitudes_m[uav_id])),
        velocity_enu_m_s=(float(velocities[uav_id, 0]), float(velocities[uav_id, 1]), 0.0),
        target_enu_m=(float(targets_m[uav_id, 0]), float(targets_m[uav_id, 1]), float(altitudes_m[uav_id])),
        separation_held=bool(held[uav_id]),
        nearest_uav_m=float(nearest[uav_id]) if np.isfinite(nearest[uav_id]) else None, **wifi_uavs[uav_id])
        for uav_id in range(len(positions))]
    qos = Qos(stamp_s=stamp_s, seq=step, source="sim", qos_s1=float(cov.qos_s1), qos_s2=float(cov.qos_s2),
              mean_throughput_mbps=float(cov.mean_throughput_mbps), n_users=int(cov.covered.shape[0]),
              **wifi_qos)
    return states, qos


def _plan(planner: Planner, targets_m: np.ndarray, alt_m: float, latency_ms: float, seq: int) -> Plan:
    from bridge.telemetry.schema import Plan, PlanTarget

    targets = tuple(PlanTarget(uav_id=i, target_enu_m=(float(x), float(y), alt_m))
                    for i, (x, y) in enumerate(targets_m))
    return Plan(stamp_s=time.time(), seq=seq, source="sim", targets=targets, planner=planner.name,
                latency_ms=float(latency_ms))


def run_sequence(config: SimulateConfig, planner: Planner, kind: str, *, outputs: RunOutputs | None = None,
                 steering: OperatorTargets | None = None, frame_every: int = 0, sample_every_s: float = 0.0,
                 progress: bool = False) -> SequenceRun:
    """Fly one planner over the sequence of ``config`` (same seed, same crowd, for every planner).

    Args:
        config: The sequence (seed, duration, UAVs, replanning period, world).
        planner: The planner, for ``config.n_uavs`` UAVs.
        kind: Its label in the results (``"learned"`` or ``"expert"``).
        outputs: The run's sinks (Zenoh, Foxglove, ROS 2): states and QoS every ``config.telemetry_every``
            steps, every plan, the scene, at simulated time (:mod:`uav_swarm.runs.outputs.fanout`).
        steering: Operator targets that replace the planner's for the UAVs they name, from the next step.
        frame_every: Keep a :class:`Frame` every this many steps (and the last); 0 keeps none.
        sample_every_s: Keep the crowd every this many simulated seconds from 0 (the static reference's
            instants); 0 keeps none.
        progress: Show a progress bar (on a terminal only: none in a log or a pipe).

    Raises:
        ValueError: The planner is for another number of UAVs.
    """
    if planner.n_uavs != config.n_uavs:
        raise ValueError(f"the planner is for {planner.n_uavs} UAVs, the sequence has {config.n_uavs}")
    env = parallel_env(config=config.env_config())
    env.reset(seed=config.seed)
    # One untimed replan first: compilation (numba) and first calls (the network) land here, not in the
    # latencies; the planner then forgets it (planning draws no random numbers, the sequence is unchanged).
    planner.plan(env.pedestrian_positions_m, env.uav_positions_m, env.pedestrian_velocities_m_s)
    planner.reset()
    outputs = outputs or RunOutputs()
    outputs.static_scene(env.scenario.obstacles)
    agents = list(env.possible_agents)
    steps, alt_m = config.n_steps, float(config.uav.alt_m)
    qos_s1, qos_s2, rate = (np.zeros(steps) for _ in range(3))
    admission = env.radio.max_stations is not None and env.radio.propagation == "paper"
    radio_log = RadioLog(env.radio, env.uav_altitudes_m) if env.radio.propagation == "802.11" else None
    paper_radio = env.radio.replace(station_limit="off")
    qos_s2_paper = np.zeros(steps if admission else 0)
    latencies: list[float] = []
    changes: list[int] = []
    frames: list[Frame] = []
    targets = np.asarray(env.uav_positions_m).copy()
    channels: np.ndarray | None = None
    serving: np.ndarray | None = None  # 802.11: the UAVs whose access point is on (the plan's)
    plans: list[np.ndarray] = []
    samples: list[tuple[float, np.ndarray, np.ndarray]] = []
    sample_every = max(1, round(sample_every_s / env.dt_s)) if sample_every_s else 0
    distance_m = 0.0
    result = None
    area_m = (config.task.scenario.width_m, config.task.scenario.height_m)
    watch = SeparationWatch(config.uav, config.n_uavs, area_m, step_s=env.dt_s)  # transitions, closest pair
    steered = 0  # the operator targets' version the transition was planned for
    done, interrupted_at_s = 0, None
    try:
        for step in tqdm(range(steps), desc=f"{kind} planner", unit="step",
                         disable=None if progress else True, leave=False):
            if step % config.replan_every == 0:
                result = planner.plan(env.pedestrian_positions_m, env.uav_positions_m,
                                      env.pedestrian_velocities_m_s)
                if latencies:
                    moved = np.linalg.norm(result.targets_m - targets, axis=1) > config.planning.min_gap_m
                    changes.append(int(np.count_nonzero(moved)))
                targets = result.targets_m
                if env.radio.propagation == "802.11":  # a channel per UAV for where it flies, few changes;
                    # under admission on rate a UAV the plan gives no users keeps its AP off (it would take
                    # airtime from the placed APs); under strategy 1 every AP in the air serves
                    serving = result.serving if env.radio.ieee80211.admits_on_rate else None
                    channels = plan_channels(targets, env.radio, env.uav_altitudes_m, channels, serving)
                    env.set_channel_plan(channels)
                    env.set_access_points(serving)
                plans.append(targets.copy())
                latencies.append(result.latency_ms)
                if steering is not None:
                    steering.planned(dict(enumerate(map(tuple, targets))))
                if outputs.active:
                    plan = _plan(planner, _steered(targets, steering), alt_m, result.latency_ms,
                                 len(latencies) - 1)
                    outputs.plan(step * env.dt_s, plan)
            if step % config.replan_every == 0 or (steering is not None and steering.version != steered):
                # an operator's change: a transition
                steered = steering.version if steering is not None else 0
                flown = _steered(targets, steering)
                watch.replan(step * env.dt_s, env.uav_positions_m, env.uav_velocities_m_s, flown)
            if sample_every and step % sample_every == 0:  # the crowd walks the same whatever the UAVs do
                samples.append((step * env.dt_s, np.array(env.pedestrian_positions_m),
                                np.array(env.pedestrian_velocities_m_s)))
            before = np.array(env.uav_positions_m)
            infos = env.step(dict(zip(agents, watch.commands(step * env.dt_s), strict=True)))[-1]
            guard = watch.observe((step + 1) * env.dt_s, env.uav_positions_m, infos)
            distance_m += float(np.linalg.norm(np.asarray(env.uav_positions_m) - before, axis=1).sum())
            cov = env.coverage
            qos_s1[step], qos_s2[step], rate[step] = cov.qos_s1, cov.qos_s2, cov.mean_throughput_mbps
            if admission:  # the same flight judged with the paper's radio, for the paper's table and qos.png
                qos_s2_paper[step] = evaluate_coverage(env.pedestrian_positions_m, env.uav_positions_m,
                                                       paper_radio).qos_s2
            if radio_log is not None:  # channels, SINR/MCS, airtime, co-channel sharing (runs.radio_report)
                radio_log.observe(cov, env.uav_positions_m, serving)
            if outputs.active and step % config.telemetry_every == 0:
                states, qos = _telemetry(env, flown, watch.altitudes_m, step, guard, radio_log)
                outputs.step((step + 1) * env.dt_s, states, qos, env.pedestrian_positions_m, cov.covered,
                             association=cov.association, throughput_mbps=cov.throughput_mbps)
            if frame_every and (step % frame_every == 0 or step == steps - 1):
                assert result is not None  # planned at step 0 (every replan_every steps from it)
                frames.append(Frame(
                    time_s=(step + 1) * env.dt_s, covered=cov.covered.copy(),
                    pedestrians_m=np.array(env.pedestrian_positions_m, np.float32),
                    uavs_m=np.array(env.uav_positions_m), targets_m=np.array(flown),
                    peaks_m=result.peaks_m.copy(), utility=result.utility, qos_s1=float(cov.qos_s1),
                    qos_s2=float(cov.qos_s2),
                    association=None if radio_log is None else np.array(cov.association),
                    channels=None if radio_log is None or cov.channel is None else np.array(cov.channel)))
            done = step + 1  # every figure of this step recorded
    except KeyboardInterrupt:  # Ctrl-C: keep the steps finished (the caller says the run was cut short)
        if done == 0:
            raise
        steps, interrupted_at_s = done, done * env.dt_s
        qos_s1, qos_s2, rate = qos_s1[:done], qos_s2[:done], rate[:done]
        qos_s2_paper = qos_s2_paper[:done] if admission else qos_s2_paper
    return SequenceRun(
        planner=kind, planner_name=planner.name, times_s=np.arange(1, steps + 1) * env.dt_s, qos_s1=qos_s1,
        qos_s2=qos_s2, throughput_mbps=rate, latency_ms=np.asarray(latencies),
        target_changes=np.asarray(changes, dtype=np.int64), final_targets_m=np.array(flown),
        final_pedestrians_m=np.array(env.pedestrian_positions_m), n_pedestrians=int(cov.covered.shape[0]),
        obstacles_m=np.array(env.scenario.obstacles, dtype=np.float64).reshape(-1, 4), frames=frames,
        target_jumps=target_jumps(np.array(plans)), distance_m=distance_m, qos_s2_paper=qos_s2_paper,
        association=cov.model, separation=watch.summary(), uav_tracks_m=watch.tracks_m,
        crowd_samples=samples, radio=None if radio_log is None else radio_log.trace(),
        interrupted_at_s=interrupted_at_s)


def _steered(targets_m: np.ndarray, steering: OperatorTargets | None) -> np.ndarray:
    """The planner's targets with the operator's in place for the UAVs it holds."""
    return targets_m if steering is None else steering.apply_array(targets_m)


def sequence_crowds(config: SimulateConfig, every_s: float
                    ) -> Iterator[tuple[float, np.ndarray, np.ndarray]]:
    """``(time_s, positions, velocities)`` of the sequence's crowd every ``every_s`` seconds from 0.

    The crowd walks the same whatever the UAVs do: here they hold their start positions.
    """
    env = parallel_env(config=config.env_config())
    env.reset(seed=config.seed)
    hold = dict(zip(env.possible_agents, np.array(env.uav_positions_m), strict=True))
    every = max(1, int(round(every_s / env.dt_s)))
    for step in range(config.n_steps):
        if step % every == 0:
            yield (step * env.dt_s, np.array(env.pedestrian_positions_m),
                   np.array(env.pedestrian_velocities_m_s))
        env.step(hold)


def simulate(config: SimulateConfig, out_dir: str | Path, *, progress: bool = True,
             record: str | Path | None = None, live: LiveView | None = None) -> SimulationResult:
    """Run the main job and write its outputs (see the module docstring).

    Everything that can fail on bad input (planner kind, checkpoint, bridge config, telemetry
    session, recording path, live view address) is checked before the first step.

    Args:
        config: The sequence, the planners and the outputs.
        out_dir: Output folder.
        progress: Show a progress bar (on a terminal only: none in a log or a pipe).
        record: Also record the flown planner's run into this MCAP file
            (:mod:`uav_swarm.runs.outputs.recording`, every ``telemetry_every`` steps and every plan).
        live: Also stream the flown planner's run to Foxglove from a WebSocket server listening here.

    Raises:
        typed_config.ConfigError: Invalid bridge config, too few vehicles, ``record`` not a .mcap file,
            or the live view cannot listen on ``live``.
        bridge.errors.GeofenceError: The area at the flight altitude is not inside the bridge's geofence.
        learning.checkpoint.CheckpointError: The learned planner's checkpoint is missing or does not fit.
        bridge.telemetry.config.TelemetryConnectionError: The Zenoh session could not be opened, e.g. a
            listen endpoint is in use (nothing is written).
        bridge.errors.BridgeError: Uploading to the configured vehicles failed (outputs are written).
    """
    from bridge.errors import BridgeError
    from bridge.telemetry import SwarmPublisher
    from typed_config.files import write_bytes_atomic
    from uav_swarm.runs.outputs.plots import write_qos_figure, write_scene_gif, write_timeseries
    from uav_swarm.runs.outputs.recording import SceneInfo, check_recording_path, open_recorder
    from uav_swarm.runs.outputs.ros2 import check_ros2, open_run_node

    out_dir = Path(out_dir)
    if config.ros2.enabled:
        check_ros2()  # before the network loads and the engines are timed
    bridge = load_bridge(config)
    record = None if record is None else check_recording_path(record)
    kinds = [config.planner] + (["expert"] if config.compare_expert and config.planner != "expert" else [])
    planners = make_planners(kinds, config.n_uavs, config.task, checkpoint=config.checkpoint or None,
                             config=config.planning, uav_config=config.uav)
    frame_every = -(-config.n_steps // (config.gif_max_frames - 1)) if config.gif else 0
    runs: dict[str, SequenceRun] = {}
    interrupted: dict[str, Any] | None = None
    scene = SceneInfo(width_m=config.task.scenario.width_m, height_m=config.task.scenario.height_m,
                      coverage_radius_m=config.task.radio.coverage_radius_m, home=bridge.home,
                      min_separation_m=config.uav.min_separation_m)
    with ExitStack() as stack:
        publisher = ros = steering = None
        if config.publish_telemetry:
            publisher = stack.enter_context(SwarmPublisher(config.telemetry, home=bridge.home))
        if config.ros2.enabled:
            ros, steering = open_run_node(config.ros2, stack, swarm=config.telemetry.swarm,
                                          n_uavs=config.n_uavs, command="simulate", sim_time=True,
                                          task=config.task, uav=config.uav, geofence=bridge.geofence)
        if publisher is not None and config.wait_for_subscriber_s > 0:
            if not publisher.wait_for_subscriber(config.wait_for_subscriber_s):
                logger.warning("no telemetry subscriber after %.1f s: flying anyway",
                               config.wait_for_subscriber_s)
        for kind, planner in planners.items():
            is_flown = kind == config.planner
            with open_recorder(scene, record=record if is_flown else None, live=live if is_flown else None,
                               command="simulate", config=config.to_dict()) as recorder:
                outputs = RunOutputs(publisher, recorder, ros) if is_flown else None
                sample_every_s = config.static_every_s if is_flown and config.static_reference else 0.0
                try:
                    runs[kind] = run_sequence(config, planner, kind, outputs=outputs,
                                              steering=steering if is_flown else None,
                                              frame_every=frame_every if is_flown else 0,
                                              sample_every_s=sample_every_s, progress=progress)
                except KeyboardInterrupt:
                    if is_flown:  # not one step flown: nothing to keep
                        raise
                    interrupted = {"planner": kind, "at_s": 0.0, "kept": "the flown planner's whole run"}
                    break
            cut = runs[kind].interrupted_at_s
            if cut is not None:  # Ctrl-C: the comparison is not flown, or not kept when cut short
                interrupted = {"planner": kind, "at_s": cut, "kept": (
                    f"the flown planner's first {cut:g} s" if is_flown else "the flown planner's whole run")}
                if not is_flown:
                    del runs[kind]
                break
    reference = (static_reference(runs[config.planner].crowd_samples, config.task, config.n_uavs,
                                  config.static_every_s, config.uav.altitudes_m(config.n_uavs))
                 if config.static_reference else None)

    out_dir.mkdir(parents=True, exist_ok=True)
    summary: dict[str, Any] = {"planners": {kind: summarise_run(run, config, reference)
                                            for kind, run in runs.items()},
                               "flown": config.planner,
                               "duration_s": len(runs[config.planner].times_s) * config.dt_s,
                               "n_uavs": config.n_uavs, "seed": config.seed, "config": config.to_dict(),
                               "radio": radio_line(config.task.radio)}
    if interrupted is not None:
        summary["interrupted"] = interrupted
    if reference is not None:
        summary["static_reference"] = reference_record(reference, config.task.strategy)
    if "learned" in runs and "expert" in runs:
        summary["ratios_learned_over_expert"] = ratios_learned_over_expert(summary["planners"]["learned"],
                                                                           summary["planners"]["expert"])
    for planner in planners.values():
        summary |= planner_names(planner)  # the checkpoint and the expert that ran
    learned = planners.get("learned")
    if isinstance(learned, LearnedPlanner):  # make_planners' learned planner
        summary["network_precision"] = learned.precision
        summary["inference_engine"] = learned.engine
        summary["peaks"] = learned.peak_choice.to_dict()
        if config.planning.refine:
            summary["refinement"] = {  # which settings ran: [planning.refinement], else the strategy's own
                "source": "[planning.refinement]" if config.planning.refinement else "strategy defaults",
                "settings": learned.refinement.to_dict()}
    files = [write_qos_figure(runs, out_dir / "qos.png", reference, config.task.strategy),
             write_timeseries(runs, out_dir / "timeseries.csv")]
    flown = runs[config.planner]
    if config.gif and flown.frames:
        files.append(write_scene_gif(flown, config, out_dir / "scene.gif"))
    area_m = np.array([config.task.scenario.width_m, config.task.scenario.height_m])
    plans = final_plans(bridge, flown.final_targets_m, config.uav, area_m)
    files += write_plan_files(bridge, plans, out_dir / "missions")
    summary["files"] = [str(p.relative_to(out_dir)) for p in files] + ["summary.json"]
    if record is not None:
        summary["recording"] = str(record)
    summary["uploaded_to_vehicles"] = []
    try:
        if bridge.vehicles and interrupted is None:  # an interrupted run's last plan is not sent
            upload_plans(bridge, plans)
            summary["uploaded_to_vehicles"] = sorted(plans)
    except BridgeError as exc:
        summary["upload_error"] = str(exc)
        raise
    finally:
        write_bytes_atomic(out_dir / "summary.json", _json(summary).encode())
    files.append(out_dir / "summary.json")
    return SimulationResult(runs, summary, files)


def _json(data: Any) -> str:
    import json

    return json.dumps(data, indent=1, sort_keys=True) + "\n"
