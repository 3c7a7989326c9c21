"""Pictures of predictions (input, utility map, expert and predicted positions) and of training curves.

Uses matplotlib's object API with the Agg canvas (no pyplot, no global backend change).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from typed_config.files import atomic_path

__all__ = ["plot_examples", "plot_history"]


def plot_examples(
    path: str | Path,
    inputs: np.ndarray,
    utilities: np.ndarray,
    experts: Sequence[np.ndarray],
    predictions: Sequence[np.ndarray],
    titles: Sequence[str],
) -> None:
    """Write a PNG with one row per example: input (channels summed) and utility map.

    Both panels show the expert positions (white circles) and the predicted positions (red crosses).

    Args:
        path: Output ``.png`` (written atomically).
        inputs: ``(n, C, h, w)`` rasters.
        utilities: ``(n, h, w)`` utility maps.
        experts: ``n`` arrays ``(k, 2)`` of pixel ``(x, y)``.
        predictions: ``n`` arrays ``(m, 2)`` of pixel ``(x, y)``.
        titles: ``n`` row captions.
    """
    n = len(inputs)
    fig = Figure(figsize=(6.0, 3.0 * max(n, 1)), dpi=80)
    FigureCanvasAgg(fig)
    for i in range(n):
        for j, (image, label) in enumerate(((inputs[i].sum(axis=0), "input"), (utilities[i], "utility"))):
            ax = fig.add_subplot(n, 2, 2 * i + j + 1)
            ax.imshow(image, origin="lower", cmap="viridis", interpolation="nearest")
            ex, pr = np.reshape(experts[i], (-1, 2)), np.reshape(predictions[i], (-1, 2))
            ax.scatter(ex[:, 0], ex[:, 1], s=60, facecolors="none", edgecolors="white", linewidths=1.5)
            ax.scatter(pr[:, 0], pr[:, 1], s=40, marker="x", c="red", linewidths=1.5)
            ax.set_title(f"{titles[i]}: {label}", fontsize=8)
            ax.set_xticks([])
            ax.set_yticks([])
    fig.tight_layout()
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")


def plot_history(path: str | Path, history: Sequence[dict[str, float]], title: str = "") -> None:
    """Write a PNG of a training run's curves against the training samples seen.

    Top: validation correspondence and precision (the paper's matching rule); bottom: training
    and validation MSE (log scale).

    Args:
        path: Output ``.png`` (written atomically).
        history: Per-epoch records of :func:`learning.train.train` (``samples`` or ``step``,
            ``train_loss`` and, with a validation split, ``val_loss``, ``val_corr``, ``val_precision``).
        title: Figure title.
    """
    x = np.array([h.get("samples", h["step"]) for h in history], dtype=np.float64)
    fig = Figure(figsize=(6.0, 5.0), dpi=100)
    FigureCanvasAgg(fig)
    top, bottom = fig.add_subplot(2, 1, 1), fig.add_subplot(2, 1, 2)
    for key, label in (("val_corr", "validation correspondence"), ("val_precision", "validation precision")):
        if all(key in h for h in history):
            top.plot(x, [100 * h[key] for h in history], marker="o", markersize=3, label=label)
    top.set_ylabel("%")
    top.grid(alpha=0.3)
    top.legend(fontsize=8)
    for key, label in (("train_loss", "training MSE"), ("val_loss", "validation MSE")):
        if all(key in h for h in history):
            bottom.plot(x, [h[key] for h in history], marker="o", markersize=3, label=label)
    bottom.set_yscale("log")
    bottom.set_xlabel("training samples seen")
    bottom.grid(alpha=0.3)
    bottom.legend(fontsize=8)
    if title:
        top.set_title(title, fontsize=10)
    fig.tight_layout()
    with atomic_path(Path(path)) as tmp:
        fig.savefig(tmp, format="png")
