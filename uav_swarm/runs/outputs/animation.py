"""The scene animation of the main job (``scene.gif``), drawn for people.

Each frame shows, side by side and in the same frame of reference (metres East and North of the
area's South-West corner, equal axes): the scene and the learned planner's utility map with its peaks
and the UAVs (the crowd density for the expert planner). On the paper's radio the scene has the
pedestrians green when covered and grey otherwise, the coverage discs (whole: the radius is the margin),
obstacles, UAVs, targets and a scale bar. Under the 802.11 radio, which has no coverage disc, each UAV
has a colour of its own (:data:`~uav_swarm.runs.outputs.radio_report.SERVICE_COLOURS`) and its channel written
beside it, and each pedestrian takes the colour of the UAV that serves it (grey: served by none). The
title gives the simulated time and the QoS; a legend below names every mark. Matplotlib (``Agg``) draws
one figure whose marks are moved from frame to frame; Pillow writes the GIF (a palette of few colours per
frame, so the default run of 100 frames of 1,000 px stays near 3 MB).
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch, Rectangle
from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar
from PIL import Image

from typed_config.files import write_bytes_atomic
from uav_swarm.missions.wifi.task import crowd_raster
from uav_swarm.runs.outputs.radio_report import SERVICE_COLOURS
from uav_swarm.runs.outputs.records import Frame, SequenceRun

if TYPE_CHECKING:
    from uav_swarm.runs.simulate_config import SimulateConfig

__all__ = ["SceneAnimation", "write_scene_gif"]

_DPI = 100
_HEIGHT_RATIO = 0.56  # frame height / width: two square maps, the title above, the legend below
_LEVELS = 10  # colour steps of the map: few colours keep the GIF small
_GIF_COLOURS = 64
_FRAME_MS = 100

_COVERED = "#1e963c"
_UNCOVERED = "#969696"
_UAV = "#dc1e1e"
_DISC_FACE = (0.27, 0.51, 0.9, 0.22)
_DISC_EDGE = (0.27, 0.51, 0.9, 0.8)
_TARGET = "black"
_OBSTACLE = "#141414"


def _scale_bar_m(extent_m: float) -> float:
    """A round length of at most a quarter of the map: 1, 2 or 5 times a power of ten metres."""
    raw = extent_m / 4.0
    power = 10.0 ** np.floor(np.log10(raw))
    return float(max(m * power for m in (1.0, 2.0, 5.0) if m * power <= raw))


class SceneAnimation:
    """One figure of a run's frames; :meth:`draw` moves the marks to a frame and returns the picture.

    Args:
        config: The simulation settings (area, coverage radius, planner, frame width).
        obstacles_m: ``(M, 4)`` the scenario's obstacle segments, metres.
        n_uavs: UAVs in every frame.
        utility: Whether the right map is the planner's utility (else the crowd density).
        wifi: Whether the run flew the 802.11 radio (each UAV's service and channel instead of discs).

    Attributes:
        figure: The matplotlib figure (scene axes, map axes, colour bar).
        title: The figure's title: time and QoS of the last frame drawn.
    """

    def __init__(self, config: SimulateConfig, obstacles_m: np.ndarray, n_uavs: int, *,
                 utility: bool, wifi: bool = False) -> None:
        self.config, self.wifi = config, wifi
        width_m, height_m = config.task.scenario.width_m, config.task.scenario.height_m
        radius_m = 0.0 if wifi else config.task.radio.coverage_radius_m
        margin_m = radius_m + (0.06 if wifi else 0.02) * max(width_m, height_m)
        width_px = config.gif_width_px
        self.figure = Figure(figsize=(width_px / _DPI, round(width_px * _HEIGHT_RATIO) / _DPI), dpi=_DPI)
        self.canvas = FigureCanvasAgg(self.figure)
        side = 0.4 / _HEIGHT_RATIO  # a square map 0.4 of the width wide
        scene = self.figure.add_axes((0.065, 0.175, 0.4, side))
        panel = self.figure.add_axes((0.53, 0.175, 0.4, side))
        colour_axes = self.figure.add_axes((0.94, 0.175, 0.012, side))
        for ax in (scene, panel):
            ax.set_xlim(-margin_m, width_m + margin_m)
            ax.set_ylim(-margin_m, height_m + margin_m)
            ax.set_aspect("equal", adjustable="box")
            ax.set_xlabel("East (m)", fontsize=9)
            ax.tick_params(labelsize=8)
            ax.add_patch(Rectangle((0.0, 0.0), width_m, height_m, fill=False, linestyle="--",
                                   edgecolor="#707070", linewidth=0.8))
        scene.set_ylabel("North (m)", fontsize=9)
        obstacles = np.asarray(obstacles_m, dtype=np.float64).reshape(-1, 2, 2)
        scene.add_collection(LineCollection(list(obstacles), colors=_OBSTACLE, linewidths=1.6))
        panel.add_collection(LineCollection(list(obstacles), colors="white", linewidths=0.8, alpha=0.6))
        bar_m = _scale_bar_m(width_m)
        scene.add_artist(AnchoredSizeBar(scene.transData, bar_m, f"{bar_m:g} m", "lower right", pad=0.3,
                                         borderpad=0.3, sep=3, frameon=False, size_vertical=0.01 * height_m,
                                         fontproperties={"size": 8}))

        self._discs = [] if wifi else [
            Circle((0.0, 0.0), radius_m, facecolor=_DISC_FACE, edgecolor=_DISC_EDGE, linewidth=0.8)
            for _ in range(n_uavs)]
        for disc in self._discs:
            scene.add_patch(disc)
        empty = np.zeros((0, 2))
        self._covered = scene.scatter(empty[:, 0], empty[:, 1], s=4, c=_COVERED, linewidths=0)
        self._uncovered = scene.scatter(empty[:, 0], empty[:, 1], s=4, c=_UNCOVERED, linewidths=0)
        self._targets = scene.scatter(empty[:, 0], empty[:, 1], s=70, facecolors="none", edgecolors=_TARGET,
                                      linewidths=1.2)
        self._uavs = scene.scatter(empty[:, 0], empty[:, 1], s=45, marker="D", c=_UAV, edgecolors="black",
                                   linewidths=0.6, zorder=5)
        self._uav_colours = [SERVICE_COLOURS[k % len(SERVICE_COLOURS)] for k in range(n_uavs)]
        self._channels = [scene.text(0.0, 0.0, "", fontsize=7, fontweight="bold", zorder=6,
                                     color=self._uav_colours[k], ha="left", va="bottom")
                          for k in range(n_uavs)] if wifi else []

        cmap = ListedColormap(colormaps["viridis"](np.linspace(0.0, 1.0, _LEVELS)))
        self._map = panel.imshow(np.zeros((2, 2)), origin="lower", extent=(0.0, width_m, 0.0, height_m),
                                 cmap=cmap, vmin=0.0, vmax=1.0, interpolation="nearest", zorder=0)
        self._peaks = panel.scatter(empty[:, 0], empty[:, 1], s=45, marker="x", c="white", linewidths=1.6,
                                    zorder=4)
        self._map_uavs = panel.scatter(empty[:, 0], empty[:, 1], s=30, marker="D", c=_UAV, edgecolors="white",
                                       linewidths=0.6, zorder=5)
        bar = self.figure.colorbar(self._map, cax=colour_axes, ticks=[0.0, 1.0])
        bar.ax.set_yticklabels(["low", "high"], fontsize=8)
        scene.set_title("Scene", fontsize=10)
        panel.set_title("Utility map of the learned planner" if utility else
                        "Crowd density (the expert planner has no utility map)", fontsize=10)

        uav = Line2D([], [], marker="D", linestyle="none", markerfacecolor=_UAV, markeredgecolor="black",
                     label="UAV")
        target = Line2D([], [], marker="o", linestyle="none", markerfacecolor="none", markeredgecolor=_TARGET,
                        markersize=8, label="UAV target")
        service: list[Line2D | Patch]
        if wifi:
            service = [
                uav, target,
                Line2D([], [], marker="o", linestyle="none", color=self._uav_colours[0], markersize=4,
                       label="pedestrian served by the UAV of its colour ('ch N': the UAV's channel)"),
                Line2D([], [], marker="o", linestyle="none", color=_UNCOVERED, markersize=4,
                       label="pedestrian not served")]
        else:
            service = [
                uav, target,
                Patch(facecolor=_DISC_FACE, edgecolor=_DISC_EDGE, label=f"coverage disc ({radius_m:g} m)"),
                Line2D([], [], marker="o", linestyle="none", color=_COVERED, markersize=4,
                       label="covered pedestrian"),
                Line2D([], [], marker="o", linestyle="none", color=_UNCOVERED, markersize=4,
                       label="uncovered pedestrian")]
        handles = [*service,
                   Line2D([], [], color=_OBSTACLE, linewidth=1.6, label="obstacle"),
                   Line2D([], [], color="#707070", linestyle="--", linewidth=0.8, label="area")]
        if utility:
            handles.append(Line2D([], [], marker="x", linestyle="none", color="#404040", markersize=7,
                                  markeredgewidth=1.6, label="utility peak (white on the map)"))
        self.figure.legend(handles=handles, loc="lower center", ncol=4, fontsize=8, frameon=False,
                           bbox_to_anchor=(0.5, 0.0), handletextpad=0.4, columnspacing=1.2)
        self.title = self.figure.suptitle("", fontsize=11, y=0.985)

    def draw(self, frame: Frame) -> Image.Image:
        """The picture of ``frame`` (RGB, ``config.gif_width_px`` wide)."""
        config = self.config
        pedestrians = np.asarray(frame.pedestrians_m, dtype=np.float64).reshape(-1, 2)
        covered = np.asarray(frame.covered, dtype=bool)
        uavs = np.asarray(frame.uavs_m, dtype=np.float64).reshape(-1, 2)
        for disc, centre in zip(self._discs, uavs, strict=False):  # no discs under 802.11
            disc.center = (float(centre[0]), float(centre[1]))
        if self.wifi and frame.association is not None:
            association = np.asarray(frame.association, dtype=np.int64)
            served = covered & (association >= 0)  # served with a usable rate, by its UAV
            self._covered.set_offsets(pedestrians[served])
            self._covered.set_facecolor([self._uav_colours[k] for k in association[served]])
            self._uncovered.set_offsets(pedestrians[~served])
            self._uavs.set_facecolor(self._uav_colours[:len(uavs)])
            channels = frame.channels if frame.channels is not None else np.zeros(0, np.int64)
            offset_m = 0.015 * config.task.scenario.width_m
            for k, (label, centre) in enumerate(zip(self._channels, uavs, strict=True)):
                label.set_position((float(centre[0]) + offset_m, float(centre[1]) + offset_m))
                label.set_text(f"ch {int(channels[k])}" if k < len(channels) else "")
        else:
            self._covered.set_offsets(pedestrians[covered])
            self._uncovered.set_offsets(pedestrians[~covered])
        self._targets.set_offsets(np.asarray(frame.targets_m, dtype=np.float64).reshape(-1, 2))
        self._uavs.set_offsets(uavs)
        self._map_uavs.set_offsets(uavs)
        self._peaks.set_offsets(np.asarray(frame.peaks_m, dtype=np.float64).reshape(-1, 2))
        values = frame.utility if frame.utility is not None else crowd_raster(pedestrians, config.task)[0]
        values = np.asarray(values, dtype=np.float64)
        low, high = float(values.min()), float(values.max())
        self._map.set_data((values - low) / (high - low) if high > low else np.zeros_like(values))
        rate = config.task.radio.min_user_rate_mbps
        covered_as = "served with a usable rate" if self.wifi else "covered"
        self.title.set_text(
            f"t = {frame.time_s:.1f} s    QoS: S1 = {frame.qos_s1:.2f} (share of {len(pedestrians)} "
            f"pedestrians {covered_as}),  S2 = {frame.qos_s2:.2f} (with >= {rate:g} Mbps)")
        self.canvas.draw()
        return Image.fromarray(np.asarray(self.canvas.buffer_rgba())[..., :3].copy())


def write_scene_gif(run: SequenceRun, config: SimulateConfig, path: Path) -> Path:
    """The animation of a run's frames as a looping GIF (10 frames per second of wall time).

    Returns:
        ``path``.

    Raises:
        ValueError: The run kept no frames.
    """
    if not run.frames:
        raise ValueError(f"the {run.planner} run kept no frames to animate")
    animation = SceneAnimation(config, run.obstacles_m, len(run.frames[0].uavs_m),
                               utility=run.frames[0].utility is not None,
                               wifi=run.frames[0].association is not None)
    images = [animation.draw(frame).quantize(_GIF_COLOURS, dither=Image.Dither.NONE) for frame in run.frames]
    buffer = io.BytesIO()
    images[0].save(buffer, format="GIF", save_all=True, append_images=images[1:], duration=_FRAME_MS, loop=0,
                   optimize=True)
    write_bytes_atomic(path, buffer.getvalue())
    return path
