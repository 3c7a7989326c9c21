"""What the radio adds to a batched env step: the 802.11 radio against the paper's, now and at another commit.

The batched env (``BatchedUAVSwarm``: 64 worlds, 10 UAVs, the default scenario, uniform random velocity
actions from a seeded generator) is stepped with the default 802.11 radio (the channel plan made by the env
at every step) and with the paper's radio; the radio's cost is the difference of the two, in CPU
milliseconds per world-step. With ``--before REV`` the packages as they were at ``REV`` (``git archive``
into a temporary folder) are measured in the same run, in interleaved rounds, each measurement in a fresh
process, so that a load changing during the run affects both alike. Goal: the 802.11 radio adds
<= 0.05 ms per world-step. The load average before and after is printed.

Usage: python benchmarks/env/radio_cost.py [--before REV] [--copies 64] [--steps 30] [--rounds 3]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("uav_swarm", "typed_config", "learning", "bridge")
RADIOS = ("802.11", "paper")
N_UAVS = 10


def measure(copies: int, steps: int, radio: str) -> float:
    """CPU milliseconds per world-step of ``copies`` batched worlds under ``radio`` (in this process)."""
    import numpy as np

    from uav_swarm.env.batched import BatchedUAVSwarm

    envs = BatchedUAVSwarm(copies, n_uavs=N_UAVS, radio={"propagation": radio}, max_cycles=10**6)
    envs.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(3):  # compiled code loaded, caches warm
        envs.step(rng.uniform(-1.0, 1.0, (copies, N_UAVS, 2)))
    start = time.process_time()
    for _ in range(steps):
        envs.step(rng.uniform(-1.0, 1.0, (copies, N_UAVS, 2)))
    return (time.process_time() - start) / (steps * copies) * 1e3


def load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def run_in(tree: Path, args: argparse.Namespace, radio: str) -> float:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    out = subprocess.run([sys.executable, __file__, "--measure", radio, "--copies", str(args.copies),
                          "--steps", str(args.steps)], env=env, cwd=tree, check=True, capture_output=True,
                         text=True)
    return float(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", metavar="REV", help="commit to measure beside the working tree")
    parser.add_argument("--copies", type=int, default=64, help="worlds of the batched env")
    parser.add_argument("--steps", type=int, default=30, help="measured steps per measurement")
    parser.add_argument("--rounds", type=int, default=3, help="interleaved rounds")
    parser.add_argument("--measure", choices=RADIOS, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.measure:
        print(measure(args.copies, args.steps, args.measure))
        return
    print(f"load before: {load()}")
    with tempfile.TemporaryDirectory() as tmp:
        trees = {"now": ROOT}
        if args.before:
            archive = subprocess.run(["git", "-C", str(ROOT), "archive", args.before, *PACKAGES],
                                     check=True, capture_output=True).stdout
            subprocess.run(["tar", "-x", "-C", tmp], input=archive, check=True)
            trees[args.before] = Path(tmp)
        times: dict[tuple[str, str], list[float]] = {(t, r): [] for t in trees for r in RADIOS}
        for _ in range(args.rounds):
            for name, tree in trees.items():
                for radio in RADIOS:
                    times[name, radio].append(run_in(tree, args, radio))
    median = {key: statistics.median(values) for key, values in times.items()}
    result = {name: {"802.11_ms": median[name, "802.11"], "paper_ms": median[name, "paper"],
                     "radio_adds_ms": median[name, "802.11"] - median[name, "paper"]} for name in trees}
    for name, row in result.items():
        print(f"{name:>10}: 802.11 {row['802.11_ms']:.4f} ms, paper {row['paper_ms']:.4f} ms per world-step; "
              f"the 802.11 radio adds {row['radio_adds_ms']:.4f} ms (goal <= 0.05)")
    if args.before:
        now, before = result["now"], result[args.before]
        print(f"802.11 step: {before['802.11_ms'] / now['802.11_ms']:.2f}x faster than {args.before}; the "
              f"radio's share {before['radio_adds_ms'] / now['radio_adds_ms']:.2f}x smaller")
    print(f"load after: {load()}")
    print(json.dumps(result))


if __name__ == "__main__":
    main()
