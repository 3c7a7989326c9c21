"""Draw the 3D panel's scene of a recording from above, with matplotlib: the picture of docs/foxglove.md.

It reads the file with the ``mcap`` reader and decodes Foxglove's messages with protobuf's own decoder
from the descriptors in the file (no Foxglove SDK, no Foxglove app), then draws, at the chosen time,
what the layout's 3D panel shows: the area and obstacles (``/scene``, first message), the crowd coloured
by ``covered`` (``/pedestrians``), and the UAVs, their coverage discs and their targets (``/scene``).

Usage: python docs/foxglove/draw_recording.py RUN.mcap OUT.png [--time-s T]   (default: the last step)
"""

from __future__ import annotations

import argparse
from functools import cache
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory  # noqa: E402
from matplotlib.patches import Circle  # noqa: E402
from mcap.reader import make_reader  # noqa: E402


@cache
def _message_class(name: str, descriptor_set: bytes) -> Any:
    pool = descriptor_pool.DescriptorPool()
    for file in descriptor_pb2.FileDescriptorSet.FromString(descriptor_set).file:
        pool.Add(file)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(name))


def read_scene(path: Path, time_s: float | None) -> dict[str, Any]:
    """The static scene, and the last swarm scene and crowd logged at or before ``time_s``."""
    found: dict[str, Any] = {}
    limit_ns = None if time_s is None else round(time_s * 1e9)
    with path.open("rb") as stream:
        for schema, channel, message in make_reader(stream).iter_messages(topics=["/scene", "/pedestrians"],
                                                                         log_time_order=True):
            if limit_ns is not None and message.log_time > limit_ns:
                break
            decoded = _message_class(schema.name, schema.data).FromString(message.data)
            if channel.topic == "/pedestrians":
                found["crowd"], found["time_ns"] = decoded, message.log_time
            elif {e.id for e in decoded.entities} >= {"area", "obstacles"}:
                found["static"] = decoded
            else:
                found["swarm"] = decoded
    return found


def _points(line: Any) -> np.ndarray:
    return np.array([(p.x, p.y) for p in line.points]).reshape(-1, 2)


def draw(scene: dict[str, Any], out: Path) -> None:
    """Draw the scene from above (East right, North up, metres) into ``out``."""
    fig, ax = plt.subplots(figsize=(7.0, 6.4), dpi=110)
    entities = {e.id: e for e in scene["static"].entities}
    outline = _points(entities["area"].lines[0])
    ax.fill(outline[:, 0], outline[:, 1], facecolor="#f4f4f4", edgecolor="#8c8c8c", lw=1.0)
    for line in entities["obstacles"].lines:
        walls = _points(line).reshape(-1, 2, 2)
        for segment in walls:
            ax.plot(segment[:, 0], segment[:, 1], color="#404040", lw=2.0)
    crowd = scene["crowd"]
    names = [f.name for f in crowd.fields]
    points = np.frombuffer(crowd.data, "<f4").reshape(-1, crowd.point_stride // 4)
    served = points[:, names.index("covered")] > 0.5
    ax.scatter(*points[~served, :2].T, s=5, color="#9e9e9e", label="pedestrian, not served")
    ax.scatter(*points[served, :2].T, s=5, color="#2e9e44", label="pedestrian, served")
    swarm = {e.id: e for e in scene["swarm"].entities}
    for disc in swarm["coverage"].cylinders:
        ax.add_patch(Circle((disc.pose.position.x, disc.pose.position.y), disc.size.x / 2, color="#1a59d9",
                            alpha=0.12, lw=0))
    for leg in swarm["targets"].lines:
        for segment in _points(leg).reshape(-1, 2, 2):
            ax.plot(segment[:, 0], segment[:, 1], color="#e6730d", lw=1.0)
    targets = np.array([(c.pose.position.x, c.pose.position.y) for c in swarm["targets"].cubes])
    targets = targets.reshape(-1, 2)
    ax.scatter(*targets.T, marker="s", s=22, color="#e6730d", label="target")
    uavs = np.array([(s.pose.position.x, s.pose.position.y) for s in swarm["uavs"].spheres]).reshape(-1, 2)
    ax.scatter(*uavs.T, s=40, color="#1a59d9", edgecolor="white", lw=0.8, label="UAV (disc: coverage)")
    ax.set_aspect("equal")
    ax.set_xlabel("East (m)")
    ax.set_ylabel("North (m)")
    ax.set_title(f"map frame at t = {scene['time_ns'] / 1e9:.1f} s: "
                 f"{int(served.sum())} of {len(served)} pedestrians served")
    ax.legend(loc="upper right", fontsize=7, framealpha=0.9)
    fig.tight_layout()
    fig.savefig(out)
    plt.close(fig)


def main() -> None:
    """Read the arguments, draw the picture."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("recording", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("--time-s", type=float, help="run time to draw (default: the last recorded step)")
    args = parser.parse_args()
    draw(read_scene(args.recording, args.time_s), args.out)


if __name__ == "__main__":
    main()
