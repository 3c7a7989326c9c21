"""Record a run (``--record FILE.mcap``) and show it live (``--live [HOST:]PORT``), through the Foxglove SDK.

The one place that turns a step of ``simulate`` or ``fly`` into messages. The loops call the
recorder once per recorded step and per plan; it logs each message on ``foxglove-sdk`` channels whose
sinks are an MCAP file and/or the SDK's WebSocket server, and never waits on a client (a slow client's
oldest queued messages are dropped by the server). Every message's log time is the **run time** of
what it shows, in nanoseconds from the start of the run: simulated seconds for ``simulate``, crowd
seconds for ``fly``; the wall clock time of the start is in the ``uav_swarm.run`` metadata record.
The channels (Foxglove's own types are protobuf; the project's are JSON):

- ``/scene`` (``foxglove.SceneUpdate``): at the start, the area's outline (entity ``area``) and the
  obstacles (``obstacles``); every recorded step, the UAVs (``uavs``), their coverage discs
  (``coverage``), their targets with a line from each UAV (``targets``) and, with a minimum separation
  (:attr:`SceneInfo.min_separation_m`), each UAV's separation circle (``separation``, radius half the
  minimum: red in a conflict, amber while held) and a red line between the UAVs of every pair closer
  than the minimum (``conflicts``);
- ``/pedestrians`` (``foxglove.PointCloud``): every recorded step, the crowd; field ``covered`` is 1
  for a user a UAV serves, else 0;
- ``/tf`` (``foxglove.FrameTransforms``): every recorded step, ``map`` -> ``uav_<id>``;
- ``/uav/<id>/state`` (``uav_swarm.UavState``, JSON): every recorded step, each UAV's telemetry state;
- ``/uav/<id>/location`` (``foxglove.LocationFix``): with it, when its WGS84 position is known;
- ``/plan`` (``uav_swarm.Plan``, JSON) and ``/plan/targets`` (``foxglove.PosesInFrame``): every plan;
- ``/qos`` (``uav_swarm.Qos``, JSON): every recorded step.

The ``uav_swarm.*`` channels carry exactly the JSON that telemetry publishes over Zenoh; their
schemas are generated from the payload types. The file is written beside its final path and
renamed when the run ends (:func:`typed_config.files.atomic_path`): a run that fails leaves no file.
The live view has its own SDK context, so that a client subscribing to ``/scene`` late gets the
static scene again at once without a second copy in the file. It gets at most
:attr:`~uav_swarm.runs.outputs.live_view.LiveView.max_rate_hz` recorded steps per wall-clock second, and a
message that no sink takes (no file, no client subscribed to its topic) is not even built.

Examples:
    >>> import tempfile
    >>> from mcap.reader import make_reader
    >>> from bridge.telemetry.schema import Qos
    >>> path = Path(tempfile.mkdtemp()) / "run.mcap"
    >>> scene = SceneInfo(width_m=100.0, height_m=80.0, coverage_radius_m=30.0)
    >>> with open_recorder(scene, record=path) as recorder:
    ...     recorder.qos(0.1, Qos(stamp_s=0.0, seq=0, source="sim", qos_s1=0.5, qos_s2=0.25,
    ...                           mean_throughput_mbps=3.0, n_users=4))
    >>> with path.open("rb") as f:
    ...     [(c.topic, m.log_time) for _, c, m in make_reader(f).iter_messages()]
    [('/qos', 100000000)]
"""

from __future__ import annotations

import json
import logging
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

import foxglove
import msgspec
import numpy as np
from foxglove.channels import (
    FrameTransformsChannel,
    LocationFixChannel,
    PointCloudChannel,
    PosesInFrameChannel,
    SceneUpdateChannel,
)
from foxglove.mcap import MCAPCompression, MCAPWriteOptions

from bridge.telemetry.schema import GeoPoint, Plan, Qos, UavState, encode_payload
from typed_config import ConfigError
from typed_config.files import atomic_path
from uav_swarm.runs.outputs import foxglove_scene as fox
from uav_swarm.runs.outputs.live_view import LiveListener, LiveView
from uav_swarm.runs.outputs.radio_report import uav_service

if TYPE_CHECKING:
    from bridge.geo import Home

__all__ = ["SceneInfo", "RunRecorder", "open_recorder", "check_recording_path", "RUN_METADATA",
           "LIVE_BACKLOG_MESSAGES", "LIVE_STOP_WAIT_S", "RUN_TOPICS"]

