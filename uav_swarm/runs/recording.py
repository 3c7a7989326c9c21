"""Record a run (``simulate --record``, ``fly --record``) as an MCAP file that Foxglove replays.

One file per run, JSON messages (MCAP message encoding ``json``, schema encoding ``jsonschema``).
Every message's log time (and publish time) is the **run time** of what it shows, in nanoseconds
from the start of the run: simulated seconds for ``simulate``, crowd seconds for ``fly``; the wall
clock time of the start is in the ``uav_swarm.run`` metadata record. The channels:

- ``/scene`` (``foxglove.SceneUpdate``): at the start, the area's outline (entity ``area``) and the
  obstacles (``obstacles``); every recorded step, the UAVs (``uavs``), their coverage discs
  (``coverage``) and their targets with a line from each UAV (``targets``);
- ``/pedestrians`` (``foxglove.PointCloud``): every recorded step, the crowd; field ``covered`` is 1
  for a user a UAV serves, else 0;
- ``/tf`` (``foxglove.FrameTransforms``): every recorded step, ``map`` -> ``uav_<id>``;
- ``/uav/<id>/state`` (``uav_swarm.UavState``): every recorded step, each UAV's telemetry state;
- ``/uav/<id>/location`` (``foxglove.LocationFix``): with it, when its WGS84 position is known;
- ``/plan`` (``uav_swarm.Plan``) and ``/plan/targets`` (``foxglove.PosesInFrame``): every plan;
- ``/qos`` (``uav_swarm.Qos``): every recorded step.

The ``uav_swarm.*`` channels carry exactly the JSON that telemetry publishes over Zenoh; their
schemas are generated from the payload types. The file is written beside its final path and
renamed when the run ends (:func:`learning.files.atomic_path`): a run that fails leaves no file.

Examples:
    >>> import tempfile
    >>> from mcap.reader import make_reader
    >>> from bridge.telemetry.schema import Qos
    >>> path = Path(tempfile.mkdtemp()) / "run.mcap"
    >>> scene = SceneInfo(width_m=100.0, height_m=80.0, coverage_radius_m=30.0)
    >>> with open_recording(path, scene) as recorder:
    ...     recorder.qos(0.1, Qos(stamp_s=0.0, seq=0, source="sim", qos_s1=0.5, qos_s2=0.25,
    ...                           mean_throughput_mbps=3.0, n_users=4))
    >>> with path.open("rb") as f:
    ...     [(c.topic, m.log_time) for _, c, m in make_reader(f).iter_messages()]
    [('/qos', 100000000)]
"""

from __future__ import annotations

import json
import logging
import time
from collections import Counter
from collections.abc import Iterator, Sequence
from contextlib import AbstractContextManager, contextmanager, nullcontext
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import msgspec
import numpy as np
from mcap.writer import CompressionType, Writer

from bridge.telemetry.schema import Plan, Qos, UavState, encode_payload
from learning.files import atomic_path
from typed_config import ConfigError
from uav_swarm.runs import foxglove_messages as fox

if TYPE_CHECKING:
    from bridge.geo import Home

Vec3 = tuple[float, float, float]

__all__ = ["SceneInfo", "RunRecorder", "open_recording", "maybe_recording", "check_recording_path",
           "RUN_METADATA"]

logger = logging.getLogger(__name__)

RUN_METADATA = "uav_swarm.run"
"""Name of the metadata record that describes the run (command, start time, config)."""

_UAV, _TARGET = fox.color(0.10, 0.35, 0.85), fox.color(0.90, 0.45, 0.05)
_DISC = fox.color(0.10, 0.35, 0.85, 0.15)
_WALL, _OUTLINE = fox.color(0.25, 0.25, 0.25), fox.color(0.55, 0.55, 0.55)
_UAV_SIZE_M, _TARGET_SIZE_M = 3.0, 2.0


@dataclass(frozen=True)
class SceneInfo:
    """What a recording needs to know of the run's world besides its messages.

    Attributes:
        width_m: East extent of the area (metres from the home).
        height_m: North extent of the area.
        coverage_radius_m: Radius of a UAV's coverage disc on the ground.
        home: The geodetic home of the local frame; ``None``: no WGS84 fixes for simulated states.
    """

    width_m: float
    height_m: float
    coverage_radius_m: float
    home: Home | None = None


