"""What a narrower Wi-Fi S1 network would cost and save: arithmetic, inference and training time per sample.

    python benchmarks/learning/student_cost.py --width 8 --rounds 300 --steps 40

Builds the shipped S1 network's architecture (the teacher) and the same with ``--width`` and
``--depth`` (the student: narrower, or wider or deeper for a capacity experiment),
untrained (time and arithmetic do not depend on the weights), and measures in one run: forward FLOPs
at batch 1, the median batch-1 inference time on one thread (eager float32, the planner's exact path
without ONNX Runtime), and the median time of a training step at batch 16 (bfloat16 autocast where the
CPU has it, as ``uav-swarm train``), with the machine and its load average.
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
from learning.model import build_model
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
    parser.add_argument("--width", type=int, default=8,
                        help="the student's first-block width (default: %(default)s)")
    parser.add_argument("--depth", type=int, default=None,
                        help="the student's poolings (default: the teacher's)")
    parser.add_argument("--rounds", type=int, default=300,
                        help="timed inference rounds (default: %(default)s)")
    parser.add_argument("--steps", type=int, default=40, help="timed training steps (default: %(default)s)")
    args = parser.parse_args()
    load = ", ".join(f"{v:.2f}" for v in os.getloadavg())
    print(f"machine: {platform.machine()}, {os.cpu_count()} CPUs, torch {torch.__version__}; "
          f"load average {load}")
    teacher_ckpt = load_checkpoint(default_checkpoint("wifi-s1"))
    shape = tuple(teacher_ckpt.input_shape)
    precision = resolve_precision("auto", torch.device("cpu"))
    dtype = torch.bfloat16 if precision == "bfloat16" else torch.float32
    x = torch.rand(1, *shape)
    print("| network | width | depth | parameters | GFLOP (batch 1) | inference ms (1 thread, float32) "
          f"| training ms per sample (batch 16, {precision}, 2 threads) |")
    print("|---|---|---|---|---|---|---|")
    for name, config in (("teacher (shipped)", teacher_ckpt.model_config),
                         ("student", teacher_ckpt.model_config.replace(
                             width=args.width, depth=args.depth or teacher_ckpt.model_config.depth))):
        model = build_model(config).eval()
        torch.set_num_threads(1)
        flops, infer = _flops(model, x), _infer_ms(model, x, args.rounds)
        torch.set_num_threads(2)
        train = _train_ms_per_sample(model.train(), shape, args.steps, dtype)
        params = sum(p.numel() for p in model.parameters())
        print(f"| {name} | {config.width} | {config.depth} | {params:,} | {flops / 1e9:.3f} | {infer:.2f} "
              f"| {train:.2f} |")


if __name__ == "__main__":
    main()
