"""Grid search over the wide target Gaussian (α2, σ2): one training per grid point.

Every trial trains a fresh model with :func:`learning.train.train` on the same
dataset, with the same configs and seeds; only ``TargetConfig.alpha2`` and
``sigma2`` change. A trial's score is the last epoch's validation correspondence
and precision from the training history (the validation split is drawn from
``TrainConfig.seed``, so it is the same for every trial).

Layout of the output folder::

    search.json       identity of the search and the finished trials (rewritten atomically after each)
    trials/a{α2}_s{σ2}/checkpoint.pt, best.pt    each trial's training run
    ray/              Ray Tune's experiment storage (``executor="ray"`` only)

Resuming: running the same search into the same folder skips the finished trials
(and continues an interrupted trial from its last epoch checkpoint). Each trial records the
executor it ran on, and the report names those, not the executor of the run that wrote it. A ``search.json``
from another dataset or another budget (model, train, peak or base target config,
torch threads) is an error, never silently mixed; the grid itself may change
(finished points that are still on the grid are kept).

Determinism: each trial fixes torch's thread count (``SearchConfig.threads``) and
:func:`train` fixes every seed, so on CPU the local and the Ray executors give
identical numbers for the same seeds. With ``TrainConfig.device`` "cuda" (or
"auto" on a driver that sees a GPU) each Ray trial reserves one GPU.
"""

from __future__ import annotations

import functools
import hashlib
import json
import logging
import os
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import torch

from learning.data import load_manifest
from learning.executors import ray_session, run_local
from learning.model import ModelConfig
from learning.peaks import PeakConfig
from learning.search_grid import Point, SearchConfig
from learning.targets import TargetConfig
from learning.train import TrainConfig, pick_device, train
from typed_config.files import write_json_atomic

__all__ = ["SEARCH_FORMAT", "SearchError", "TrialSpec", "trial_name", "run_trial", "run_search",
           "executor_label"]

log = logging.getLogger(__name__)

SEARCH_FORMAT = "learning-search/1"
RESULTS_FILE = "search.json"


class SearchError(RuntimeError):
    """A search cannot run or resume: wrong results file, failed trial, or unusable settings."""


@dataclass(frozen=True)
class TrialSpec:
    """Everything a trial needs, as plain values (picklable for process pools and Ray)."""

    data_dir: str
    out_dir: str
    model_config: dict[str, Any]
    target_config: dict[str, Any]
    train_config: dict[str, Any]
    peak_config: dict[str, Any]
    threads: int


def trial_name(alpha2: float, sigma2: float) -> str:
    """The trial's folder name, e.g. ``a40_s20`` (``a2.5_s10`` for fractional values)."""
    return f"a{alpha2:g}_s{sigma2:g}"


def _resumable(path: Path, expected: dict[str, dict[str, Any]]) -> Path | None:
    """``path`` when it is a checkpoint of exactly this trial's configs, else None."""
    from learning.checkpoint import CheckpointError, load_checkpoint

    if not path.exists():
        return None
    try:
        payload = load_checkpoint(path).payload
    except CheckpointError as exc:
        log.warning("restarting trial: %s", exc)
        return None
    if any(payload.get(key) != value for key, value in expected.items()):
        log.warning("restarting trial: %s has other configs", path)
        return None
    return path


def run_trial(spec: TrialSpec, alpha2: float, sigma2: float) -> dict[str, Any]:
    """Train one grid point and return its scores (a top-level function for workers).

    Returns:
        ``alpha2``, ``sigma2``, ``corr`` and ``precision`` (last epoch's validation),
        ``val_loss``, ``train_loss``, ``epochs``, ``steps``, ``train_s`` and the ``history``.
    """
    target = TargetConfig.from_dict(spec.target_config).replace(alpha2=alpha2, sigma2=sigma2)
    out = Path(spec.out_dir) / "trials" / trial_name(alpha2, sigma2)
    manifest = load_manifest(spec.data_dir)
    expected = {"model_config": spec.model_config, "target_config": target.to_dict(),
                "train_config": spec.train_config, "peak_config": spec.peak_config,
                "task_name": manifest["task"], "task_config": manifest["task_config"],
                "data": {k: manifest[k] for k in ("seed", "split", "n")}}
    threads = torch.get_num_threads()
    torch.set_num_threads(spec.threads)
    try:
        result = train(spec.data_dir, out, model_config=ModelConfig.from_dict(spec.model_config),
                       target_config=target, train_config=TrainConfig.from_dict(spec.train_config),
                       peak_config=PeakConfig.from_dict(spec.peak_config),
                       resume=_resumable(out / "checkpoint.pt", expected), progress=False)
    finally:
        torch.set_num_threads(threads)
    last = result.history[-1]
    return {"alpha2": alpha2, "sigma2": sigma2, "corr": last["val_corr"], "precision": last["val_precision"],
            "val_loss": last["val_loss"], "train_loss": last["train_loss"], "epochs": len(result.history),
            "steps": int(last["step"]), "train_s": last["elapsed_s"], "history": result.history}


