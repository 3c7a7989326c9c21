"""Closed-loop flight: the placement planner flies real or SITL autopilots over the simulated crowd.

:func:`fly` runs the crowd world in real time (or ``speedup`` times faster) and, every
``replan_every_s`` of crowd time, plans from the vehicles' **measured** positions
(GLOBAL_POSITION_INT in the East-North-Up frame of the bridge config's home) and sends each
live vehicle its new target while it flies: ``MAV_CMD_DO_REPOSITION`` in guided mode, or a new
mission flown in AUTO (``mode = "mission"``).

The sequence is the real one (:mod:`bridge.flight.guided`): every vehicle's heartbeat, its position fix
and its home (each vehicle on its own), the guided mode, arming, take-off to ``uav.alt_m`` above
its home; then the loop; at the end (``duration_s`` reached, or :meth:`Flight.stop` from Ctrl-C or
SIGTERM) every vehicle is sent RTL or LAND (``flight.end_action``) and the outputs are written.

Faults in flight: a vehicle silent for ``flight.link_timeout_s`` is marked lost (its liveliness
token withdrawn, a warning naming it) and the planner replans with the others; when its
heartbeat returns it is launched again (only switched back to guided mode if still airborne) and
rejoins the plan. A refused or unanswered command is retried by the command protocol, then
reported by name; a target outside the geofence is never sent.

Telemetry (Zenoh, loopback by default): each vehicle's state on ``uav_swarm/<swarm>/uav/<id>/state``
(``source = "vehicle"``) as each GLOBAL_POSITION_INT arrives, with its accepted target; the plans on
``/plan``; the QoS of the measured positions over the simulated crowd on ``/qos``.

The loop itself is :class:`uav_swarm.runs.flight.loop.Flight`. Outputs in ``out_dir``: ``qos.png``
(QoS over time with the static reference), ``timeseries.csv`` (QoS over time), ``track.png`` (the
flight from above: paths, homes, last targets, the crowd), ``track.csv`` (each vehicle's measured track
and target, and its channel under the 802.11 radio) and ``summary.json`` (events, failures, QoS, the config);
with ``record``, an MCAP file of the flight at crowd time, and with ``live``, the same messages streamed
to Foxglove as they happen (:mod:`uav_swarm.runs.outputs.recording`).
"""

from __future__ import annotations

import json
import threading
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from bridge.errors import BridgeError
from bridge.flight.preflight import PreflightError
from uav_swarm.planning.planner import make_planner
from uav_swarm.runs.flight.loop import Flight
from uav_swarm.runs.fly_config import FlyConfig
from uav_swarm.runs.outputs.fanout import RunOutputs
from uav_swarm.runs.outputs.records import QosTrace
from uav_swarm.runs.service import StaticReference
from uav_swarm.runs.summary import planner_names, summarise_flight

if TYPE_CHECKING:
    from bridge.config import BridgeConfig
    from uav_swarm.planning.base import Planner
    from uav_swarm.runs.outputs.live_view import LiveView

__all__ = ["FlightResult", "fly", "load_flight_bridge"]


@dataclass
class FlightResult:
    """What :func:`fly` did: the summary written to ``summary.json`` and the files."""

    summary: dict[str, Any]
    files: list[Path] = field(default_factory=list)


