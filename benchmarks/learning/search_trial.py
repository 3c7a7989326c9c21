"""Wall time of one (α2, σ2) search trial, and the best way to run trials on this machine.

One trial = 1 epoch of the paper's network (batch 16) on ``--n`` blob scenes of
``--size`` px (the synthetic test task: training cost depends on the raster size
and sample count, not on the mission), scored on the 10 % validation split. The
reference is one trial in this process with 1 torch thread; it is compared with one
trial with 2 threads, and with two trials in a 2-process pool (1 thread each),
whose per-trial time is half the pool's wall time. Also checks that the same grid
point gives the same numbers in the pool as in the reference.

Usage: python benchmarks/learning/search_trial.py [--n 1000] [--size 64] [--batch 16]
"""

from __future__ import annotations

import argparse
import functools
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import torch

from learning.data import generate_dataset
from learning.search import run_search
from learning.search_grid import SearchConfig
from learning.train import TrainConfig

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests" / "learning"))
from blob_task import BlobConfig, BlobTask  # noqa: E402  (the test suite's synthetic task)


def timed_search(data: Path, out: Path, grid: SearchConfig, train: TrainConfig, workers: int
                 ) -> tuple[float, dict]:
    """Wall seconds of a search, and its per-point (corr, precision, val_loss)."""
    t0 = time.perf_counter()
    summary = run_search(data, out, grid, train_config=train, workers=workers)
    wall_s = time.perf_counter() - t0
    points = [(a, s) for a in summary["grid"]["alpha2"] for s in summary["grid"]["sigma2"]]
    corr = [c for row in summary["corr"] for c in row]
    return wall_s, dict(zip(points, corr, strict=True))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1000)
    parser.add_argument("--size", type=int, default=64)
    parser.add_argument("--batch", type=int, default=16)
    args = parser.parse_args()
    print(f"python {platform.python_version()}, torch {torch.__version__}, {os.cpu_count()} CPUs, "
          f"load average {os.getloadavg()[0]:.1f}")
    train = TrainConfig(epochs=1, batch_size=args.batch, device="cpu")
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        task = functools.partial(BlobTask, BlobConfig(size_px=args.size, max_blobs=10))
        generate_dataset(task, args.n, 0, root / "data", workers=1, progress=False)
        one = SearchConfig(alpha2="20", sigma2="20")
        ref_s, ref = timed_search(root / "data", root / "t1", one, train, 1)
        two_s, two = timed_search(root / "data", root / "t2", one.replace(threads=2), train, 1)
        pair = SearchConfig(alpha2="20:30:10", sigma2="20")
        pool_s, pool = timed_search(root / "data", root / "pool", pair, train, 2)
    label = f"1 epoch, {args.n} scenes {args.size}x{args.size}, batch {args.batch}"
    print(f"one trial: {label}")
    print(f"{'1 trial, 1 thread (reference)':<45}: {ref_s:7.1f} s")
    print(f"{'1 trial, 2 threads':<45}: {two_s:7.1f} s, speed ratio {ref_s / two_s:.2f}x")
    print(f"{'2 trials in a 2-process pool, 1 thread each':<45}: {pool_s / 2:7.1f} s per trial, "
          f"speed ratio {2 * ref_s / pool_s:.2f}x")
    print(f"same numbers, 1 thread vs pool: {pool[20.0, 20.0] == ref[20.0, 20.0]}; "
          f"1 vs 2 threads: {two[20.0, 20.0] == ref[20.0, 20.0]}")


if __name__ == "__main__":
    main()