def _trial_range(spec: TrialSpec, points: Sequence[Point], start: int, stop: int) -> list[dict[str, Any]]:
    return [run_trial(spec, *points[i]) for i in range(start, stop)]


def _run_local(spec: TrialSpec, points: Sequence[Point], workers: int) -> Iterator[dict[str, Any]]:
    jobs = [(i, i, i + 1) for i in range(len(points))]
    results = run_local(functools.partial(_trial_range, spec, list(points)), jobs, workers)
    try:
        for _, trials in results:
            yield from trials
    finally:
        results.close()


def _run_ray(spec: TrialSpec, points: Sequence[Point], address: str | None, workers: int | None,
             record: Callable[[dict[str, Any]], None]) -> None:
    """Run the trials with Ray Tune's ``grid_search``; ``record`` gets each result on the driver."""
    try:
        from ray import tune
    except ImportError as exc:
        raise ImportError("the Ray executor needs Ray Tune: pip install 'ray[tune]'") from exc

    def trainable(config: dict[str, Any], spec: TrialSpec) -> None:
        tune.report({"search_trial": json.dumps(run_trial(spec, *config["point"]))})

    class Recorder(tune.Callback):
        def on_trial_result(self, iteration: int, trials: list, trial: Any, result: dict,
                            **info: Any) -> None:
            record(json.loads(result["search_trial"]))

    device = spec.train_config["device"]
    use_gpu = device == "cuda" or (device == "auto" and pick_device("auto").type == "cuda")
    # Ray hides GPUs from trials without one
    resources: dict[str, float] = {"cpu": spec.threads, "gpu": 1 if use_gpu else 0}
    with ray_session(address, num_cpus=os.cpu_count(), object_store_memory=256 * 2**20):
        tuner = tune.Tuner(
            tune.with_resources(tune.with_parameters(trainable, spec=spec), resources),
            param_space={"point": tune.grid_search([list(p) for p in points])},
            tune_config=tune.TuneConfig(max_concurrent_trials=workers, reuse_actors=True),
            run_config=tune.RunConfig(name=time.strftime("search-%Y%m%d-%H%M%S"), verbose=0,
                                      storage_path=str(Path(spec.out_dir) / "ray"), callbacks=[Recorder()]),
        )
        grid = tuner.fit()
        if grid.errors:
            raise SearchError(f"{len(grid.errors)} Ray trial(s) failed; first: {grid.errors[0]}")


def _dataset_identity(manifest: dict[str, Any]) -> dict[str, Any]:
    digest = hashlib.sha256("".join(s["sha256"] for s in manifest["shards"]).encode()).hexdigest()
    keys = ("task", "task_config", "shape", "channels", "seed", "split", "n")
    return {**{k: manifest[k] for k in keys}, "shards_sha256": digest}


def _differences(old: Any, new: Any, where: str = "") -> list[str]:
    if isinstance(old, dict) and isinstance(new, dict):
        return [d for k in sorted(set(old) | set(new))
                for d in _differences(old.get(k), new.get(k), f"{where}.{k}" if where else k)]
    return [] if old == new else [f"{where} = {old!r} there, {new!r} now"]


def executor_label(trials: Sequence[dict[str, Any]]) -> str:
    """Where the trials ran: ``"local"``, ``"ray"``, or e.g. ``"local + ray"`` for a search resumed elsewhere.

    Examples:
        >>> executor_label([{"executor": "ray"}, {"executor": "local"}, {"executor": "ray"}])
        'local + ray'
    """
    return " + ".join(sorted({t.get("executor", "unrecorded") for t in trials})) or "none"


def _previous_executor(out: Path) -> str | None:
    """The executor named by the report already in ``out`` (for trials recorded before trials named it)."""
    try:
        executor = json.loads((out / "summary.json").read_text(encoding="utf-8")).get("executor")
    except (OSError, ValueError, AttributeError):
        return None
    return executor if executor in ("local", "ray") else None


def _load_finished(path: Path, identity: dict[str, Any], legacy_executor: str | None = None
                   ) -> dict[Point, dict[str, Any]]:
    """The finished trials of ``path`` (empty when it does not exist).

    Trials written before each trial recorded its executor get ``legacy_executor`` when known.

    Raises:
        SearchError: The file is unreadable or belongs to a different search.
    """
    if not path.exists():
        return {}
    try:
        saved = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as exc:
        raise SearchError(f"{path}: unreadable results file ({exc}); move it away to start afresh") from None
    if not isinstance(saved, dict) or saved.get("format") != SEARCH_FORMAT:
        raise SearchError(f"{path}: not a {SEARCH_FORMAT} results file")
    diff = _differences(saved.get("identity"), identity)
    if diff:
        raise SearchError(f"{path} holds a search of another dataset or budget ({'; '.join(diff[:4])}); "
                          "use another output folder or the same settings")
    trials = saved["trials"]
    if legacy_executor is not None:
        trials = [t if "executor" in t else {**t, "executor": legacy_executor} for t in trials]
    return {(t["alpha2"], t["sigma2"]): t for t in trials}


