"""Datasets of demonstrations on disk: generation into shards, resumable, executor-independent.

Layout of a dataset folder::

    manifest.json         task name and config, seed, split, sizes, the finished shards and their SHA-256
    shard-00000.npz       inputs (n, C, h, w) float32, positions (n, 10, 2) float64 pixel (x, y),
    shard-00001.npz       mask (n, 10) bool, seeds (n,) uint64, indices (n,) int64
    ...

Seeds: sample ``i`` of split ``s`` of a dataset with seed ``S`` draws its scene
from ``numpy.random.default_rng(sample_seed(S, s, i))``, where
``sample_seed = SeedSequence(S, spawn_key=(SPLITS[s], i))`` reduced to 64 bits and
stored in the shard, so anyone can regenerate a scene from the shard alone. The
split is part of the key, so a test set and a training set drawn with the same
``S`` share no sample seed (up to a 64-bit hash collision, which evaluation checks).

Writes are atomic (temporary file, then ``os.replace``) and the shard bytes depend
only on the task, the seed and the shard size (fixed zip timestamps), so the local
and the Ray executors produce identical files. After a kill, running the same
generation again keeps every shard whose hash matches the manifest and computes
the rest.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import logging
import zipfile
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, Literal

import numpy as np
from tqdm.auto import tqdm

from learning.executors import ShardJob, run_local, run_ray
from learning.task import MAX_POSITIONS, Task
from typed_config.files import atomic_path, write_json_atomic

__all__ = [
    "SPLITS", "FORMAT", "DatasetError", "sample_seed", "generate_shard", "generate_samples",
    "generate_dataset", "load_manifest", "load_arrays",
]

log = logging.getLogger(__name__)

FORMAT = "learning-shards/1"
SPLITS: dict[str, int] = {"train": 0, "test": 1, "val": 2}
"""Seed namespaces: the split name's number is the first spawn key of every sample seed."""

_IDENTITY_KEYS = ("format", "task", "task_config", "channels", "shape", "seed", "split", "n", "shard_size")
_ZIP_EPOCH = (1980, 1, 1, 0, 0, 0)


class DatasetError(RuntimeError):
    """A dataset folder is inconsistent, corrupt, or holds a different dataset."""


def sample_seed(seed: int, split: str, index: int) -> int:
    """The 64-bit seed of sample ``index`` of ``split`` (see the module docstring).

    Raises:
        ValueError: Unknown split or negative seed/index.
    """
    if split not in SPLITS:
        raise ValueError(f"split = {split!r} is not allowed: choose one of {sorted(SPLITS)}")
    if seed < 0 or index < 0:
        raise ValueError(f"seed = {seed} and index = {index} must be >= 0")
    sequence = np.random.SeedSequence(seed, spawn_key=(SPLITS[split], index))
    return int(sequence.generate_state(1, np.uint64)[0])


def generate_shard(task_factory: Callable[[], Task], seed: int, split: str, start: int, stop: int
                   ) -> dict[str, np.ndarray]:
    """Samples ``start .. stop-1``: observations, expert positions, mask, seeds, indices.

    A top-level function, so process pools and Ray can run it; the task is rebuilt
    in the worker from the picklable ``task_factory``.

    Raises:
        DatasetError: The task returned an observation or a placement of the wrong shape.
    """
    return generate_samples(task_factory, seed, split, range(start, stop))


