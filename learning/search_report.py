"""The report of an (α2, σ2) grid search: summary, α2-rise, rule of thumb and heat map.

- α2-rise: best minus worst validation correspondence over the grid, in percentage points
  (the paper's measure of how much the second Gaussian matters).
- Best point: the highest correspondence, ties broken by precision, then by grid order
  (the paper's ranking).
- Best point by F1: the highest harmonic mean of correspondence and precision, ties broken
  by correspondence, then by grid order. Correspondence alone rewards a network that
  spreads many weak peaks (a short training on wide targets does); F1 also charges for the
  peaks that match no expert, and is the rule the shipped task configs follow.
- Rule of thumb (the paper's): α2 ≈ a quarter of the mean distance between expert
  positions, in pixels. The mean distance is computed per scene (mean over the pairs
  of its expert positions, scenes with at least two positions) and averaged over the
  dataset's scenes.

Files written in the search folder: ``summary.json``, ``summary.md`` and ``heatmap.png``.
"""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from typed_config.files import atomic_path, write_json_atomic, write_text_atomic

if TYPE_CHECKING:
    from learning.search_grid import SearchConfig
    from learning.train import TrainConfig

__all__ = ["mean_expert_distance_px", "f1_score", "summarise", "heatmap_figure", "plot_heatmap",
           "markdown_summary", "write_report"]


def mean_expert_distance_px(positions_px: np.ndarray, mask: np.ndarray) -> float:
    """Mean over scenes of the mean pairwise distance between a scene's expert positions.

    Args:
        positions_px: ``(n, k, 2)`` pixel positions.
        mask: ``(n, k)`` which positions are real.

    Returns:
        The mean distance in pixels; NaN when no scene has two positions.

    Examples:
        >>> p = np.array([[[0.0, 0.0], [3.0, 4.0], [0.0, 0.0]], [[1.0, 1.0], [0.0, 0.0], [0.0, 0.0]]])
        >>> mean_expert_distance_px(p, np.array([[True, True, False], [True, False, False]]))
        5.0
    """
    per_scene = []
    for points, keep in zip(positions_px, mask, strict=True):
        points = points[keep]  # (m, 2)
        if len(points) >= 2:
            d = np.linalg.norm(points[:, None] - points[None], axis=-1)  # (m, m)
            per_scene.append(d[np.triu_indices(len(points), 1)].mean())
    return float(np.mean(per_scene)) if per_scene else float("nan")


def _best_index(primary: np.ndarray, secondary: np.ndarray) -> int:
    """Index of the highest ``primary``, then ``secondary``; the first in order among equals."""
    order = sorted(range(len(primary)), key=lambda i: (-primary[i], -secondary[i], i))
    return order[0]


def f1_score(corr: np.ndarray, precision: np.ndarray) -> np.ndarray:
    """Harmonic mean of correspondence and precision, element-wise (0 where both are 0).

    Examples:
        >>> f1_score(np.array([0.5, 0.0]), np.array([1.0, 0.0])).round(3).tolist()
        [0.667, 0.0]
    """
    corr, precision = np.asarray(corr, np.float64), np.asarray(precision, np.float64)
    total = corr + precision
    return np.divide(2.0 * corr * precision, total, out=np.zeros_like(total), where=total > 0)


