"""Training samples/s and batch-1 inference latency of the utility networks, against the paper's network.

Trains the paper's network (the reference) and our U-Net variant on random 64×64
rasters and two-Gaussian targets (Adam, MSE, batch 16) in interleaved rounds, so
a machine whose load changes affects both alike; then times batch-1 inference
(eager, and ``torch.compile`` unless ``--no-compile``), peak extraction, and the
on-the-fly target rendering of the data loader.

On a shared 2-core machine, two torch threads can be several times slower than one
(OpenMP threads spin while the other core is busy): compare ``--threads 1`` and ``--threads 2``.

Usage: python benchmarks/train_speed.py [--threads T] [--seconds S] [--rounds R] [--size PX] [--batch B]
       [--no-compile]
"""

from __future__ import annotations

import argparse
import platform
import statistics
import time

import numpy as np
import torch
import torch.nn.functional as F

from learning.model import ModelConfig, build_model
from learning.peaks import find_peaks
from learning.targets import TargetConfig, render_targets

MODELS = {
    "paper (reference)": ModelConfig(arch="paper"),
    "unet w16 d3 coord": ModelConfig(arch="unet", width=16, depth=3, coord_channels=True),
}
ISSUE_REFERENCE_SAMPLES_S = 107.0  # the baseline's speed quoted in issue 3 (2-core CPU, 64², batch 16)


def train_rate(model: torch.nn.Module, x: torch.Tensor, y: torch.Tensor, seconds: float) -> float:
    """Training samples per second over about ``seconds``."""
    optimizer = torch.optim.Adam(model.parameters(), lr=1e-3)
    steps, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        loss = F.mse_loss(model(x), y)
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        steps += 1
    return steps * len(x) / (time.perf_counter() - t0)


@torch.inference_mode()
def latency_ms(fn, x: torch.Tensor, repeats: int = 50) -> float:
    """Median wall time of ``fn(x)`` in milliseconds."""
    for _ in range(5):
        fn(x)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn(x)
        times.append(time.perf_counter() - t0)
    return 1000 * statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=5.0, help="training time per model and round")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--size", type=int, default=64)
    parser.add_argument("--batch", type=int, default=16)
    parser.add_argument("--threads", type=int, default=0, help="torch CPU threads (0: torch's default)")
    parser.add_argument("--no-compile", action="store_true", help="skip torch.compile")
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    print(f"{platform.processor() or platform.machine()}, {torch.get_num_threads()} torch threads, "
          f"torch {torch.__version__}, {args.size}x{args.size}, batch {args.batch}")

    rng = np.random.default_rng(0)
    x = torch.from_numpy(rng.random((args.batch, 1, args.size, args.size), dtype=np.float32))
    targets = TargetConfig(alpha2=50.0, sigma2=12.5)
    positions = [rng.uniform(0, args.size - 1, size=(5, 2)) for _ in range(args.batch)]
    y = torch.from_numpy(np.stack([render_targets(p, (args.size, args.size), targets) / 255.0
                                   for p in positions])[:, None])
    torch.manual_seed(0)
    models = {name: build_model(cfg) for name, cfg in MODELS.items()}
    rates: dict[str, list[float]] = {name: [] for name in models}
    for _ in range(args.rounds):
        for name, model in models.items():
            model.train()
            rates[name].append(train_rate(model, x, y, args.seconds))
    reference = statistics.median(rates["paper (reference)"])
    print("\n| model | parameters | train samples/s (median of rounds) | vs paper net | vs issue's 107/s |")
    print("|---|---|---|---|---|")
    for name, model in models.items():
        rate = statistics.median(rates[name])
        n_params = sum(p.numel() for p in model.parameters())
        print(f"| {name} | {n_params:,} | {rate:.1f} | {rate / reference:.2f} | "
              f"{rate / ISSUE_REFERENCE_SAMPLES_S:.2f} |")

    x1 = x[:1]
    print("\n| model | eager batch-1 ms | compiled ms | compiled / eager |")
    print("|---|---|---|---|")
    for name, model in models.items():
        model.eval()
        eager = latency_ms(model, x1)
        if args.no_compile:
            print(f"| {name} | {eager:.2f} | - | - |")
            continue
        compiled_model = torch.compile(model)
        t0 = time.perf_counter()
        with torch.inference_mode():
            compiled_model(x1)
        compile_s = time.perf_counter() - t0
        compiled = latency_ms(compiled_model, x1)
        print(f"| {name} | {eager:.2f} | {compiled:.2f} (compile {compile_s:.0f} s) "
              f"| {compiled / eager:.2f} |")

    utility = models["paper (reference)"](x1)[0, 0].detach().numpy()
    peaks_ms = latency_ms(lambda u: find_peaks(u), utility)
    render_us = 1000 * latency_ms(lambda p: render_targets(p, (args.size, args.size), targets), positions[0])
    print(f"\npeak extraction on a {args.size}² map: {peaks_ms:.3f} ms; "
          f"target rendering (5 positions): {render_us:.0f} µs per sample")


if __name__ == "__main__":
    main()
