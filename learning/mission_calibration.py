"""Choosing a checkpoint's mission operating point: the peak settings that serve the mission best.

Training calibrates the peak thresholds for correspondence + precision (:mod:`learning.calibrate`,
the *balanced* point). The mission is judged by its QoS, and a placement with one guard too few
fails a building where one with a guard too many covers it: the best operating point for the
mission sits elsewhere. :func:`calibrate_mission` scores a grid of peak settings
(``threshold_abs`` x ``min_contrast`` x ``min_distance_px``) on the checkpoint's validation split
(the scenes ``train`` held out with the checkpoint's own ``seed`` and ``val_fraction``, regenerated
from their seeds and cached, so a killed run resumes) with QoS judged exactly on each regenerated
scene, and chooses by one rule:

    among the points whose correspondence and precision, each less its margin, both reach their
    floors (a metric's floor is the paper's figure for the task, or the balanced point's own value
    less its margin where that is lower, so the balanced point itself always qualifies), the point
    that promises the most of the paper's columns, then the highest mean QoS;

ties go to the higher correspondence + precision, then to the first grid point.

**The margin** keeps a choice made on validation scenes from falling short on held-out ones: a
point's validation mean is a draw, and so is the held-out row it will be judged by. A column's margin
is ``margin_z`` standard errors of the difference between two independent means over as many
scenes as the validation: ``margin_z * sqrt(2) * se``, ``se`` the standard error of the point's
validation mean (for QoS, of the per-scene difference to the expert, over the expert's mean QoS,
since the QoS column is relative to the expert). The default ``margin_z = 2.0`` leaves a held-out
row of as many scenes below a promised column in about 2.3 % of draws per column (a normal
approximation); 0 gives the choice without a margin. A point **promises** a column (corr,
precision, QoS) when its validation value less the margin is at least the paper's; ``evaluate``
says which columns the point that ran promises.

The report holds every point (with its standard errors), the balanced point's scores on the same
scenes and the front of QoS against precision (the points no other point beats on both).

Examples:
    >>> balanced = {"corr": 0.9, "precision": 0.9, "qos": 0.5}
    >>> rows = [{"corr": 0.92, "precision": 0.85, "qos": 0.7}, {"corr": 0.95, "precision": 0.8, "qos": 0.9}]
    >>> choose_mission_point(rows, {"corr": 0.91, "precision": 0.82}, balanced)["qos"]  # 0.8 < 0.82
    0.7
    >>> row = {"corr": 0.93, "corr_se": 0.005, "precision": 0.83, "precision_se": 0.005,
    ...        "qos_relative": 0.99, "qos_relative_se": 0.001}
    >>> promised_columns(row, {"corr": 0.91, "precision": 0.82, "qos": 0.97}, margin_z=2.0)
    ['corr', 'qos']
"""

from __future__ import annotations

import hashlib
import json
import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import numpy as np
from tqdm.auto import tqdm

from learning.checkpoint import Checkpoint, checkpoint_label
from learning.data import generate_samples
from learning.inference import utility_maps
from learning.metrics import MATCH_FRACTION, aggregate, score_sample
from learning.peaks import PEAK_REGIONS, PeakConfig, find_peaks
from learning.precision import resolve_precision
from learning.task import Task
from learning.train import TrainConfig, split_indices
from typed_config import Config, ConfigError, param
from typed_config.files import atomic_path

__all__ = ["MissionGrid", "MARGIN_Z", "COLUMNS", "score_grid", "margins", "promised_columns",
           "floors", "choose_mission_point", "pareto_front", "validation_samples", "calibrate_mission"]

log = logging.getLogger(__name__)

_CHUNK = 100
"""Validation scenes per cache file."""

MARGIN_Z = 2.0
"""Default margin, in standard errors of a validation-against-held-out difference (module docstring)."""

COLUMNS = {"corr": "corr", "precision": "precision", "qos": "qos_relative"}
"""The paper's columns and the row key each is judged by (QoS relative to the expert)."""