def summarise(search_config: SearchConfig, trials: Sequence[dict[str, Any]], manifest: dict[str, Any],
              mean_distance_px: float, budget: dict[str, Any], executor: str) -> dict[str, Any]:
    """The search's summary: score grids, best (by corr, by F1) and worst points, α2-rise, rule of thumb.

    Args:
        search_config: The grid.
        trials: One finished trial per grid point, α2-major (as ``search_config.points``).
        manifest: The dataset's manifest.
        mean_distance_px: See :func:`mean_expert_distance_px`.
        budget: The per-trial training budget, stated in the report.
        executor: Where the trials ran.
    """
    alphas, sigmas = search_config.alpha2_values, search_config.sigma2_values
    corr = np.array([t["corr"] for t in trials])
    precision = np.array([t["precision"] for t in trials])
    f1 = f1_score(corr, precision)
    best, worst = _best_index(corr, precision), int(np.argmin(corr))
    best_f1 = _best_index(f1, corr)
    rule_alpha2 = mean_distance_px / 4.0
    nearest = min(alphas, key=lambda a: abs(a - rule_alpha2)) if np.isfinite(rule_alpha2) else None

    def point(i: int) -> dict[str, float]:
        return {**{k: trials[i][k] for k in ("alpha2", "sigma2", "corr", "precision")}, "f1": float(f1[i])}

    return {
        "task": manifest["task"],
        "data": {"n": manifest["n"], "seed": manifest["seed"], "split": manifest["split"],
                 "shape": manifest["shape"]},
        "grid": {"alpha2": list(alphas), "sigma2": list(sigmas), "rows": "alpha2", "columns": "sigma2"},
        "budget": budget,
        "executor": executor,
        "threads_per_trial": search_config.threads,
        "corr": corr.reshape(len(alphas), len(sigmas)).tolist(),
        "precision": precision.reshape(len(alphas), len(sigmas)).tolist(),
        "f1": f1.reshape(len(alphas), len(sigmas)).tolist(),
        "best": point(best),
        "best_f1": point(best_f1),
        "worst": point(worst),
        "alpha2_rise_pts": float(100.0 * (corr[best] - corr[worst])),
        "rule_of_thumb": {"mean_expert_distance_px": mean_distance_px, "alpha2": rule_alpha2,
                          "nearest_grid_alpha2": nearest},
        "total_train_s": float(sum(t["train_s"] for t in trials)),
    }


_TITLE_PT = 8.0
_MIN_WIDTH_IN = 4.5


def _wrapped(lines: Sequence[str], width_in: float) -> str:
    """``lines`` wrapped to fit ``width_in`` inches at the title's font size (a wide glyph: 0.62 em)."""
    chars = max(20, int(0.95 * width_in * 72.0 / (0.62 * _TITLE_PT)))
    return "\n".join(part for line in lines for part in textwrap.wrap(line, chars))


