"""Median batch-1 inference time of utility networks on the default engine, as the planner runs them.

    python benchmarks/learning/inference_time.py --rounds 300 uav_swarm/checkpoints/agp.pt
        runs/agp-w32/best.pt

For each checkpoint (default: the shipped AGP, FP, Wi-Fi S1 and S2 networks): the network's
parameters and forward FLOPs at batch 1, the engine :func:`learning.inference.select_engine` chooses
for float32 on one thread (the planner's default: the fastest of ONNX Runtime, traced TorchScript and
eager whose maps equal eager float32's), then ``--rounds`` batch-1 calls of that engine on a seeded
raster, the checkpoints' calls interleaved round by round so that the machine's load hits all alike.
With ``--tta`` each checkpoint also times the symmetry-averaged map the same way: the raster's 8
symmetric views in one call of the same engine, each map turned back, then their mean.
Prints the machine, the load average before and after, and one table row per checkpoint.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch.utils.flop_counter import FlopCounterMode

from learning.checkpoint import load_checkpoint
from learning.inference import SYMMETRIES, select_engine
from learning.symmetry import Symmetry

SHIPPED = ("agp", "fp", "wifi-s1", "wifi-s2")


def _flops(model: torch.nn.Module, shape: tuple[int, int, int]) -> int:
    with FlopCounterMode(display=False) as counter, torch.no_grad():
        model(torch.zeros(1, *shape))
    return int(counter.get_total_flops())


def _view(x: np.ndarray, symmetry: Symmetry, inverse: bool = False) -> np.ndarray:
    """``x`` ``(..., h, w)`` under a symmetry of the square raster (flips, then transpose), or its inverse."""
    flip_x, flip_y, transpose = symmetry
    if inverse and transpose:
        x = np.swapaxes(x, -2, -1)
    x = x[..., ::-1] if flip_x else x
    x = x[..., ::-1, :] if flip_y else x
    if not inverse and transpose:
        x = np.swapaxes(x, -2, -1)
    return x


def _symmetry_averaged(engine: Any, raster: np.ndarray) -> np.ndarray:
    """The ``(1, h, w)`` mean of the 8 symmetric views' maps, each turned back, from one engine call."""
    views = np.ascontiguousarray(np.concatenate([_view(raster, s) for s in SYMMETRIES]))
    maps = engine.maps(views)
    return np.mean([_view(maps[i], s, inverse=True) for i, s in enumerate(SYMMETRIES)], axis=0)[None]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkpoints", nargs="*", help="checkpoint files (default: the shipped four)")
    parser.add_argument("--rounds", type=int, default=300, help="timed batch-1 calls per checkpoint")
    parser.add_argument("--tta", action="store_true", help="also time the symmetry-averaged map")
    args = parser.parse_args()
    if args.rounds < 1:
        parser.error("--rounds must be >= 1")
    root = Path(__file__).resolve().parents[2] / "uav_swarm" / "checkpoints"
    paths = [Path(p) for p in args.checkpoints] or [root / f"{name}.pt" for name in SHIPPED]
    torch.set_num_threads(1)
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, torch "
          f"{torch.__version__}, 1 thread; load average before {os.getloadavg()}", flush=True)
    rows = []
    for path in paths:
        ckpt = load_checkpoint(path)
        channels, height, width = (int(v) for v in ckpt.payload["input_shape"])
        shape = (channels, height, width)
        model = ckpt.model.eval()
        choice = select_engine(model, shape, "float32", threads=1)
        raster = np.random.default_rng(0).random((1, *shape), dtype=np.float32)
        cfg = ckpt.model_config
        rows.append({"name": f"{path.parent.name}/{path.name}", "task": ckpt.payload["task_name"],
                     "net": f"width {cfg.width}, depth {cfg.depth}",
                     "params": sum(p.numel() for p in model.parameters()), "flops": _flops(model, shape),
                     "engine": choice.engine, "raster": raster, "spent": [], "spent_tta": []})
        for _ in range(3):
            choice.engine.maps(raster)
    for _ in range(args.rounds):
        for row in rows:
            start = time.perf_counter()
            row["engine"].maps(row["raster"])
            row["spent"].append((time.perf_counter() - start) * 1e3)
            if args.tta:
                start = time.perf_counter()
                _symmetry_averaged(row["engine"], row["raster"])
                row["spent_tta"].append((time.perf_counter() - start) * 1e3)
    print(f"load average after {os.getloadavg()}; {args.rounds} calls each, interleaved\n")
    print("| checkpoint | task | network | parameters | MFLOPs (batch 1) | engine | median ms | p95 ms |")
    print("|---|---|---|---|---|---|---|---|")
    for row in rows:
        spent = np.array(row["spent"])
        print(f"| {row['name']} | {row['task']} | {row['net']} | {row['params']:,} | "
              f"{row['flops'] / 1e6:,.0f} | {row['engine'].name} | {np.median(spent):.2f} | "
              f"{np.percentile(spent, 95):.2f} |")
        if args.tta:
            spent = np.array(row["spent_tta"])
            print(f"| {row['name']} (8 symmetries averaged) | {row['task']} | {row['net']} | "
                  f"{row['params']:,} | {8 * row['flops'] / 1e6:,.0f} | {row['engine'].name} | "
                  f"{np.median(spent):.2f} | {np.percentile(spent, 95):.2f} |")


if __name__ == "__main__":
    main()