def load_flight_bridge(config: FlyConfig) -> BridgeConfig:
    """The bridge config, checked for the flight: vehicles listed, the area inside the fence at ``uav.alt_m``.

    Raises:
        ConfigError: Unreadable or invalid bridge config, no vehicles, or fewer than ``n_uavs``; a
            minimum separation the fleet cannot keep in the area; return layers above the fence.
        GeofenceError: The area at the cruise altitude is not inside the geofence.
    """
    from bridge.config import BridgeConfig
    from bridge.geofence import check_geofence
    from typed_config import ConfigError, load_toml
    from uav_swarm.runs.flight.launch_plan import return_altitudes_m
    from uav_swarm.world.separation import check_fleet_fits

    bridge = load_toml(BridgeConfig, config.bridge_config)
    if bridge.home_source != "config":
        raise ConfigError(f"{config.bridge_config}: home_source = {bridge.home_source!r}: fly plans every "
                          "vehicle in one frame, around [home]; give the vehicles' common home there")
    if not bridge.vehicles:
        raise ConfigError(f"{config.bridge_config}: no [[vehicles]]: fly needs at least one vehicle")
    if config.n_uavs > len(bridge.vehicles):
        raise ConfigError(f"{config.bridge_config}: {len(bridge.vehicles)} vehicles for "
                          f"n_uavs = {config.n_uavs}")
    width_m, height_m, alt_m = config.task.scenario.width_m, config.task.scenario.height_m, config.uav.alt_m
    corners = [(0.0, 0.0), (width_m, 0.0), (0.0, height_m), (width_m, height_m)]
    check_geofence([(x, y, alt_m) for x, y in corners], bridge.geofence,
                   labels=[f"the crowd area's corner ({x:g}, {y:g}) at uav.alt_m" for x, y in corners])
    n = config.n_uavs or len(bridge.vehicles)
    check_fleet_fits(n, config.uav.min_separation_m, width_m, height_m)
    top_m = float(return_altitudes_m(n, config.uav, config.guard.margin_m).max())
    if top_m > bridge.geofence.alt_max_m:
        raise ConfigError(f"{config.bridge_config}: geofence.alt_max_m = {bridge.geofence.alt_max_m:g} m is "
                          f"below the highest return layer, {top_m:g} m (uav.alt_m + layers of "
                          f"max(uav.min_separation_m + guard.margin_m, uav.layer_step_m) for {n} vehicles): "
                          "raise it, or lower uav.alt_m or the separation")
    return bridge


def _write_track(track: list[dict[str, Any]], path: Path) -> Path:
    from typed_config.files import write_bytes_atomic

    columns = ["time_s", "uav_id", "system_id", "status", "x_m", "y_m", "z_m", "target_x_m", "target_y_m",
               "target_z_m", "wifi_channel"]  # the channel: 802.11 radio only (empty otherwise)

    def text(value: Any) -> str:
        return "" if value is None else f"{value:.3f}" if isinstance(value, float) else str(value)

    lines = [",".join(columns)] + [",".join(text(row[c]) for c in columns) for row in track]
    write_bytes_atomic(path, ("\n".join(lines) + "\n").encode())
    return path


def _stop_when_set(stop_event: threading.Event, flight: Flight) -> None:
    """End ``flight`` once ``stop_event`` is set (the watcher thread of :func:`fly`)."""
    stop_event.wait()
    flight.stop()


