"""Dataset generation samples/s: in-process (the reference), local process pool, and Ray on this machine.

Generates the same ``--n`` scenes of a registered task three times into a
temporary folder and checks that the three datasets are byte-identical.

Usage: python benchmarks/learning/dataset_speed.py [--task wifi-s1] [--n 64] [--workers 2] [--config FILE]
       [--no-ray]
"""

from __future__ import annotations

import argparse
import contextlib
import tempfile
import time
from pathlib import Path

from learning.data import generate_dataset
from learning.executors import ray_session
from uav_swarm.missions.registry import make_task, task_factory


def files(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="wifi-s1")
    parser.add_argument("--config", help="task settings TOML")
    parser.add_argument("--n", type=int, default=64)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--no-ray", action="store_true")
    args = parser.parse_args()
    factory = task_factory(make_task(args.task, args.config))
    shard_size = max(1, args.n // (2 * args.workers))
    runs: dict[str, dict] = {"in-process (reference)": {"workers": 1},
                             f"local pool x{args.workers}": {"workers": args.workers}}
    if not args.no_ray:
        runs[f"ray (local, {args.workers} CPUs)"] = {"executor": "ray"}
    with tempfile.TemporaryDirectory() as tmp:
        rates, outputs = {}, {}
        for name, options in runs.items():
            session = (ray_session(num_cpus=args.workers, log_to_driver=False)
                       if options.get("executor") == "ray" else contextlib.nullcontext())
            out = Path(tmp) / name.split()[0]
            with session:  # Ray: a local instance on 127.0.0.1, started before the clock, shut down within
                t0 = time.perf_counter()
                generate_dataset(factory, args.n, args.seed, out, shard_size=shard_size, progress=False,
                                 **options)
            rates[name] = args.n / (time.perf_counter() - t0)
            outputs[name] = files(out)
        reference = rates["in-process (reference)"]
        print(f"{args.task}: {args.n} scenes, shards of {shard_size}")
        print("| executor | scenes/s | vs in-process | identical bytes |")
        print("|---|---|---|---|")
        first = next(iter(outputs.values()))
        for name, rate in rates.items():
            print(f"| {name} | {rate:.2f} | {rate / reference:.2f} | {outputs[name] == first} |")


if __name__ == "__main__":
    main()