@dataclass(frozen=True)
class MissionGrid(Config):
    """The peak settings tried for the mission point (utility-map units and pixels)."""

    thresholds: tuple[float, ...] = param((0.01, 0.02, 0.03, 0.05, 0.08, 0.1, 0.15, 0.2, 0.3),
                                          doc="threshold_abs values tried")
    contrasts: tuple[float, ...] = param((0.0, 0.02, 0.05), doc="min_contrast values tried")
    distances_px: tuple[int, ...] = param((1, 2, 3, 4), doc="min_distance_px values tried")
    regions: tuple[str, ...] = param(("any",), doc="region values tried (learning.peaks.PEAK_REGIONS)")

    def check(self) -> None:
        """Every grid is non-empty and in PeakConfig's ranges."""
        if not self.thresholds or not self.contrasts or not self.distances_px:
            raise ConfigError("MissionGrid.thresholds, .contrasts and .distances_px must each hold a value")
        if min(self.contrasts) < 0.0 or min(self.distances_px) < 1:
            raise ConfigError(f"MissionGrid: contrasts {self.contrasts} must be >= 0 and distances_px "
                              f"{self.distances_px} >= 1")
        if not self.regions or not set(self.regions) <= set(PEAK_REGIONS):
            raise ConfigError(f"MissionGrid.regions = {self.regions}: choose among {list(PEAK_REGIONS)}")

    def configs(self, base: PeakConfig) -> list[PeakConfig]:
        """``base`` with each grid point's values, in grid order."""
        return [base.replace(threshold_abs=t, min_contrast=c, min_distance_px=d, region=r)
                for r in self.regions for t in self.thresholds for c in self.contrasts
                for d in self.distances_px]


def score_grid(task: Task, utilities: np.ndarray, arrays: Mapping[str, np.ndarray],
               configs: Sequence[PeakConfig], progress: bool = False) -> list[dict[str, Any]]:
    """Correspondence, precision and exact QoS of each peak config on the scenes of ``arrays``.

    Args:
        task: Regenerates each scene from its stored seed and judges QoS on it.
        utilities: ``(n, h, w)`` utility maps of the scenes.
        arrays: ``inputs``, ``positions``, ``mask`` and ``seeds`` of the scenes (a dataset's arrays).
        configs: The settings scored.
        progress: Show a progress bar (on a terminal only: none in a log or a pipe).

    Returns:
        One row per config: its settings, ``corr``, ``precision`` (means over scenes, the paper's rule),
        ``n_predicted``, ``qos`` (mean), ``expert_qos``, ``qos_relative`` and the standard errors of
        the means ``corr_se``, ``precision_se``, ``qos_relative_se`` (module docstring).
    """
    n = len(utilities)
    scenes = [task.sample(np.random.default_rng(int(arrays["seeds"][i]))) for i in range(n)]
    experts = [arrays["positions"][i][arrays["mask"][i]] for i in range(n)]
    expert_each = np.array([task.qos(s, e)["qos"] for s, e in zip(scenes, experts, strict=True)])
    expert_qos = float(np.mean(expert_each))
    eps_px = MATCH_FRACTION * task.mission_dimension_px
    judged: list[dict[bytes, float]] = [{} for _ in range(n)]  # the same placement is judged once

    def qos(i: int, placement: np.ndarray) -> float:
        key = placement.tobytes()
        if key not in judged[i]:
            judged[i][key] = float(task.qos(scenes[i], placement)["qos"])
        return judged[i][key]

    rows = []
    for config in tqdm(configs, disable=None if progress else True, desc="grid", unit="point"):
        predicted = [find_peaks(u, config, raster=x)
                     for u, x in zip(utilities, arrays["inputs"], strict=True)]
        scores = [score_sample(e, p, eps_px) for e, p in zip(experts, predicted, strict=True)]
        summary = aggregate(scores)
        each = np.array([qos(i, p) for i, p in enumerate(predicted)])
        mean_qos = float(np.mean(each))
        rows.append({**config.to_dict(), "corr": summary["corr"], "precision": summary["precision"],
                     "n_predicted": summary["n_predicted"], "qos": mean_qos, "expert_qos": expert_qos,
                     "qos_relative": mean_qos / expert_qos if expert_qos > 0 else 1.0,
                     "corr_se": _standard_error([s.corr for s in scores]),
                     "precision_se": _standard_error([s.precision for s in scores]),
                     "qos_relative_se": _standard_error(each - expert_each) / expert_qos if expert_qos > 0
                     else 0.0})
    return rows