class RunRecorder:
    """Writes a run's messages into an open MCAP writer (see the module docstring for the channels).

    Use :func:`open_recording`, which also finishes the file and renames it into place.
    """

    def __init__(self, writer: Writer, scene: SceneInfo) -> None:
        self._writer = writer
        self.scene = scene
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self.counts: Counter[str] = Counter()
        """Messages written, by topic."""

    # -- channels ------------------------------------------------------------------------------
    def _schema_id(self, name: str) -> int:
        if name not in self._schemas:
            if name in fox.SCHEMAS:
                schema = fox.SCHEMAS[name]
            else:
                payload = {"uav_swarm.UavState": UavState, "uav_swarm.Plan": Plan, "uav_swarm.Qos": Qos}[name]
                schema = {"title": name, **msgspec.json.schema(payload)}
            data = json.dumps(schema, sort_keys=True).encode()
            self._schemas[name] = self._writer.register_schema(name=name, encoding="jsonschema", data=data)
        return self._schemas[name]

    def _write(self, topic: str, schema: str, time_s: float, data: bytes) -> None:
        if time_s < 0:
            raise ValueError(f"{topic}: time_s = {time_s} is negative: run times start at 0")
        if topic not in self._channels:
            self._channels[topic] = self._writer.register_channel(
                topic=topic, message_encoding="json", schema_id=self._schema_id(schema))
        ns = round(time_s * 1e9)
        self._writer.add_message(self._channels[topic], log_time=ns, publish_time=ns, data=data,
                                 sequence=self.counts[topic])
        self.counts[topic] += 1

    def _write_json(self, topic: str, schema: str, time_s: float, message: dict[str, Any]) -> None:
        self._write(topic, schema, time_s, json.dumps(message, separators=(",", ":")).encode())

    # -- what a run records --------------------------------------------------------------------
    def static_scene(self, obstacles_m: np.ndarray, time_s: float = 0.0) -> None:
        """The area's outline and the obstacle segments ``(M, 4)`` (``x1, y1, x2, y2``), kept all run."""
        w, h = self.scene.width_m, self.scene.height_m
        outline = {"type": fox.LINE_LOOP, "pose": fox.pose(0.0, 0.0, 0.0), "thickness": 0.5,
                   "scale_invariant": False, "color": _OUTLINE, "colors": [], "indices": [],
                   "points": [fox.pose(x, y, 0.0)["position"] for x, y in ((0, 0), (w, 0), (w, h), (0, h))]}
        segments = np.asarray(obstacles_m, np.float64).reshape(-1, 4)
        walls = {"type": fox.LINE_LIST, "pose": fox.pose(0.0, 0.0, 0.0), "thickness": 1.0,
                 "scale_invariant": False, "color": _WALL, "colors": [], "indices": [],
                 "points": [fox.pose(x, y, 0.0)["position"] for x1, y1, x2, y2 in segments
                            for x, y in ((x1, y1), (x2, y2))]}
        entities = [fox.scene_entity("area", time_s, lines=[outline]),
                    fox.scene_entity("obstacles", time_s, lines=[walls] if len(segments) else [])]
        self._write_json("/scene", "foxglove.SceneUpdate", time_s, {"deletions": [], "entities": entities})

    def plan(self, time_s: float, plan: Plan) -> None:
        """A plan: its telemetry payload on ``/plan`` and its targets on ``/plan/targets``."""
        self._write("/plan", "uav_swarm.Plan", time_s, encode_payload(plan))
        self._write_json("/plan/targets", "foxglove.PosesInFrame", time_s,
                         fox.poses_in_frame(time_s, [t.target_enu_m for t in plan.targets]))

    def qos(self, time_s: float, qos: Qos) -> None:
        """The QoS at ``time_s`` on ``/qos``."""
        self._write("/qos", "uav_swarm.Qos", time_s, encode_payload(qos))

    def step(self, time_s: float, states: Sequence[UavState], qos: Qos, pedestrians_m: np.ndarray,
             covered: np.ndarray) -> None:
        """One recorded step: each UAV's state (and fix), the frames, the scene, the crowd and the QoS.

        Args:
            time_s: Run time of the step.
            states: The state of each UAV flying now (one without a position fix is recorded on its
                ``/state`` channel only).
            qos: The QoS of those UAVs over the crowd.
            pedestrians_m: ``(N, 2)`` crowd positions.
            covered: ``(N,)`` True for a user a UAV serves.
        """
        from bridge.geo import enu_to_geodetic

        placed: dict[int, tuple[Vec3, Vec3 | None]] = {}  # position and target of each UAV with a fix
        for state in states:
            self._write(f"/uav/{state.uav_id}/state", "uav_swarm.UavState", time_s, encode_payload(state))
            if state.position_enu_m is None:  # no position fix: its state says so, nothing to draw
                continue
            placed[state.uav_id] = (state.position_enu_m, state.target_enu_m)
            fix = state.position_wgs84
            if fix is None and self.scene.home is not None:
                lat, lon, alt = enu_to_geodetic(self.scene.home, *state.position_enu_m)
            elif fix is not None:
                lat, lon, alt = fix.lat_deg, fix.lon_deg, fix.alt_m
            else:
                continue
            self._write_json(f"/uav/{state.uav_id}/location", "foxglove.LocationFix", time_s,
                             fox.location_fix(time_s, state.uav_id, lat, lon, alt))
        self._write_json("/tf", "foxglove.FrameTransforms", time_s,
                         fox.frame_transforms(time_s, {uav_id: p for uav_id, (p, _) in placed.items()}))
        self._write_json("/scene", "foxglove.SceneUpdate", time_s,
                         {"deletions": [], "entities": self._swarm_entities(time_s, list(placed.values()))})
        users = np.asarray(pedestrians_m, np.float64).reshape(-1, 2)
        points = np.column_stack([users, np.zeros(len(users))])
        self._write_json("/pedestrians", "foxglove.PointCloud", time_s,
                         fox.point_cloud(time_s, points, {"covered": np.asarray(covered, np.float32)}))
        self.qos(time_s, qos)

    def _swarm_entities(self, time_s: float, placed: list[tuple[Vec3, Vec3 | None]]) -> list[dict[str, Any]]:
        """The UAVs, their coverage discs and their targets (``placed``: position and target of each)."""
        size = {"x": _UAV_SIZE_M, "y": _UAV_SIZE_M, "z": _UAV_SIZE_M}
        uavs = [{"pose": fox.pose(*position), "size": size, "color": _UAV} for position, _ in placed]
        radius = self.scene.coverage_radius_m
        discs = [{"pose": fox.pose(x, y, 0.05), "size": {"x": 2 * radius, "y": 2 * radius, "z": 0.1},
                  "bottom_scale": 1.0, "top_scale": 1.0, "color": _DISC} for (x, y, _), _ in placed]
        aimed = [(position, target) for position, target in placed if target is not None]
        marker = {"x": _TARGET_SIZE_M, "y": _TARGET_SIZE_M, "z": _TARGET_SIZE_M}
        targets = [{"pose": fox.pose(*target), "size": marker, "color": _TARGET} for _, target in aimed]
        legs = {"type": fox.LINE_LIST, "pose": fox.pose(0.0, 0.0, 0.0), "thickness": 0.3,
                "scale_invariant": False, "color": _TARGET, "colors": [], "indices": [],
                "points": [fox.pose(*p)["position"] for pair in aimed for p in pair]}
        return [fox.scene_entity("uavs", time_s, spheres=uavs),
                fox.scene_entity("coverage", time_s, cylinders=discs),
                fox.scene_entity("targets", time_s, cubes=targets, lines=[legs] if aimed else [])]