def fly(config: FlyConfig, out_dir: str | Path, *, stop_event: threading.Event | None = None,
        record: str | Path | None = None, live: LiveView | None = None,
        planner: Planner | None = None, keep_bridge_config: bool = False) -> FlightResult:
    """Fly the vehicles of ``config.bridge_config`` under the planner and write the outputs.

    Args:
        config: The flight's settings.
        out_dir: Output folder.
        stop_event: Set it (e.g. from a signal handler) to end the flight early; it still ends safely.
        record: Also record the flight into this MCAP file (plans; every ``record_every_s`` the
            scene, the vehicles' measured states and the QoS).
        live: Also stream the flight to Foxglove from a WebSocket server listening here.
        planner: Fly this planner (any :class:`uav_swarm.planning.base.Planner` for the flight's number
            of vehicles) instead of the config's.
        keep_bridge_config: Also copy the bridge config into ``out_dir`` as ``bridge.toml``, which the
            summary then names (one made for this flight only, in a folder removed after it).

    Raises:
        typed_config.ConfigError: Invalid bridge config, no vehicles, ``record`` not a .mcap file, or the
            live view cannot listen on ``live``.
        bridge.errors.GeofenceError: The area at the cruise altitude is outside the geofence.
        learning.checkpoint.CheckpointError: The learned planner's checkpoint is missing or does not fit.
        bridge.telemetry.config.TelemetryConnectionError: The Zenoh session could not be opened.
        bridge.flight.preflight.PreflightError: Take-off positions closer than the minimum, or a vehicle
            without a link-loss failsafe (and no ``set_failsafe``): refused before any vehicle was armed,
            nothing written.
        bridge.errors.BridgeError: No vehicle could be launched: nothing written when none flew at all
            (no track), else the outputs of what flew.
    """
    from bridge.flight.fleet import Fleet
    from bridge.telemetry import SwarmPublisher
    from typed_config.files import write_bytes_atomic
    from uav_swarm.runs.outputs.plots import write_qos_figure
    from uav_swarm.runs.outputs.recording import SceneInfo, check_recording_path, open_recorder
    from uav_swarm.runs.outputs.ros2 import check_ros2, open_run_node

    out_dir = Path(out_dir)
    if config.ros2.enabled:
        check_ros2()  # before the network loads and any vehicle is contacted
    bridge = load_flight_bridge(config)
    record = None if record is None else check_recording_path(record)
    scene = SceneInfo(width_m=config.task.scenario.width_m, height_m=config.task.scenario.height_m,
                      coverage_radius_m=config.task.radio.coverage_radius_m, home=bridge.home)
    n = config.n_uavs or len(bridge.vehicles)
    if planner is None:
        planner = make_planner(config.planner, n, config.task, checkpoint=config.checkpoint or None,
                               config=config.planning, uav_config=config.uav)
    summary: dict[str, Any] = {"config": config.to_dict(), "mode": config.mode, **planner_names(planner)}
    trace: QosTrace | None = None
    track: list[dict[str, Any]] = []
    error: BaseException | None = None
    with ExitStack() as stack:
        publisher = ros = steering = None
        if config.publish_telemetry:
            publisher = stack.enter_context(SwarmPublisher(config.telemetry, home=bridge.home))
        if config.ros2.enabled:
            ros, steering = open_run_node(config.ros2, stack, swarm=config.telemetry.swarm, n_uavs=n,
                                          command="fly", sim_time=False, task=config.task, uav=config.uav,
                                          geofence=bridge.geofence)
        with (open_recorder(scene, record=record, live=live, command="fly",  # its port before any link
                            config=config.to_dict()) as recorder,
              Fleet(bridge) as fleet):
            outputs = RunOutputs(publisher, recorder, ros, states_on_arrival=True)
            flight = Flight(config, bridge, fleet, outputs, planner, steering)
            watcher = None
            if stop_event is not None:
                watcher = threading.Thread(target=_stop_when_set, args=(stop_event, flight), daemon=True)
                watcher.start()
            try:
                trace, track = flight.run()
            except PreflightError:
                raise  # refused before any vehicle was armed: nothing written
            except BridgeError as exc:
                error = exc
            summary |= flight.summary()
    if error is not None and not track:
        raise error  # nothing flew: nothing to write
    out_dir.mkdir(parents=True, exist_ok=True)
    files: list[Path] = []
    if trace is not None and trace.times_s.size:
        from uav_swarm.runs.outputs.plots import write_timeseries

        summary |= summarise_flight(trace, config, n, flight.plans, track, flight.crowd_samples)
        reference = summary["static_reference"]
        drawn = StaticReference(np.asarray(reference["times_s"]), np.asarray(reference["qos"]),
                                tuple(reference["experts"]), reference["every_s"])
        files += [write_qos_figure({"flown": trace}, out_dir / "qos.png", drawn, config.task.strategy),
                  write_timeseries({"flown": trace}, out_dir / "timeseries.csv")]
    files.append(_write_track(track, out_dir / "track.csv"))
    if track:
        from uav_swarm.runs.outputs.plots import write_track_figure

        crowd = flight.crowd_samples[-1][1] if flight.crowd_samples else None
        area_m = (config.task.scenario.width_m, config.task.scenario.height_m)
        files.append(write_track_figure(track, crowd, area_m, out_dir / "track.png"))
    if keep_bridge_config:
        write_bytes_atomic(out_dir / "bridge.toml", Path(config.bridge_config).read_bytes())
        files.append(out_dir / "bridge.toml")
        summary["config"]["bridge_config"] = "bridge.toml"  # beside summary.json
    if error is not None:
        summary["error"] = f"{type(error).__name__}: {error}"
    summary["files"] = [p.name for p in files] + ["summary.json"]
    if record is not None:
        summary["recording"] = str(record)
    text = json.dumps(summary, indent=1, sort_keys=True) + "\n"
    write_bytes_atomic(out_dir / "summary.json", text.encode())
    files.append(out_dir / "summary.json")
    if error is not None:
        raise error
    return FlightResult(summary, files)