logger = logging.getLogger(__name__)

RUN_METADATA = "uav_swarm.run"
"""Name of the metadata record that describes the run (command, start time, config)."""

LIVE_BACKLOG_MESSAGES = 256
"""Messages queued per live client; past that the server drops the oldest: the client lags, the run not."""

LIVE_STOP_WAIT_S = 5.0
"""At the end, how long the live view's clients get to take what is queued for them."""

_SCENE = "/scene"
_PAYLOADS = {"uav_swarm.UavState": UavState, "uav_swarm.Plan": Plan, "uav_swarm.Qos": Qos}


@dataclass(frozen=True)
class SceneInfo:
    """What a recording needs to know of the run's world besides its messages.

    Attributes:
        width_m: East extent of the area (metres from the home).
        height_m: North extent of the area.
        coverage_radius_m: Radius of a UAV's coverage disc on the ground.
        home: The geodetic home of the local frame; ``None``: no WGS84 fixes for simulated states.
        min_separation_m: The minimum distance between two UAVs: each UAV's separation circle (radius
            half of it) and every pair closer than it are drawn; 0 draws none.
    """

    width_m: float
    height_m: float
    coverage_radius_m: float
    home: Home | None = None
    min_separation_m: float = 0.0


def _json_channel(name: str) -> Callable[[str, foxglove.Context], foxglove.Channel]:
    """A maker of JSON channels of the telemetry payload ``name`` (its JSON Schema from the payload type)."""
    data = json.dumps({"title": name, **msgspec.json.schema(_PAYLOADS[name])}, sort_keys=True).encode()
    schema = foxglove.Schema(name=name, encoding="jsonschema", data=data)
    return lambda topic, context: foxglove.Channel(topic, schema=schema, message_encoding="json",
                                                   context=context)