def _standard_error(values: Sequence[float] | np.ndarray) -> float:
    """The standard error of the mean of ``values`` (0 for fewer than two)."""
    values = np.asarray(values, dtype=np.float64)
    return float(np.std(values, ddof=1) / np.sqrt(len(values))) if len(values) > 1 else 0.0


def margins(row: Mapping[str, Any], margin_z: float) -> dict[str, float]:
    """Each column's margin for ``row`` (module docstring); a row without standard errors has none.

    >>> margins({"corr_se": 0.01, "precision_se": 0.0}, 2.0)["corr"]  # 2 * sqrt(2) * 0.01
    0.028284271247461905
    """
    return {column: margin_z * float(np.sqrt(2.0)) * float(row.get(f"{key}_se", 0.0))
            for column, key in COLUMNS.items()}


def promised_columns(row: Mapping[str, Any], paper: Mapping[str, float], margin_z: float) -> list[str]:
    """The paper's columns (``corr``, ``precision``, ``qos``) that ``row``, less its margins, reaches."""
    margin = margins(row, margin_z)
    return [column for column, key in COLUMNS.items()
            if column in paper and key in row and row[key] - margin[column] >= paper[column] - 1e-12]


def floors(paper: Mapping[str, float], balanced: Mapping[str, Any], margin_z: float = 0.0
           ) -> dict[str, float]:
    """The corr and precision floors of the rule: the paper's, or the balanced point's less its margin."""
    margin = margins(balanced, margin_z)
    return {key: min(paper[key], balanced[key] - margin[key]) for key in ("corr", "precision")}


def choose_mission_point(rows: Sequence[Mapping[str, Any]], paper: Mapping[str, float],
                         balanced: Mapping[str, Any], margin_z: float = 0.0) -> Mapping[str, Any]:
    """The row chosen by the module docstring's rule (``paper``: the floors and the promised columns).

    The balanced point is a candidate too (last), so the choice never promises fewer columns than it,
    nor, promising as many, has a lower QoS.
    """
    floor = floors(paper, balanced, margin_z)

    def reaches(row: Mapping[str, Any]) -> bool:
        margin = margins(row, margin_z)
        return all(row[key] - margin[key] >= floor[key] - 1e-12 for key in floor)

    def rank(row: Mapping[str, Any]) -> tuple[int, float, float]:
        return len(promised_columns(row, paper, margin_z)), row["qos"], row["corr"] + row["precision"]

    candidates = [r for r in rows if reaches(r)] + [balanced]
    best = candidates[0]
    for row in candidates[1:]:  # strictly better only: ties keep the earlier row
        if rank(row) > rank(best):
            best = row
    return best


def pareto_front(rows: Sequence[Mapping[str, Any]]) -> list[Mapping[str, Any]]:
    """The rows no other row beats on both precision and QoS, by increasing precision."""
    ordered = sorted(rows, key=lambda r: (-r["precision"], -r["qos"]))
    front, best_qos = [], -1.0
    for row in ordered:
        if row["qos"] > best_qos:
            front.append(row)
            best_qos = row["qos"]
    return front[::-1]