def generate_samples(task_factory: Callable[[], Task], seed: int, split: str, indices: Sequence[int]
                     ) -> dict[str, np.ndarray]:
    """The samples of ``indices`` (any order) of a dataset, as :func:`generate_shard` returns them.

    Raises:
        DatasetError: The task returned an observation or a placement of the wrong shape.
    """
    task = task_factory()
    n = len(indices)
    c, (h, w) = task.channels, task.shape
    arrays: dict[str, np.ndarray] = {
        "inputs": np.zeros((n, c, h, w), dtype=np.float32),
        "positions": np.zeros((n, MAX_POSITIONS, 2), dtype=np.float64),
        "mask": np.zeros((n, MAX_POSITIONS), dtype=bool),
        "seeds": np.zeros(n, dtype=np.uint64),
        "indices": np.asarray(indices, dtype=np.int64).reshape(n),
    }
    for row, index in enumerate(indices):
        s = sample_seed(seed, split, index)
        scene = task.sample(np.random.default_rng(s))
        observation = np.asarray(task.observe(scene))
        expert = np.asarray(task.expert(scene), dtype=np.float64).reshape(-1, 2)
        if observation.shape != (c, h, w):
            raise DatasetError(f"sample {index} (seed {s}): observation shape {observation.shape} "
                               f"!= {(c, h, w)}")
        if len(expert) > MAX_POSITIONS or not np.all(np.isfinite(expert)):
            raise DatasetError(f"sample {index} (seed {s}): expert gave {len(expert)} positions "
                               f"(allowed 0..{MAX_POSITIONS}, finite)")
        arrays["inputs"][row] = observation
        arrays["positions"][row, : len(expert)] = expert
        arrays["mask"][row, : len(expert)] = True
        arrays["seeds"][row] = s
    return arrays


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(functools.partial(f.read, 1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _write_npz_atomic(path: Path, arrays: Mapping[str, np.ndarray]) -> None:
    """A deterministic ``.npz`` (stored, fixed timestamps, sorted members), written atomically."""
    with atomic_path(path) as tmp, zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_STORED) as archive:
        for name in sorted(arrays):
            member = zipfile.ZipInfo(f"{name}.npy", date_time=_ZIP_EPOCH)
            with archive.open(member, "w", force_zip64=True) as f:
                np.lib.format.write_array(f, np.ascontiguousarray(arrays[name]), allow_pickle=False)


def load_manifest(data_dir: str | Path) -> dict[str, Any]:
    """The manifest of a dataset folder.

    Raises:
        DatasetError: Missing or unreadable manifest, or an unknown format.
    """
    path = Path(data_dir) / "manifest.json"
    try:
        manifest = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise DatasetError(f"no dataset manifest at {path}") from None
    except (OSError, json.JSONDecodeError) as exc:
        raise DatasetError(f"{path}: unreadable manifest: {exc}") from None
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT:
        raise DatasetError(f"{path}: not a {FORMAT} manifest")
    return manifest


def _shard_jobs(n: int, shard_size: int) -> list[ShardJob]:
    return [(i, start, min(start + shard_size, n)) for i, start in enumerate(range(0, n, shard_size))]


def generate_dataset(
    task_factory: Callable[[], Task],
    n: int,
    seed: int,
    out_dir: str | Path,
    *,
    split: str = "train",
    shard_size: int = 256,
    executor: Literal["local", "ray"] = "local",
    workers: int | None = None,
    address: str | None = None,
    progress: bool = True,
    on_shard: Callable[[dict[str, Any]], None] | None = None,
) -> dict[str, Any]:
    """Generate (or finish generating) a dataset of ``n`` demonstrations into ``out_dir``.

    Args:
        task_factory: Picklable zero-argument callable returning the task (rebuilt in each worker).
        n: Number of samples.
        seed: Dataset seed (see :func:`sample_seed`).
        out_dir: Dataset folder (created if needed).
        split: Seed namespace, one of ``SPLITS``.
        shard_size: Samples per shard file.
        executor: ``"local"`` (process pool) or ``"ray"``.
        workers: Local worker processes (``None``: all CPUs; 1: in this process).
        address: Ray cluster address (``executor="ray"`` only).
        progress: Show a progress bar (on a terminal only: none in a log or a pipe).
        on_shard: Called with each shard's manifest record after it is written.

    Returns:
        The final manifest (also in ``out_dir/manifest.json``).

    Raises:
        ValueError: Bad ``n``, ``seed``, ``shard_size``, ``split`` or ``executor``.
        DatasetError: ``out_dir`` holds a different dataset.
    """
    if n < 1 or seed < 0 or shard_size < 1:
        raise ValueError(f"need n >= 1, seed >= 0, shard_size >= 1; "
                         f"got n={n}, seed={seed}, shard_size={shard_size}")
    if split not in SPLITS:
        raise ValueError(f"split = {split!r} is not allowed: choose one of {sorted(SPLITS)}")
    if executor not in ("local", "ray"):
        raise ValueError(f"executor = {executor!r} is not allowed: choose 'local' or 'ray'")
    task = task_factory()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    manifest: dict[str, Any] = {
        "format": FORMAT, "task": task.name, "task_config": task.config.to_dict(),
        "channels": task.channels, "vector_channels": list(getattr(task, "vector_channels", ())),
        "shape": list(task.shape),
        "mission_dimension_px": task.mission_dimension_px,
        "max_positions": MAX_POSITIONS, "seed": seed, "split": split, "n": n, "shard_size": shard_size,
        "shards": [],
    }
    if (out / "manifest.json").exists():
        old = load_manifest(out)
        for key in _IDENTITY_KEYS:
            if old.get(key) != manifest[key]:
                raise DatasetError(f"{out} holds a different dataset: {key} = {old.get(key)!r}, "
                                   f"requested {manifest[key]!r}; use another folder")
        manifest["shards"] = [s for s in old["shards"]
                              if (out / s["file"]).exists() and _sha256(out / s["file"]) == s["sha256"]]
        if len(manifest["shards"]) < len(old["shards"]):
            log.warning("%s: %d shard(s) missing or corrupt, regenerating them",
                        out, len(old["shards"]) - len(manifest["shards"]))
    finished = {s["index"] for s in manifest["shards"]}
    jobs = [job for job in _shard_jobs(n, shard_size) if job[0] not in finished]
    write_json_atomic(out / "manifest.json", manifest)
    fn = functools.partial(generate_shard, task_factory, seed, split)
    results = run_ray(fn, jobs, address) if executor == "ray" else run_local(fn, jobs, workers)
    done = sum(s["stop"] - s["start"] for s in manifest["shards"])
    with contextlib.closing(results), tqdm(total=n, initial=done, disable=None if progress else True,
                                           unit="scene", desc=f"{task.name} {split}") as bar:
        for (index, start, stop), arrays in results:
            path = out / f"shard-{index:05d}.npz"
            _write_npz_atomic(path, arrays)
            record = {"index": index, "file": path.name, "start": start, "stop": stop,
                      "sha256": _sha256(path)}
            manifest["shards"] = sorted([*manifest["shards"], record], key=lambda s: s["index"])
            write_json_atomic(out / "manifest.json", manifest)
            bar.update(stop - start)
            if on_shard is not None:
                on_shard(record)
    return manifest


def load_arrays(data_dir: str | Path, *, verify: bool = True) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """The manifest and all shards of a complete dataset, concatenated in sample order.

    Args:
        data_dir: Dataset folder.
        verify: Check every shard's SHA-256 against the manifest.

    Raises:
        DatasetError: Incomplete dataset (finish it with the same ``generate_dataset`` call)
            or a corrupt shard.
    """
    data_dir = Path(data_dir)
    manifest = load_manifest(data_dir)
    have = sum(s["stop"] - s["start"] for s in manifest["shards"])
    if have != manifest["n"]:
        raise DatasetError(f"{data_dir}: incomplete dataset ({have} of {manifest['n']} samples); "
                           "run the same generation again to finish it")
    parts: dict[str, list[np.ndarray]] = {}
    for record in manifest["shards"]:
        path = data_dir / record["file"]
        if not path.is_file():
            raise DatasetError(f"{path}: shard listed in the manifest is missing")
        if verify and _sha256(path) != record["sha256"]:
            raise DatasetError(f"{path}: SHA-256 mismatch with the manifest (corrupt shard)")
        with np.load(path, allow_pickle=False) as shard:
            for key in shard.files:
                parts.setdefault(key, []).append(shard[key])
    return manifest, {key: np.concatenate(value) for key, value in parts.items()}