class RunRecorder:
    """Logs a run's messages to its sinks (see the module docstring for the channels).

    Use :func:`open_recorder`, which opens the sinks, and finishes and renames the file.

    Args:
        scene: The run's area and coverage radius.
        contexts: One SDK context per sink group: the file's and/or the live view's.
        live: The live view's context (one of ``contexts``), or None.
        view: The live view's settings: its pace (each step waits for the clock, never for a client)
            and its rate of steps.
    """

    def __init__(self, scene: SceneInfo, contexts: Sequence[foxglove.Context],
                 live: foxglove.Context | None = None, view: LiveView | None = None) -> None:
        self.scene = scene
        self._speed = None if view is None else view.speed
        self._start_wall_s: float | None = None
        self._stream_period_s = 1.0 / view.max_rate_hz if view is not None and view.max_rate_hz else 0.0
        self._next_stream_s = 0.0
        self._streaming = True  # whether what is logged now goes to the live view too
        self._contexts = list(contexts)
        self._live = None if live is None else self._contexts.index(live)
        self._channels: dict[str, list[Any]] = {}
        self._lock = threading.Lock()  # the live server's thread re-sends the static scene
        self._obstacles_m: np.ndarray | None = None
        self._now_s = 0.0
        self.counts: Counter[str] = Counter()
        """Messages logged, by topic."""

    # -- channels ------------------------------------------------------------------------------
    def _channel_list(self, topic: str, make: Callable[[str, foxglove.Context], Any]) -> list[Any]:
        with self._lock:
            if topic not in self._channels:
                self._channels[topic] = [make(topic, context) for context in self._contexts]
            return self._channels[topic]

    def _log(self, topic: str, make: Callable[[str, foxglove.Context], Any], time_s: float,
             build: Callable[[], Any]) -> None:
        """Log ``build()`` on ``topic`` at ``time_s``; built only if a sink takes it (a file always does)."""
        if time_s < 0:
            raise ValueError(f"{topic}: time_s = {time_s} is negative: run times start at 0")
        self._now_s = max(self._now_s, time_s)
        channels = self._takers(topic, make)
        if not channels:  # only a live view, and no client subscribes to the topic (or not this step)
            return
        message, ns = build(), round(time_s * 1e9)
        for channel in channels:
            channel.log(message, log_time=ns)
        self.counts[topic] += 1

    def _takers(self, topic: str, make: Callable[[str, foxglove.Context], Any]) -> list[Any]:
        """The channels of ``topic`` that take a message now: a sink takes it, the live view if streaming."""
        return [channel for i, channel in enumerate(self._channel_list(topic, make))
                if (self._streaming or i != self._live) and channel.has_sinks()]

    def _log_json(self, topic: str, schema: str, time_s: float, payload: Any) -> None:
        """Log a telemetry payload (``Plan``, ``Qos``, ``UavState``) as the JSON that Zenoh carries."""
        self._log(topic, _JSON_CHANNELS[schema], time_s, lambda: encode_payload(payload))

    # -- what a run records --------------------------------------------------------------------
    def static_scene(self, obstacles_m: np.ndarray, time_s: float = 0.0) -> None:
        """The area's outline and the obstacle segments ``(M, 4)`` (``x1, y1, x2, y2``), kept all run."""
        self._obstacles_m = np.asarray(obstacles_m, np.float64).reshape(-1, 4).copy()
        update = fox.static_scene(self.scene.width_m, self.scene.height_m, self._obstacles_m, time_s)
        self._log(_SCENE, _scene_channel, time_s, lambda: update)

    def advertise(self) -> None:
        """Create the channels every run has (scene, crowd, frames, plans, QoS) before their first message."""
        for topic, make in _RUN_CHANNELS.items():
            self._channel_list(topic, make)

    def resend_static_scene(self, topic: str = _SCENE) -> None:
        """Log the static scene again on the live view only (a client has just subscribed to ``topic``)."""
        if topic != _SCENE or self._live is None or self._obstacles_m is None:
            return
        now_s = self._now_s
        update = fox.static_scene(self.scene.width_m, self.scene.height_m, self._obstacles_m, now_s)
        self._channel_list(_SCENE, _scene_channel)[self._live].log(update, log_time=round(now_s * 1e9))

    def plan(self, time_s: float, plan: Plan) -> None:
        """A plan: its telemetry payload on ``/plan`` and its targets on ``/plan/targets``."""
        self._log_json("/plan", "uav_swarm.Plan", time_s, plan)
        self._log("/plan/targets", _RUN_CHANNELS["/plan/targets"], time_s,
                  lambda: fox.poses_in_frame(time_s, [t.target_enu_m for t in plan.targets]))

    def qos(self, time_s: float, qos: Qos) -> None:
        """The QoS at ``time_s`` on ``/qos``."""
        self._log_json("/qos", "uav_swarm.Qos", time_s, qos)

    def step(self, time_s: float, states: Sequence[UavState], qos: Qos, pedestrians_m: np.ndarray,
             covered: np.ndarray, *, association: np.ndarray | None = None) -> None:
        """One recorded step: each UAV's state (and fix), the frames, the scene, the crowd and the QoS.

        Args:
            time_s: Run time of the step.
            states: The state of each UAV flying now (one without a position fix is recorded on its
                ``/state`` channel only).
            qos: The QoS of those UAVs over the crowd.
            pedestrians_m: ``(N, 2)`` crowd positions.
            covered: ``(N,)`` True for a user a UAV serves.
            association: ``(N,)`` each user's UAV (-1: none). With the UAVs' channels in their states (the
                802.11 radio) the scene shows each UAV's channel, and with ``association`` the users it
                serves, instead of coverage discs.
        """
        self._keep_pace(time_s)
        self._streaming = self._stream_due()
        if not self._streaming and len(self._contexts) == 1:  # a live view only, and not this step
            self._streaming = True
            return
        try:
            self._log_step(time_s, states, qos, pedestrians_m, covered, association)
        finally:
            self._streaming = True

    def _keep_pace(self, time_s: float) -> None:
        if self._speed is None:
            return
        if self._start_wall_s is None:
            self._start_wall_s = time.monotonic() - time_s / self._speed
        time.sleep(max(0.0, self._start_wall_s + time_s / self._speed - time.monotonic()))

    def _fixes_from_home(self, positions_m: dict[int, fox.Vec3]) -> dict[int, tuple[float, float, float]]:
        """WGS84 positions of local ones around the scene's home (none without a home), in one call.

        The same numbers as :func:`bridge.geo.enu_to_geodetic`, which the telemetry publisher uses.
        """
        from bridge.geo import enu_to_geodetic_many

        if self.scene.home is None or not positions_m:
            return {}
        geodetic = enu_to_geodetic_many(self.scene.home, np.array(list(positions_m.values())))
        return {uav_id: (float(lat), float(lon), float(alt))
                for uav_id, (lat, lon, alt) in zip(positions_m, geodetic, strict=True)}

    def _stream_due(self) -> bool:
        """Whether this step goes to the live view (at most ``max_rate_hz`` steps per wall-clock second)."""
        if self._live is None or not self._stream_period_s:
            return True
        now_s = time.monotonic()
        if now_s < self._next_stream_s:
            return False
        self._next_stream_s = now_s + self._stream_period_s
        return True

    def _log_step(self, time_s: float, states: Sequence[UavState], qos: Qos, pedestrians_m: np.ndarray,
                  covered: np.ndarray, association: np.ndarray | None) -> None:
        # a state without its WGS84 position gets it from the home, as the telemetry publisher sends it
        located = self._fixes_from_home({
            s.uav_id: s.position_enu_m for s in states
            if s.position_enu_m is not None and s.position_wgs84 is None
            and (self._takers(f"/uav/{s.uav_id}/state", _STATE_CHANNEL)
                 or self._takers(f"/uav/{s.uav_id}/location", _LOCATION_CHANNEL))})
        placed: dict[int, tuple[fox.Vec3, fox.Vec3 | None]] = {}  # position and target of each UAV with a fix
        for state in states:
            if state.uav_id in located:
                state = msgspec.structs.replace(state, position_wgs84=GeoPoint(*located[state.uav_id]))
            self._log_json(f"/uav/{state.uav_id}/state", "uav_swarm.UavState", time_s, state)
            if state.position_enu_m is None:  # no position fix: its state says so, nothing to draw
                continue
            placed[state.uav_id] = (state.position_enu_m, state.target_enu_m)
            fix = state.position_wgs84
            if fix is not None:
                self._log(f"/uav/{state.uav_id}/location", _LOCATION_CHANNEL, time_s, partial(
                    fox.location_fix, time_s, state.uav_id, fix.lat_deg, fix.lon_deg, fix.alt_m))
        self._log("/tf", _RUN_CHANNELS["/tf"], time_s,
                  lambda: fox.frame_transforms(time_s, {uav_id: p for uav_id, (p, _) in placed.items()}))
        drawn = [s for s in states if s.position_enu_m is not None]
        held = [bool(s.separation_held) for s in drawn]
        service = uav_service(drawn, pedestrians_m, covered, association)  # 802.11: channel, whom it serves
        served_by = None if service is None else association
        self._log(_SCENE, _scene_channel, time_s,
                  lambda: fox.swarm_scene(time_s, list(placed.values()), self.scene.coverage_radius_m,
                                          self.scene.min_separation_m, held, service))
        self._log("/pedestrians", _RUN_CHANNELS["/pedestrians"], time_s,
                  lambda: fox.crowd_cloud(time_s, pedestrians_m, covered, served_by))
        self.qos(time_s, qos)