def run_search(
    data_dir: str | Path,
    out_dir: str | Path,
    search_config: SearchConfig,
    *,
    model_config: ModelConfig | None = None,
    target_config: TargetConfig | None = None,
    train_config: TrainConfig | None = None,
    peak_config: PeakConfig | None = None,
    executor: Literal["local", "ray"] = "local",
    workers: int | None = None,
    address: str | None = None,
    on_trial: Callable[[dict[str, Any]], None] | None = None,
) -> dict[str, Any]:
    """Run (or resume) the (α2, σ2) grid search and write its report.

    Args:
        data_dir: A complete dataset folder (see :mod:`learning.data`).
        out_dir: Output folder (see the module docstring).
        search_config: The grid and per-trial torch threads.
        model_config: Architecture (``in_channels`` is taken from the data).
        target_config: ``alpha1`` and ``sigma1``; its ``alpha2``/``sigma2`` are replaced per trial.
        train_config: The per-trial budget (a reduced one is fine: the report states it);
            ``val_fraction`` must be > 0.
        peak_config: Peak extraction for the validation metrics.
        executor: ``"local"`` or ``"ray"`` (Ray Tune ``grid_search``).
        workers: Trials at once, each with ``threads`` torch threads. Local: processes
            (default: CPUs // threads; 1 runs in this process). Ray: concurrent trials
            (default: as many as the cluster's CPUs allow).
        address: Ray cluster address (``executor="ray"``); data and output folders must
            then be on a filesystem shared by every node, at the same path.
        on_trial: Called with each newly finished trial, after ``search.json`` is written.

    Returns:
        The summary (see :func:`learning.search_report.summarise`), also written to
        ``summary.json``, ``summary.md`` and ``heatmap.png`` in ``out_dir``.

    Raises:
        ValueError: Unknown executor or ``workers < 1``.
        SearchError: No validation split, a results file of another search, or a failed trial.
        learning.data.DatasetError: Missing or incomplete dataset.
    """
    from learning.data import load_arrays
    from learning.search_report import write_report

    if executor not in ("local", "ray"):
        raise ValueError(f"executor = {executor!r} is not allowed: choose 'local' or 'ray'")
    if workers is not None and workers < 1:
        raise ValueError(f"workers = {workers} must be >= 1")
    train_config = train_config or TrainConfig()
    if train_config.val_fraction <= 0:
        raise SearchError("TrainConfig.val_fraction = 0: a search scores trials on a validation split (> 0)")
    data, out = Path(data_dir).resolve(), Path(out_dir).resolve()
    manifest, arrays = load_arrays(data)  # complete and intact, before any trial starts
    model_config = (model_config or ModelConfig()).replace(in_channels=manifest["channels"])
    spec = TrialSpec(str(data), str(out), model_config.to_dict(), (target_config or TargetConfig()).to_dict(),
                     train_config.to_dict(), (peak_config or PeakConfig()).to_dict(), search_config.threads)
    positions_px, mask = arrays["positions"], arrays["mask"]  # for the rule of thumb; the inputs are freed
    del arrays
    identity = {"data": _dataset_identity(manifest), "model_config": spec.model_config,
                "target_config": {k: spec.target_config[k] for k in ("alpha1", "sigma1")},
                "train_config": spec.train_config, "peak_config": spec.peak_config, "threads": spec.threads}
    out.mkdir(parents=True, exist_ok=True)
    path = out / RESULTS_FILE
    finished = _load_finished(path, identity, _previous_executor(out))
    points = search_config.points
    todo = [p for p in points if p not in finished]
    log.info("search: %d grid points, %d finished, %d to run (%s)", len(points), len(points) - len(todo),
             len(todo), executor)

    def save() -> None:
        write_json_atomic(path, {"format": SEARCH_FORMAT, "identity": identity,
                                 "trials": [finished[p] for p in sorted(finished)]})

    def record(trial: dict[str, Any]) -> None:
        trial = {**trial, "executor": executor}
        finished[(trial["alpha2"], trial["sigma2"])] = trial
        save()
        log.info("trial α2=%g σ2=%g: corr %.3f precision %.3f (%.0f s)", trial["alpha2"], trial["sigma2"],
                 trial["corr"], trial["precision"], trial["train_s"])
        if on_trial is not None:
            on_trial(trial)

    save()
    if todo and executor == "ray":
        _run_ray(spec, todo, address, workers, record)
    elif todo:
        for trial in _run_local(spec, todo, workers or max(1, (os.cpu_count() or 1) // spec.threads)):
            record(trial)
    trials = [finished[p] for p in points]
    return write_report(out, search_config, trials, manifest, positions_px, mask, train_config,
                        executor_label(trials))
