"""What a narrower utility network would cost and save: arithmetic, inference and training time per sample.

    python benchmarks/learning/student_cost.py --width 8 --rounds 300 --steps 40
    python benchmarks/learning/student_cost.py --task wifi-s2-80211 --width 8 --width 4 --steps 0

Builds a shipped network's architecture (the teacher, ``--task``: the checkpoint's name, default
``wifi-s1``) and the same with each ``--width`` and ``--depth`` (the students: narrower, or wider or
deeper for a capacity experiment), untrained (time and arithmetic do not depend on the weights), and
measures in one run: forward FLOPs at batch 1, the median batch-1 inference time on one thread in eager
float32 and on ONNX Runtime (the planner's default engine, :func:`learning.engines.build_engine`; the
calls interleaved over the networks so that the machine's load hits all alike), and the median time of a
training step at batch 16 (bfloat16 autocast where the CPU has it, as ``uav-swarm train``; ``--steps 0``
skips it), with the machine and its load average before and after.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np
import torch
from torch.utils.flop_counter import FlopCounterMode

from learning.checkpoint import load_checkpoint
from learning.engines import build_engine
from learning.model import UtilityNet, build_model
from learning.precision import resolve_precision
from uav_swarm.planning.planner import default_checkpoint


def _flops(model: torch.nn.Module, x: torch.Tensor) -> int:
    with FlopCounterMode(display=False) as counter, torch.no_grad():
        model(x)
    return counter.get_total_flops()


def _infer_ms(model: torch.nn.Module, x: torch.Tensor, rounds: int) -> float:
    times = []
    with torch.inference_mode():
        for _ in range(rounds):
            start = time.perf_counter()
            model(x)
            times.append(time.perf_counter() - start)
    return 1e3 * float(np.median(times))


def _onnx_ms(models: list[UtilityNet], shape: tuple[int, int, int], rounds: int) -> list[float]:
    """Median batch-1 time of each model on ONNX Runtime (one thread), calls interleaved over the models."""
    engines = [build_engine("onnxruntime", model, shape, threads=1) for model in models]
    x = np.random.default_rng(0).random((1, *shape), dtype=np.float32)
    times: list[list[float]] = [[] for _ in engines]
    for _ in range(rounds):
        for engine, row in zip(engines, times, strict=True):
            start = time.perf_counter()
            engine.maps(x)
            row.append(time.perf_counter() - start)
    return [1e3 * float(np.median(row[2:])) for row in times]


def _train_ms_per_sample(model: torch.nn.Module, shape: tuple[int, ...], steps: int, dtype: torch.dtype
                         ) -> float:
    optimiser = torch.optim.Adam(model.parameters(), lr=1e-3)
    x, y = torch.rand(16, *shape), torch.rand(16, 1, *shape[1:])
    times = []
    for _ in range(steps):
        start = time.perf_counter()
        with torch.autocast("cpu", dtype=dtype, enabled=dtype == torch.bfloat16):
            loss = torch.nn.functional.mse_loss(model(x).float().reshape(y.shape), y)
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        times.append(time.perf_counter() - start)
    return 1e3 * float(np.median(times[2:])) / 16


def main() -> None:
    """Measure the teacher and the student."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--task", default="wifi-s1",
                        help="the shipped checkpoint whose network is the teacher (default: %(default)s)")
    parser.add_argument("--width", type=int, action="append", default=None,
                        help="a student's first-block width, once per student (default: 8)")
    parser.add_argument("--depth", type=int, default=None,
                        help="the student's poolings (default: the teacher's)")
    parser.add_argument("--rounds", type=int, default=300,
                        help="timed inference rounds (default: %(default)s)")
    parser.add_argument("--steps", type=int, default=40,
                        help="timed training steps, 0: none (default: %(default)s)")
    args = parser.parse_args()
    print(f"machine: {platform.machine()}, {os.cpu_count()} CPUs, torch {torch.__version__}; "
          f"load average {_load()}")
    teacher_ckpt = load_checkpoint(default_checkpoint(args.task))
    shape = tuple(teacher_ckpt.input_shape)
    precision = resolve_precision("auto", torch.device("cpu"))
    dtype = torch.bfloat16 if precision == "bfloat16" else torch.float32
    x = torch.rand(1, *shape)
    print("| network | width | depth | parameters | GFLOP (batch 1) | inference ms (1 thread, float32 eager) "
          f"| ONNX Runtime ms (1 thread) | training ms per sample (batch 16, {precision}, 2 threads) |")
    print("|---|---|---|---|---|---|---|---|")
    teacher = teacher_ckpt.model_config
    configs = [(f"teacher ({args.task}, shipped)", teacher)] + [
        ("student", teacher.replace(width=width, depth=args.depth or teacher.depth))
        for width in (args.width or [8])]
    models = [build_model(config).eval() for _, config in configs]
    torch.set_num_threads(1)
    channels, height, width = shape
    onnx = _onnx_ms(models, (channels, height, width), args.rounds)
    for (name, config), model, ort in zip(configs, models, onnx, strict=True):
        torch.set_num_threads(1)
        flops, infer = _flops(model, x), _infer_ms(model, x, args.rounds)
        train = "skipped"
        if args.steps:
            torch.set_num_threads(2)
            train = f"{_train_ms_per_sample(model.train(), shape, args.steps, dtype):.2f}"
        params = sum(p.numel() for p in model.parameters())
        print(f"| {name} | {config.width} | {config.depth} | {params:,} | {flops / 1e9:.3f} | {infer:.2f} "
              f"| {ort:.2f} | {train} |")
    print(f"load average after: {_load()}")


def _load() -> str:
    return ", ".join(f"{v:.2f}" for v in os.getloadavg())


if __name__ == "__main__":
    main()