def _typed(kind: Callable[..., Any]) -> Callable[[str, foxglove.Context], Any]:
    return lambda topic, context: kind(topic, context=context)


_scene_channel = _typed(SceneUpdateChannel)
_LOCATION_CHANNEL = _typed(LocationFixChannel)
_JSON_CHANNELS = {name: _json_channel(name) for name in _PAYLOADS}
_STATE_CHANNEL = _JSON_CHANNELS["uav_swarm.UavState"]
_RUN_CHANNELS: dict[str, Callable[[str, foxglove.Context], Any]] = {
    _SCENE: _scene_channel, "/pedestrians": _typed(PointCloudChannel), "/tf": _typed(FrameTransformsChannel),
    "/plan": _JSON_CHANNELS["uav_swarm.Plan"], "/plan/targets": _typed(PosesInFrameChannel),
    "/qos": _JSON_CHANNELS["uav_swarm.Qos"]}
RUN_TOPICS = tuple(_RUN_CHANNELS)
"""The topics every run has (the per-UAV ``/uav/<id>/...`` ones come with the UAVs)."""


@contextmanager
def open_recorder(scene: SceneInfo, *, record: str | Path | None = None, live: LiveView | None = None,
                  command: str = "", config: dict[str, Any] | None = None) -> Iterator[RunRecorder | None]:
    """A recorder to an MCAP file (``record``) and/or a live view (``live``); None when neither is asked.

    The file (zstd chunks) is renamed into place when the block ends; the live server stops then.

    Args:
        scene: The run's area, coverage radius and home.
        record: The ``.mcap`` file to write (its folder is created).
        live: Where the live view's WebSocket server listens.
        command: The command that records (``simulate`` or ``fly``), for the metadata and the server name.
        config: The run's resolved config, for the metadata.

    Raises:
        ConfigError: ``record`` does not end in ``.mcap`` or names a folder; the live view cannot listen
            on ``live`` (port in use, host not of this machine).
    """
    if record is None and live is None:
        yield None
        return
    with ExitStack() as stack:
        contexts: list[foxglove.Context] = []
        if record is not None:
            path = check_recording_path(record)
            path.parent.mkdir(parents=True, exist_ok=True)
            contexts.append(foxglove.Context())
            tmp = stack.enter_context(atomic_path(path))
            options = MCAPWriteOptions(compression=MCAPCompression.Zstd, profile="")
            writer = stack.enter_context(foxglove.open_mcap(tmp, context=contexts[-1],
                                                            writer_options=options))
            writer.write_metadata(RUN_METADATA, {
                "command": command, "start_unix_s": f"{time.time():.3f}",
                "time": "log times are run time: nanoseconds from the start of the run",
                "config": json.dumps(config or {}, sort_keys=True)})
        live_context = foxglove.Context() if live is not None else None
        recorder = RunRecorder(scene, contexts + ([live_context] if live_context else []), live_context, live)
        if live is not None and live_context is not None:  # the context exists whenever live is given
            stack.callback(_stop_live, _start_live(live, live_context, recorder, command))
        yield recorder
    if record is not None:
        logger.info("recorded %d messages on %d topics in %s", sum(recorder.counts.values()),
                    len(recorder.counts), record)