def validation_samples(ckpt: Checkpoint, task: Task, n: int | None, cache_dir: str | Path,
                       progress: bool = True) -> dict[str, np.ndarray]:
    """The checkpoint's first ``n`` validation samples, regenerated from their seeds (cached, resumable).

    The validation split is the one ``train`` held out: the indices ``split_indices`` gives for the
    checkpoint's dataset size and training config. Chunks of ``_CHUNK`` samples are written atomically
    to ``cache_dir``, named by the task config and dataset; a rerun loads the chunks already there.
    """
    data = ckpt.payload["data"]
    _, val = split_indices(int(data["n"]), TrainConfig.from_dict(ckpt.payload["train_config"]))
    val = val[:n] if n is not None else val
    cache = Path(cache_dir)
    described = json.dumps([task.config.to_dict(), data], sort_keys=True, default=str)
    identity = hashlib.sha256(described.encode()).hexdigest()[:12]  # the task config and dataset
    cache.mkdir(parents=True, exist_ok=True)
    parts: list[dict[str, np.ndarray]] = []
    chunks = range(0, len(val), _CHUNK)
    for start in tqdm(chunks, disable=None if progress else True, desc=f"{task.name} validation",
                      unit="chunk"):
        indices = val[start:start + _CHUNK]
        path = cache / f"{task.name}-{identity}-val-{start // _CHUNK:05d}.npz"
        if path.is_file():
            with np.load(path, allow_pickle=False) as stored:
                if np.array_equal(stored["indices"], indices):
                    parts.append({key: stored[key] for key in stored.files})
                    continue
        arrays = generate_samples(lambda: task, int(data["seed"]), str(data["split"]), indices.tolist())
        with atomic_path(path) as tmp, open(tmp, "wb") as f:
            np.savez(f, **cast(dict[str, Any], arrays))  # the stubs read a key as savez's own flags
        parts.append(arrays)
    return {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}


def calibrate_mission(ckpt: Checkpoint, task: Task, paper: Mapping[str, float], cache_dir: str | Path, *,
                      n: int | None = None, grid: MissionGrid | None = None, precision: str = "auto",
                      margin_z: float = MARGIN_Z, progress: bool = True) -> dict[str, Any]:
    """Score ``grid`` and the balanced point on the validation split and choose the mission point.

    Args:
        ckpt: The checkpoint (its ``peak_config`` is the balanced point).
        task: Its task, as trained.
        paper: The paper's ``corr`` and ``precision`` for the task (fractions), the floors.
        cache_dir: Where the regenerated validation samples are cached.
        n: At most this many validation scenes (default: all).
        grid: The settings tried; default ``MissionGrid()``.
        precision: Network precision (``"auto"``: bfloat16 where native, as ``evaluate``).
        margin_z: The margin, in standard errors (module docstring; 0: none).
        progress: Show progress bars (on a terminal only: none in a log or a pipe).

    Returns:
        ``{"task", "checkpoint", "n_validation", "paper", "margin_z", "floors", "balanced", "mission",
        "front", "rows"}``; ``mission`` and ``balanced`` are rows (settings and scores) with their
        ``margins`` and the columns each ``promises``.

    Raises:
        ValueError: ``margin_z < 0``.
    """
    if not margin_z >= 0.0:
        raise ValueError(f"margin_z = {margin_z}: the margin must be >= 0 standard errors")
    grid = grid or MissionGrid()
    arrays = validation_samples(ckpt, task, n, cache_dir, progress)
    resolved = resolve_precision(precision, next(ckpt.model.parameters()).device)
    utilities = utility_maps(ckpt.model, arrays["inputs"], resolved)
    configs = grid.configs(ckpt.peak_config)
    balanced = score_grid(task, utilities, arrays, [ckpt.peak_config])[0]
    rows = score_grid(task, utilities, arrays, configs, progress)
    mission = dict(choose_mission_point(rows, paper, balanced, margin_z))
    for row in (mission, balanced):
        row.update(margins=margins(row, margin_z), promises=promised_columns(row, paper, margin_z))
    log.info("%s: mission point %s (QoS %.3f) against balanced QoS %.3f", task.name,
             {k: mission[k] for k in ("threshold_abs", "min_contrast", "min_distance_px")}, mission["qos"],
             balanced["qos"])
    return {"task": task.name, "checkpoint": checkpoint_label(ckpt.path), "n_validation": len(utilities),
            "validation": {**ckpt.payload["data"], "indices": "the first n of split_indices (train_config)"},
            "network_precision": resolved, "paper": dict(paper), "margin_z": margin_z,
            "floors": floors(paper, balanced, margin_z), "balanced": balanced, "mission": mission,
            "front": [dict(r) for r in pareto_front(rows)], "rows": rows}
