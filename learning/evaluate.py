"""Evaluating a checkpoint on held-out scenes: metrics, QoS, results files and pictures.

The test set is a dataset of ``split="test"`` (by default generated into
``out_dir/test-data`` with the same resumable machinery as training data). Its
sample seeds live in another namespace than the training split's, and
:func:`evaluate` checks that none of them is a seed of the checkpoint's training
dataset, so the test scenes are ones training never saw.

For each scene: the model's peaks are the prediction (optionally with test-time
augmentation, :mod:`learning.inference`); the scene is regenerated from its stored
seed to judge the QoS of both the prediction and the expert on the real scene.
Correspondence and precision follow the paper's matching rule (least total distance,
then pairs within ε; :mod:`learning.metrics`); the rule that maximises the matches is
reported beside it (``max_matches``). Outputs in ``out_dir``:

- ``results.json``: per-sample seed, expert and predicted pixel positions, counts,
  corr, precision and QoS dicts, plus ε and the configs: enough to recompute every metric;
- ``summary.json`` and ``results.md``: the peak settings that ran and their source (``peaks``), the
  aggregates (means of per-sample corr and
  precision as in the paper, pooled ratios too; QoS absolute as the mean over scenes
  and relative as mean QoS / mean expert QoS, plus the mean of per-scene ratios);
- ``examples.png``: the first scenes' input, utility map, expert and predicted positions.

With a ``refiner`` (the mission's repair or local search, :class:`learning.task.Refiner`) every
scene is also refined from its learned positions, and each pipeline is timed on its own: the
learned one (network on that scene alone, then peaks), the refined one (the same plus the
refinement) and the expert solving the scene from scratch (``Refiner.solve``); the network then
runs on one thread, as the planner runs it. ``summary.json``
then holds ``learned`` and ``refined`` side by side (corr, precision, QoS, relative QoS,
positions, median and p95 time) and ``expert`` (positions, QoS, times).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, Literal

import numpy as np
import torch
from tqdm.auto import tqdm

from learning.checkpoint import checkpoint_label, load_checkpoint
from learning.data import generate_dataset, load_arrays, sample_seed
from learning.inference import utility_maps
from learning.metrics import MATCH_FRACTION, SampleScore, aggregate, score_sample
from learning.mission_calibration import COLUMNS
from learning.model import with_memory_format
from learning.operating_points import choose_peaks, point_promises
from learning.peaks import PeakConfig, find_peaks
from learning.plots import plot_examples
from learning.precision import resolve_precision
from learning.task import PlacementCheck, Refiner, Task
from typed_config.files import write_json_atomic, write_text_atomic

__all__ = ["evaluate", "summarise_qos", "summarise_pipeline", "markdown_table"]

log = logging.getLogger(__name__)


def summarise_qos(samples: list[dict[str, Any]]) -> dict[str, float]:
    """QoS aggregates of per-sample ``qos`` / ``expert_qos`` dicts (keys common to all samples)."""
    keys = set.intersection(*(set(s["qos"]) & set(s["expert_qos"]) for s in samples))
    out: dict[str, float] = {}
    for key in sorted(keys):
        pred = np.array([s["qos"][key] for s in samples], dtype=np.float64)
        expert = np.array([s["expert_qos"][key] for s in samples], dtype=np.float64)
        out[f"{key}"] = float(pred.mean())
        out[f"expert_{key}"] = float(expert.mean())
        out[f"{key}_relative"] = float(pred.mean() / expert.mean()) if expert.mean() > 0 else float("nan")
        positive = expert > 0
        per_scene = pred[positive] / expert[positive]
        out[f"{key}_relative_per_scene"] = float(per_scene.mean()) if positive.any() else float("nan")
    return out


def summarise_pipeline(scores: list[SampleScore], samples: list[dict[str, Any]], key: str
                       ) -> dict[str, Any]:
    """One pipeline's row: corr, precision, QoS (``samples[i][key]["qos"]``), positions and times.

    Args:
        scores: The pipeline's per-scene scores against the expert.
        samples: Per-scene records holding ``key`` (``{"positions", "qos", "time_ms"}``) and ``expert_qos``.
        key: ``"learned"`` or ``"refined"``.
    """
    qos = summarise_qos([{"qos": s[key]["qos"], "expert_qos": s["expert_qos"]} for s in samples])
    times = np.array([s[key]["time_ms"] for s in samples])
    n_positions = int(sum(len(s[key]["positions"]) for s in samples))
    n_expert = int(sum(len(s["expert"]) for s in samples))
    summary = aggregate(scores)
    row: dict[str, Any] = {}
    if "refine_ms" in samples[0][key]:  # the refinement alone, without the network and peaks before it
        refine = np.array([s[key]["refine_ms"] for s in samples])
        row = {"refine_time_median_ms": float(np.median(refine)),
               "refine_time_p95_ms": float(np.percentile(refine, 95))}
    return {**row, "corr": summary["corr"], "precision": summary["precision"], "qos": qos["qos"],
            "qos_relative": qos["qos_relative"], **{k: v for k, v in qos.items() if k.startswith("seen")},
            "n_positions": n_positions,
            "positions_vs_expert": n_positions / n_expert if n_expert else float("nan"),
            "time_median_ms": float(np.median(times)), "time_p95_ms": float(np.percentile(times, 95))}


def markdown_table(task_name: str, summary: dict[str, Any]) -> str:
    """The paper-style results table (percentages); with a refinement, the learned, refined and expert rows.

    Corr and precision by the paper's matching rule, then by the rule that maximises the matches; the
    peak settings that ran below the table.
    """
    def pct(key: str, table: dict[str, Any] = summary) -> str:
        value = table.get(key, float("nan"))
        return f"{100 * value:.1f}" if value == value else "n/a"

    best = summary.get("max_matches", {})
    table = (
        "| Task | Corr % | Precision % | QoS % | QoS rel. % | expert QoS % "
        "| corr / precision, max-matches rule % | scenes |\n"
        "|---|---|---|---|---|---|---|---|\n"
        f"| {task_name} | {pct('corr')} | {pct('precision')} | {pct('qos')} | {pct('qos_relative')} "
        f"| {pct('expert_qos')} | {pct('corr', best)} / {pct('precision', best)} | {summary['n_samples']} |\n"
    )
    if "peaks" in summary:
        peaks = summary["peaks"]
        settings = ", ".join(f"{k} {v}" for k, v in peaks["settings"].items())
        table += f"\nPeaks: {settings}; from the {peaks['source']}.\n"
    if "promises" in summary:
        table += f"\n{promises_line(summary['promises'])}\n"
    if "refined" not in summary:
        return table
    rows = ["| Placement | Corr % | Precision % | QoS % | QoS rel. % | positions (x expert) "
            "| median / p95 time, ms | speed-up vs expert (median) |", "|---|---|---|---|---|---|---|---|"]
    expert = summary["expert"]

    def alone(row: dict[str, Any]) -> str:
        if "refine_time_median_ms" not in row:
            return ""
        return (f" (refinement alone: {row['refine_time_median_ms']:.2f} ms, "
                f"{expert['time_median_ms'] / row['refine_time_median_ms']:.1f}x)")

    for name in ("learned", "refined"):
        row = summary[name]
        rows.append(f"| {name} | {pct('corr', row)} | {pct('precision', row)} | {pct('qos', row)} "
                    f"| {pct('qos_relative', row)} "
                    f"| {row['n_positions']} ({row['positions_vs_expert']:.3f}x) "
                    f"| {row['time_median_ms']:.2f} / {row['time_p95_ms']:.2f} "
                    f"| {expert['time_median_ms'] / row['time_median_ms']:.1f}x{alone(row)} |")
    rows.append(f"| expert | 100.0 | 100.0 | {pct('qos', expert)} | 100.0 | {expert['n_positions']} (1.000x) "
                f"| {expert['time_median_ms']:.2f} / {expert['time_p95_ms']:.2f} | 1.0x |")
    return table + "\n" + "\n".join(rows) + "\n"


def promises_line(promises: dict[str, Any]) -> str:
    """One line: the paper's columns the point promises, and how each held on these scenes.

    >>> promises_line({"columns": ["corr"], "paper": {"corr": 0.75}, "basis": "b",
    ...                "held": {"corr": {"value": 0.8, "met": True}}})
    'Promises (b): corr >= 75.0 % (here 80.0 %, held).'
    """
    if not promises["columns"]:
        return f"Promises: none of the paper's columns ({promises['basis']})."
    held = promises.get("held", {})
    parts = []
    for column in promises["columns"]:
        text = f"{column} >= {100 * promises['paper'][column]:.1f} %"
        if column in held:
            verdict = "held" if held[column]["met"] else "MISSED"
            text += f" (here {100 * held[column]['value']:.1f} %, {verdict})"
        parts.append(text)
    return f"Promises ({promises['basis']}): {'; '.join(parts)}."


def _learned(utility: np.ndarray, observation: np.ndarray, peaks: PeakConfig,
             check: PlacementCheck | None) -> np.ndarray:
    """The learned placement of one scene: the peaks of its utility map, checked if asked."""
    predicted = find_peaks(utility, peaks, raster=observation)
    return predicted if check is None else check(observation, predicted)


def _check_disjoint(train_data: dict[str, Any], test_seeds: np.ndarray) -> None:
    train_seeds = {sample_seed(train_data["seed"], train_data["split"], i) for i in range(train_data["n"])}
    shared = train_seeds.intersection(int(s) for s in test_seeds)
    if shared:
        raise ValueError(f"{len(shared)} test scene seed(s) were in the training dataset (seed "
                         f"{train_data['seed']}, split {train_data['split']!r}); use another seed or split")


def evaluate(
    checkpoint: str | Path,
    task_factory: Callable[[], Task],
    n: int,
    seed: int,
    out_dir: str | Path,
    *,
    split: str = "test",
    data_dir: str | Path | None = None,
    peak_overrides: Mapping[str, Any] | None = None,
    peaks_source: str = "config",
    operating_point: str | None = None,
    n_examples: int = 6,
    executor: Literal["local", "ray"] = "local",
    workers: int | None = None,
    address: str | None = None,
    precision: str = "auto",
    tta: bool = False,
    refiner: Refiner | None = None,
    check: PlacementCheck | None = None,
    progress: bool = True,
) -> dict[str, Any]:
    """Evaluate a checkpoint on ``n`` test scenes; write the results files into ``out_dir``.

    Args:
        checkpoint: A ``.pt`` file trained on this task.
        task_factory: Picklable zero-argument callable returning the task.
        n: Number of test scenes.
        seed: Test dataset seed.
        out_dir: Output folder (created if needed).
        split: Seed namespace of the test set (must differ from training's or use another seed).
        data_dir: Where the test dataset is (or is generated); default ``out_dir/test-data``.
        peak_overrides: Peak settings the user gave (a ``[peaks]`` table), applied over the operating
            point's (:func:`learning.operating_points.choose_peaks`).
        peaks_source: Where ``peak_overrides`` come from, in words (recorded in the summary).
        operating_point: The checkpoint's ``"mission"`` or ``"balanced"`` peak settings; default:
            mission where the checkpoint has it.
        n_examples: Scenes drawn in ``examples.png`` (0: no picture).
        executor: Executor for generating the test dataset.
        workers: Local worker processes for generating the test dataset.
        address: Ray address.
        precision: Network precision, ``"auto"`` (bfloat16 where native), ``"float32"`` or ``"bfloat16"``.
        tta: Average the utility maps of the 8 grid symmetries (test-time augmentation).
        refiner: The mission's refinement: report and time the refined placement beside the learned
            one (see the module docstring).
        check: Mission knowledge applied to the learned peaks from the observation alone (the Wi-Fi
            rule check): peaks at ``check.threshold_abs``, then what ``check`` keeps is the learned
            placement (recorded as ``"check"`` in the summary).
        progress: Show progress bars (on a terminal only: none in a log or a pipe).

    Returns:
        The summary (also in ``summary.json``).

    Raises:
        learning.checkpoint.CheckpointError: The checkpoint is corrupt or from another task or input shape.
        ValueError: The test scenes overlap the checkpoint's training scenes.
        typed_config.ConfigError: A peak setting cannot apply (unknown, out of range, or set by the check),
            or the mission point is asked of a checkpoint without one.
    """
    task = task_factory()
    ckpt = load_checkpoint(checkpoint, task_name=task.name, task_config=task.config,
                           input_shape=(task.channels, *task.shape))
    fixed = {} if check is None else {"threshold_abs": (check.threshold_abs, "the rule check ([rule_check])")}
    choice = choose_peaks(ckpt.peak_config, ckpt.mission_peak_config, peak_overrides,
                          operating_point=operating_point, source=peaks_source, fixed=fixed)
    peaks = choice.config
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    data_dir = Path(data_dir) if data_dir is not None else out / "test-data"
    generate_dataset(task_factory, n, seed, data_dir, split=split, executor=executor, workers=workers,
                     address=address, progress=progress)
    _, arrays = load_arrays(data_dir)
    _check_disjoint(ckpt.payload["data"], arrays["seeds"])
    eps_px = MATCH_FRACTION * task.mission_dimension_px

    resolved = resolve_precision(precision, next(ckpt.model.parameters()).device)
    with_memory_format(ckpt.model, torch.channels_last)
    inputs = arrays["inputs"][:n]
    utilities: list[np.ndarray] = []  # n × (h, w)
    threads = torch.get_num_threads()
    if refiner is None:
        utilities = list(utility_maps(ckpt.model, inputs, resolved, tta))
    else:  # one scene at a time, as the planner runs it: one thread, none left spinning beside the timed code
        torch.set_num_threads(1)
    samples, scores, max_scores, refined_scores = [], [], [], []
    try:  # Ctrl-C: the scenes scored so far are kept, the summary marked as partial
        for i in tqdm(range(n), disable=None if progress else True, desc="qos", unit="scene"):
            expert = arrays["positions"][i][arrays["mask"][i]]
            scene = task.sample(np.random.default_rng(int(arrays["seeds"][i])))
            if refiner is not None:  # each pipeline timed on this scene alone
                start = time.perf_counter()
                utilities.append(utility_maps(ckpt.model, inputs[i:i + 1], resolved, tta)[0])
                predicted = _learned(utilities[i], inputs[i], peaks, check)
                learned_ms = (time.perf_counter() - start) * 1e3
            else:
                predicted = _learned(utilities[i], inputs[i], peaks, check)
            score = score_sample(expert, predicted, eps_px)
            max_scores.append(score_sample(expert, predicted, eps_px, rule="max-matches"))
            scores.append(score)
            sample = {
                "index": int(arrays["indices"][i]), "seed": int(arrays["seeds"][i]),
                "expert": expert.tolist(), "predicted": predicted.tolist(), **score.to_dict(),
                "n_matched_max_matches": max_scores[-1].n_matched,
                "qos": {k: float(v) for k, v in task.qos(scene, predicted).items()},
                "expert_qos": {k: float(v) for k, v in task.qos(scene, expert).items()},
            }
            if refiner is not None:
                start = time.perf_counter()
                refined = refiner.refine(scene, predicted)
                refine_ms = (time.perf_counter() - start) * 1e3
                start = time.perf_counter()
                refiner.solve(scene)
                expert_ms = (time.perf_counter() - start) * 1e3
                refined_scores.append(score_sample(expert, refined, eps_px))
                sample["learned"] = {"positions": sample["predicted"], "qos": sample["qos"],
                                     "time_ms": learned_ms}
                sample["refined"] = {"positions": refined.tolist(), **refined_scores[-1].to_dict(),
                                     "qos": {k: float(v) for k, v in task.qos(scene, refined).items()},
                                     "time_ms": learned_ms + refine_ms, "refine_ms": refine_ms}
                sample["expert_time_ms"] = expert_ms
            samples.append(sample)
    except KeyboardInterrupt:
        if not samples:
            raise
        k = len(samples)
        scores, max_scores, refined_scores = scores[:k], max_scores[:k], refined_scores[:k]
    torch.set_num_threads(threads)

    max_summary = aggregate(max_scores)
    summary: dict[str, Any] = {
        "task": task.name, "checkpoint": checkpoint_label(checkpoint), "seed": seed, "split": split,
        "eps_px": eps_px, "match_rule": "paper", "network_precision": resolved, "tta": tta,
        "peaks": choice.to_dict(),
        **aggregate(scores), **summarise_qos(samples),
        "max_matches": {"corr": max_summary["corr"], "precision": max_summary["precision"]},
    }
    if len(samples) < n:
        summary["interrupted"] = {"scenes_scored": len(samples), "of": n}
    promises = point_promises(ckpt.payload.get("mission_calibration"), choice)
    promises["held"] = {column: {"value": summary[COLUMNS[column]],
                                 "met": bool(summary[COLUMNS[column]] >= promises["paper"][column] - 1e-12)}
                        for column in promises["columns"]}
    summary["promises"] = promises
    if check is not None:
        summary["check"] = check.settings()
    if refiner is not None:
        expert_times = np.array([s["expert_time_ms"] for s in samples])
        summary["learned"] = summarise_pipeline(scores, samples, "learned")
        summary["refined"] = summarise_pipeline(refined_scores, samples, "refined")
        summary["expert"] = {"n_positions": int(sum(len(s["expert"]) for s in samples)),
                             "qos": summary["expert_qos"], "time_median_ms": float(np.median(expert_times)),
                             "time_p95_ms": float(np.percentile(expert_times, 95))}
    write_json_atomic(out / "results.json", {
        "task": task.name, "task_config": task.config.to_dict(), "checkpoint": checkpoint_label(checkpoint),
        "peak_config": peaks.to_dict(), "eps_px": eps_px, "match": "the paper's rule: optimal assignment of "
        "least total distance, then the pairs with distance <= eps_px (n_matched); n_matched_max_matches: "
        "the assignment maximising the number of pairs within eps_px",
        "test_data": {"seed": seed, "split": split, "n": len(samples)}, "samples": samples,
        "summary": summary,
    })
    write_json_atomic(out / "summary.json", summary)
    write_text_atomic(out / "results.md", markdown_table(task.name, summary))
    if n_examples > 0:
        k = min(n_examples, len(samples))
        plot_examples(out / "examples.png", arrays["inputs"][:k], np.stack(utilities[:k]),
                      [np.asarray(s["expert"]) for s in samples[:k]],
                      [np.asarray(s["predicted"]) for s in samples[:k]],
                      [f"#{s['index']} corr {s['corr']:.2f} prec {s['precision']:.2f}" for s in samples[:k]])
    log.info("%s: corr %.3f precision %.3f", task.name, summary["corr"], summary["precision"])
    return summary