def heatmap_figure(summary: dict[str, Any]) -> Figure:
    """The correspondence heat map (rows α2, columns σ2, values in %) as a figure.

    The best cell by correspondence is framed in solid blue, the best by F1 in dashed black. The
    title spans the figure and wraps to its width, so a grid of one or two columns shows it whole.

    Args:
        summary: As returned by :func:`summarise`.
    """
    alphas, sigmas = summary["grid"]["alpha2"], summary["grid"]["sigma2"]
    corr = 100.0 * np.asarray(summary["corr"])  # (len(alphas), len(sigmas))
    width_in = max(_MIN_WIDTH_IN, 2.2 + 0.9 * len(sigmas))
    best, best_f1, budget = summary["best"], summary["best_f1"], summary["budget"]
    title = _wrapped([
        f"{summary['task']}: best α2={best['alpha2']:g}, σ2={best['sigma2']:g}; "
        f"α2-rise {summary['alpha2_rise_pts']:+.1f} pts",
        f"best F1 (dashed) α2={best_f1['alpha2']:g}, σ2={best_f1['sigma2']:g}",
        f"per trial: {budget['steps_run']} steps of batch {budget['batch_size']} "
        f"on {budget['n_train']} scenes",
    ], width_in)
    n_title_lines = title.count("\n") + 1
    fig = Figure(figsize=(width_in, 1.2 + 0.7 * len(alphas) + 0.16 * n_title_lines), dpi=100,
                 layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    image = ax.imshow(corr, origin="lower", cmap="RdYlGn", aspect="auto")
    fig.colorbar(image, ax=ax, label="correspondence %")
    for i in range(len(alphas)):
        for j in range(len(sigmas)):
            ax.text(j, i, f"{corr[i, j]:.1f}", ha="center", va="center", fontsize=8)
    bi, bj = alphas.index(best["alpha2"]), sigmas.index(best["sigma2"])
    ax.add_patch(Rectangle((bj - 0.5, bi - 0.5), 1, 1, fill=False, edgecolor="blue", linewidth=2.5))
    fi, fj = alphas.index(best_f1["alpha2"]), sigmas.index(best_f1["sigma2"])
    ax.add_patch(Rectangle((fj - 0.4, fi - 0.4), 0.8, 0.8, fill=False, edgecolor="black", linewidth=1.5,
                           linestyle="--"))
    ax.set_xticks(range(len(sigmas)), [f"{s:g}" for s in sigmas])
    ax.set_yticks(range(len(alphas)), [f"{a:g}" for a in alphas])
    ax.set_xlabel("σ2 (px)")
    ax.set_ylabel("α2")
    fig.suptitle(title, fontsize=_TITLE_PT)
    return fig


def plot_heatmap(path: str | Path, summary: dict[str, Any]) -> None:
    """Write :func:`heatmap_figure` as a PNG.

    Args:
        path: Output ``.png`` (written atomically).
        summary: As returned by :func:`summarise`.
    """
    fig = heatmap_figure(summary)
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")


def markdown_summary(summary: dict[str, Any]) -> str:
    """The summary as Markdown: headline numbers, budget, and the correspondence, precision and F1 tables."""
    best, best_f1 = summary["best"], summary["best_f1"]
    rule, budget = summary["rule_of_thumb"], summary["budget"]
    sigmas = summary["grid"]["sigma2"]
    lines = [
        f"# (α2, σ2) grid search: {summary['task']}", "",
        f"- best (α2, σ2): ({best['alpha2']:g}, {best['sigma2']:g}), validation correspondence "
        f"{100 * best['corr']:.1f} %, precision {100 * best['precision']:.1f} %",
        f"- best (α2, σ2) by F1 of correspondence and precision: ({best_f1['alpha2']:g}, "
        f"{best_f1['sigma2']:g}), correspondence {100 * best_f1['corr']:.1f} %, precision "
        f"{100 * best_f1['precision']:.1f} %, F1 {100 * best_f1['f1']:.1f} %",
        f"- α2-rise (best minus worst correspondence): {summary['alpha2_rise_pts']:+.1f} points",
        f"- rule of thumb: mean distance between expert positions {rule['mean_expert_distance_px']:.1f} px, "
        f"so α2 ≈ {rule['alpha2']:.1f} (nearest grid value {rule['nearest_grid_alpha2']:g})",
        f"- budget per trial (may be reduced from a full training): {budget['text']}",
        f"- executor: {summary['executor']}, {summary['threads_per_trial']} torch thread(s) per trial, "
        f"{summary['total_train_s']:.0f} s of training in all", "",
    ]
    for key, title in (("corr", "correspondence"), ("precision", "precision"), ("f1", "F1")):
        lines += [f"Validation {title} % (rows α2, columns σ2):", "",
                  "| α2 \\ σ2 | " + " | ".join(f"{s:g}" for s in sigmas) + " |",
                  "|---|" + "---|" * len(sigmas)]
        for alpha, row in zip(summary["grid"]["alpha2"], summary[key], strict=True):
            lines.append(f"| {alpha:g} | " + " | ".join(f"{100 * v:.1f}" for v in row) + " |")
        lines.append("")
    return "\n".join(lines)


def write_report(out_dir: Path, search_config: SearchConfig, trials: Sequence[dict[str, Any]],
                 manifest: dict[str, Any], positions_px: np.ndarray, mask: np.ndarray,
                 train_config: TrainConfig, executor: str) -> dict[str, Any]:
    """Summarise a finished search into ``summary.json``, ``summary.md`` and ``heatmap.png``.

    Args:
        out_dir: The search folder.
        search_config: The grid.
        trials: One finished trial per grid point, α2-major.
        manifest: The dataset's manifest.
        positions_px: ``(n, k, 2)`` the dataset's expert positions (for the rule of thumb).
        mask: ``(n, k)`` which positions are real.
        train_config: The per-trial budget.
        executor: Where the trials ran.
    """
    n = manifest["n"]
    n_val = min(n - 1, max(1, round(train_config.val_fraction * n))) if n > 1 else 0
    epochs = f"{train_config.epochs} epoch(s)" + (
        f", at most {train_config.max_steps} step(s)" if train_config.max_steps else "")
    steps = trials[0]["steps"] if trials else 0
    budget = {
        "epochs": train_config.epochs, "max_steps": train_config.max_steps,
        "batch_size": train_config.batch_size, "lr": train_config.lr, "schedule": train_config.schedule,
        "seed": train_config.seed, "n_train": n - n_val, "n_val": n_val,
        "steps_run": steps,
        "text": f"{epochs} of batch {train_config.batch_size} ({steps} steps run) "
                f"on {n - n_val} scenes, scored on {n_val} validation scenes (seed {train_config.seed})",
    }
    distance = mean_expert_distance_px(positions_px, mask)
    summary = summarise(search_config, trials, manifest, distance, budget, executor)
    write_json_atomic(out_dir / "summary.json", summary)
    write_text_atomic(out_dir / "summary.md", markdown_summary(summary))
    plot_heatmap(out_dir / "heatmap.png", summary)
    return summary