@contextmanager
def open_recording(path: str | Path, scene: SceneInfo, *, command: str = "",
                   config: dict[str, Any] | None = None) -> Iterator[RunRecorder]:
    """A recorder writing to ``path`` (MCAP, zstd chunks), renamed into place when the block ends.

    Args:
        path: The ``.mcap`` file to write (its folder is created).
        scene: The run's area, altitude, coverage radius and home.
        command: The command that records (``simulate`` or ``fly``), for the metadata.
        config: The run's resolved config, for the metadata.

    Raises:
        ConfigError: ``path`` does not end in ``.mcap`` or names a folder.
    """
    path = check_recording_path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp, tmp.open("wb") as stream:
        writer = Writer(stream, compression=CompressionType.ZSTD)
        writer.start(profile="", library="uav_swarm")
        writer.add_metadata(RUN_METADATA, {
            "command": command, "start_unix_s": f"{time.time():.3f}",
            "time": "log times are run time: nanoseconds from the start of the run",
            "config": json.dumps(config or {}, sort_keys=True)})
        recorder = RunRecorder(writer, scene)
        yield recorder
        writer.finish()
        logger.info("recorded %d messages on %d topics in %s", sum(recorder.counts.values()),
                    len(recorder.counts), path)


def check_recording_path(path: str | Path) -> Path:
    """``path`` as a :class:`Path`, refused unless it is a ``.mcap`` file name (not a folder).

    Raises:
        ConfigError: Naming ``record`` and the path.
    """
    path = Path(path)
    if path.suffix != ".mcap" or path.is_dir():
        raise ConfigError(f"record = {str(path)!r}: give a .mcap file to write the recording to")
    return path


def maybe_recording(path: str | Path | None, scene: SceneInfo, *, command: str = "",
                    config: dict[str, Any] | None = None) -> AbstractContextManager[RunRecorder | None]:
    """:func:`open_recording` when ``path`` is given, else a block that yields ``None`` (nothing recorded)."""
    if path is None:
        return nullcontext()
    return open_recording(path, scene, command=command, config=config)