def _start_live(live: LiveView, context: foxglove.Context, recorder: RunRecorder,
                command: str) -> Any:
    """Start the SDK's WebSocket server on ``live`` for ``context``; a client's late ``/scene`` is re-sent."""
    listener = LiveListener([_SCENE], recorder.resend_static_scene)
    recorder.advertise()  # a client can subscribe to every run-wide channel before the first step
    try:
        server = foxglove.start_server(
            name=f"uav-swarm {command}".strip(), host=live.host, port=live.port, context=context,
            server_listener=listener,  # type: ignore[arg-type]  # the SDK calls only the callbacks it has
            message_backlog_size=LIVE_BACKLOG_MESSAGES)
    except RuntimeError as exc:
        raise ConfigError(f"--live {live.host}:{live.port}: the live view cannot listen there: "
                          f"{exc}") from exc
    host = f"[{live.host}]" if ":" in live.host else live.host
    logger.info("live view on ws://%s:%d (Foxglove: Open connection, Foxglove WebSocket)", host, server.port)
    if not live.is_loopback:
        logger.warning("the live view listens on %s: anyone who reaches this machine on port %d can watch "
                       "the run (no password, no encryption)", live.host, server.port)
    if live.wait_for_client_s > 0:
        logger.info("waiting at most %.0f s for a live client to subscribe to %s", live.wait_for_client_s,
                    _SCENE)
        if not listener.viewer.wait(live.wait_for_client_s):
            logger.warning("no live client after %.1f s: running anyway", live.wait_for_client_s)
    return server


def _stop_live(server: Any) -> None:
    """Stop the server, waiting at most :data:`LIVE_STOP_WAIT_S` for its clients to take the end.

    The SDK's ``stop`` waits until every client has been sent what it queued, which a client that
    stopped reading never lets happen: past the wait, the server is left to the end of the process.
    """
    stopping = threading.Thread(target=server.stop, name="live-view-stop", daemon=True)
    stopping.start()
    stopping.join(LIVE_STOP_WAIT_S)
    if stopping.is_alive():
        logger.warning("a live client did not take the end of the stream in %.0f s (stopped reading?): "
                       "not waiting for it", LIVE_STOP_WAIT_S)


def check_recording_path(path: str | Path) -> Path:
    """``path`` as a :class:`Path`, refused unless it is a ``.mcap`` file name (not a folder).

    Raises:
        ConfigError: Naming ``record`` and the path.
    """
    path = Path(path)
    if path.suffix != ".mcap" or path.is_dir():
        raise ConfigError(f"record = {str(path)!r}: give a .mcap file to write the recording to")
    return path
