"""Pictures and tables of the main job: the QoS figure, the scene animation, the time series.

Drawing only: the runs come from :func:`uav_swarm.simulate.run_sequence`. Every file is written
atomically (a temporary file in the same folder, then ``os.replace``). Matplotlib (``Agg``) draws
the figure; Pillow draws and saves the GIF frames (:func:`uav_swarm.render.draw_frame` for the scene).
"""

from __future__ import annotations

import io
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from PIL import Image, ImageDraw

from learning.files import write_bytes_atomic
from uav_swarm.missions.wifi import crowd_raster
from uav_swarm.render import draw_frame

if TYPE_CHECKING:
    from uav_swarm.simulate import Frame, SequenceRun
    from uav_swarm.simulate_config import SimulateConfig

__all__ = ["write_qos_figure", "write_scene_gif", "write_timeseries", "scene_frame"]

_STYLE = {"learned": {"color": "tab:blue"}, "expert": {"color": "tab:orange"}}
_TARGET = (20, 20, 20)
_PEAK = (255, 255, 255)
_HEADER_PX = 18
_LEVELS = 10



def write_qos_figure(runs: Mapping[str, SequenceRun], path: Path) -> Path:
    """QoS S1 and S2 over time (top) and mean user throughput over time (bottom), every planner.

    Returns:
        ``path``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, (ax_qos, ax_rate) = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True)
    for kind, run in runs.items():
        style = _STYLE.get(kind, {})
        ax_qos.plot(run.times_s, run.qos_s1, label=f"{kind}: S1 (share covered)", **style)
        ax_qos.plot(run.times_s, run.qos_s2, linestyle="--", label=f"{kind}: S2 (covered with >= min rate)",
                    **style)
        ax_rate.plot(run.times_s, run.throughput_mbps, label=f"{kind} ({run.planner_name})", **style)
    ax_qos.set(ylabel="QoS", ylim=(0.0, 1.02), title="Dynamic sequence: QoS over time")
    ax_qos.legend(loc="center right", fontsize="small", ncol=2, framealpha=0.8)  # S1 above, S2 below
    ax_qos.grid(alpha=0.3)
    ax_rate.set(xlabel="simulated time (s)", ylabel="mean throughput per user (Mbps)")
    ax_rate.set_ylim(bottom=0.0)
    ax_rate.legend(loc="lower right", fontsize="small")
    ax_rate.grid(alpha=0.3)
    figure.tight_layout()
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=100)
    plt.close(figure)
    write_bytes_atomic(path, buffer.getvalue())
    return path


def write_timeseries(runs: Mapping[str, SequenceRun], path: Path) -> Path:
    """``planner,time_s,qos_s1,qos_s2,mean_throughput_mbps`` one row per step and planner."""
    lines = ["planner,time_s,qos_s1,qos_s2,mean_throughput_mbps"]
    for kind, run in runs.items():
        for row in zip(run.times_s, run.qos_s1, run.qos_s2, run.throughput_mbps, strict=True):
            lines.append(f"{kind},{row[0]:.2f},{row[1]:.6f},{row[2]:.6f},{row[3]:.6f}")
    write_bytes_atomic(path, ("\n".join(lines) + "\n").encode())
    return path


def _viridis(values: np.ndarray, levels: int = _LEVELS) -> np.ndarray:
    """(h, w) values -> (h, w, 3) uint8 colours in ``levels`` steps of the map's own range.

    Few distinct colours leave the GIF palette to the scene and keep the file small.
    """
    from matplotlib import colormaps

    lo, hi = float(values.min()), float(values.max())
    scaled = (values - lo) / (hi - lo) if hi > lo else np.zeros_like(values)
    stepped = np.minimum(np.floor(scaled * levels), levels - 1) / (levels - 1)
    return (colormaps["viridis"](stepped)[..., :3] * 255).astype(np.uint8)


def _mark(draw: ImageDraw.ImageDraw, points_px: np.ndarray, colour: tuple[int, int, int], size: float
          ) -> None:
    for x, y in points_px:
        draw.line((x - size, y - size, x + size, y + size), fill=colour, width=2)
        draw.line((x - size, y + size, x + size, y - size), fill=colour, width=2)


def _rings(draw: ImageDraw.ImageDraw, points_px: np.ndarray, colour: tuple[int, int, int], size: float
           ) -> None:
    for x, y in points_px:
        draw.ellipse((x - size, y - size, x + size, y + size), outline=colour, width=1)


def scene_frame(frame: Frame, config: SimulateConfig, obstacles_m: np.ndarray, width_px: int) -> Image.Image:
    """One animation frame: the scene (left) and the utility map, or the density raster (right).

    Targets are black rings on the scene; the planner's peaks are white crosses on the map.
    """
    width_m, height_m = config.task.scenario.width_m, config.task.scenario.height_m
    scene = draw_frame(width_m, height_m, obstacles_m=obstacles_m, pedestrians_m=frame.pedestrians_m,
                       covered=frame.covered, uavs_m=frame.uavs_m,
                       coverage_radius_m=config.task.radio.coverage_radius_m, width_px=width_px)
    scale = width_px / width_m
    height_px = scene.shape[0]

    def to_px(xy_m: np.ndarray) -> np.ndarray:
        xy = np.asarray(xy_m, dtype=np.float64).reshape(-1, 2)
        return np.column_stack([xy[:, 0] * scale, (height_m - xy[:, 1]) * scale])

    left = Image.fromarray(scene)
    _rings(ImageDraw.Draw(left), to_px(frame.targets_m), _TARGET, max(4.0, 0.02 * width_px))
    values = frame.utility if frame.utility is not None else crowd_raster(frame.pedestrians_m, config.task)[0]
    panel = Image.fromarray(_viridis(np.flipud(values))).resize((width_px, height_px),
                                                                Image.Resampling.NEAREST)
    _mark(ImageDraw.Draw(panel), to_px(frame.peaks_m), _PEAK, 3.0)
    image = Image.new("RGB", (2 * width_px, height_px + _HEADER_PX), (255, 255, 255))
    image.paste(left, (0, _HEADER_PX))
    image.paste(panel, (width_px, _HEADER_PX))
    label = "utility map" if frame.utility is not None else "crowd density"
    text = f"t = {frame.time_s:.1f} s   QoS: S1 = {frame.qos_s1:.2f}, S2 = {frame.qos_s2:.2f}  right: {label}"
    ImageDraw.Draw(image).text((4, 3), text, fill=(0, 0, 0))
    return image


def write_scene_gif(run: SequenceRun, config: SimulateConfig, path: Path) -> Path:
    """The animation of a run's frames as a looping GIF (10 frames per second of wall time).

    Returns:
        ``path``.

    Raises:
        ValueError: The run kept no frames.
    """
    if not run.frames:
        raise ValueError(f"the {run.planner} run kept no frames to animate")
    frames = (scene_frame(f, config, run.obstacles_m, config.gif_width_px) for f in run.frames)
    images = [image.quantize(32, dither=Image.Dither.NONE) for image in frames]  # flat areas compress well
    buffer = io.BytesIO()
    images[0].save(buffer, format="GIF", save_all=True, append_images=images[1:], duration=100, loop=0,
                   optimize=True)
    write_bytes_atomic(path, buffer.getvalue())
    return path
