"""Drawing of the world as an RGB picture (PIL and numpy), and a matplotlib window for it.

The picture is North-up: ``x`` (East) grows to the right and ``y`` (North) upward.
Layers, bottom to top: coverage discs (translucent), obstacles (black segments),
pedestrians (2x2 px dots: green when covered, grey otherwise) and UAVs (red diamonds).
Matplotlib is imported only when a window is opened.

Examples:
    >>> import numpy as np
    >>> frame = draw_frame(
    ...     100.0, 50.0, obstacles_m=np.array([[10.0, 10.0, 40.0, 10.0]]),
    ...     pedestrians_m=np.array([[20.0, 20.0]]), covered=np.array([True]),
    ...     uavs_m=np.array([[25.0, 25.0]]), coverage_radius_m=30.0, width_px=200)
    >>> frame.shape, frame.dtype
    ((100, 200, 3), dtype('uint8'))
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np
from PIL import Image, ImageDraw

__all__ = ["draw_frame", "HumanViewer"]

logger = logging.getLogger(__name__)

_BACKGROUND = (255, 255, 255)
_DISC = (70, 130, 230, 60)
_DISC_EDGE = (70, 130, 230, 160)
_OBSTACLE = (20, 20, 20)
_COVERED = np.array([30, 150, 60], dtype=np.uint8)
_UNCOVERED = np.array([150, 150, 150], dtype=np.uint8)
_UAV = (220, 30, 30)
_NON_INTERACTIVE_BACKENDS = frozenset({"agg", "cairo", "pdf", "pgf", "ps", "svg", "template"})


def draw_frame(
    width_m: float,
    height_m: float,
    *,
    obstacles_m: np.ndarray,
    pedestrians_m: np.ndarray,
    covered: np.ndarray,
    uavs_m: np.ndarray,
    coverage_radius_m: float,
    width_px: int = 512,
) -> np.ndarray:
    """Draw one frame of the world.

    Args:
        width_m: Area width (x extent) in metres.
        height_m: Area height (y extent) in metres.
        obstacles_m: (M, 4) obstacle segments ``x1, y1, x2, y2`` in metres.
        pedestrians_m: (N, 2) pedestrian positions in metres.
        covered: (N,) bool, whether each pedestrian is covered.
        uavs_m: (K, 2) UAV positions in metres.
        coverage_radius_m: Horizontal radius of a UAV's coverage disc in metres (0 draws none).
        width_px: Picture width in pixels; the height keeps the area's aspect ratio.

    Returns:
        (H, W, 3) uint8 RGB picture.
    """
    scale = width_px / width_m  # px per metre
    height_px = max(1, round(height_m * scale))

    def to_px(xy_m: np.ndarray) -> np.ndarray:
        return np.column_stack([xy_m[:, 0] * scale, (height_m - xy_m[:, 1]) * scale])

    image = Image.new("RGB", (width_px, height_px), _BACKGROUND)
    uavs_px = to_px(np.asarray(uavs_m, dtype=np.float64).reshape(-1, 2))
    if coverage_radius_m > 0 and len(uavs_px):
        overlay = Image.new("RGBA", image.size, (0, 0, 0, 0))
        draw = ImageDraw.Draw(overlay)
        r_px = coverage_radius_m * scale
        for x, y in uavs_px:
            draw.ellipse((x - r_px, y - r_px, x + r_px, y + r_px), fill=_DISC, outline=_DISC_EDGE)
        image.paste(overlay, mask=overlay)
    draw = ImageDraw.Draw(image)
    obstacles = np.asarray(obstacles_m, dtype=np.float64).reshape(-1, 4)
    for (x1, y1), (x2, y2) in zip(to_px(obstacles[:, :2]), to_px(obstacles[:, 2:]), strict=True):
        draw.line((x1, y1, x2, y2), fill=_OBSTACLE, width=2)

    frame = np.asarray(image).copy()
    peds_px = to_px(np.asarray(pedestrians_m, dtype=np.float64).reshape(-1, 2))
    cols = np.clip(peds_px[:, 0].astype(np.intp), 0, width_px - 2)
    rows = np.clip(peds_px[:, 1].astype(np.intp), 0, height_px - 2) if height_px > 1 else np.zeros_like(cols)
    colours = np.where(np.asarray(covered, dtype=bool)[:, None], _COVERED, _UNCOVERED)
    for dr in (0, 1) if height_px > 1 else (0,):
        for dc in (0, 1):
            frame[rows + dr, cols + dc] = colours

    image = Image.fromarray(frame)
    draw = ImageDraw.Draw(image)
    size = max(3.0, 0.012 * width_px)
    for x, y in uavs_px:
        diamond = [(x, y - size), (x + size, y), (x, y + size), (x - size, y)]
        draw.polygon(diamond, fill=_UAV, outline=(0, 0, 0))
    return np.asarray(image)


class HumanViewer:
    """A matplotlib window that shows successive frames.

    With a non-interactive matplotlib backend (e.g. ``Agg`` on a headless machine) there is
    no window: frames are dropped and a warning is logged once.

    Args:
        title: Window title.
        fps: Frames per second to pace the display.
    """

    def __init__(self, title: str, fps: float) -> None:
        self._title = title
        self._pause_s = 1.0 / fps
        self._figure: Any = None
        self._artist: Any = None
        self._warned = False

    def show(self, frame: np.ndarray) -> None:
        """Display ``frame`` (H, W, 3 uint8), opening the window on the first call."""
        import matplotlib
        import matplotlib.pyplot as plt

        if matplotlib.get_backend().lower() in _NON_INTERACTIVE_BACKENDS:
            if not self._warned:
                logger.warning("matplotlib backend %r cannot show windows: human rendering shows nothing",
                               matplotlib.get_backend())
                self._warned = True
            return
        if self._figure is None or not plt.fignum_exists(self._figure.number):
            self._figure, ax = plt.subplots(num=self._title)
            ax.set_axis_off()
            self._artist = ax.imshow(frame)
            plt.show(block=False)
        else:
            self._artist.set_data(frame)
        self._figure.canvas.draw_idle()
        plt.pause(self._pause_s)

    def close(self) -> None:
        """Close the window if it is open."""
        if self._figure is not None:
            import matplotlib.pyplot as plt

            plt.close(self._figure)
            self._figure = None
            self._artist = None
