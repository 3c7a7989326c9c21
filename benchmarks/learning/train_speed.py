"""Training samples/s of the shipped U-Net: the old setting (float32, batch 16) against the new default.

Both settings run the real data path of ``uav-swarm train`` (``ShardDataset`` with the 8
symmetries and on-the-fly two-Gaussian targets, ``DataLoader``, Adam, MSE) on synthetic
64x64 rasters, in interleaved rounds so that a change of machine load hits both alike.
The new default is ``learning.train.TrainConfig``'s: bfloat16 autocast where the CPU has
native bfloat16 (float32 master weights and loss), channels-last tensors, and its batch
size. The CPU flags that decide the precision are printed first. Then batch-1 inference
of the same network, float32 against bfloat16, and the share of a training step spent
in the data loader.

Usage: python benchmarks/learning/train_speed.py [--threads T] [--seconds S] [--rounds R] [--batch B ...]
"""

from __future__ import annotations

import argparse
import platform
import statistics
import time

import numpy as np
import torch
import torch.nn.functional as F
from torch.utils.data import DataLoader

from learning.loader import ShardDataset
from learning.model import ModelConfig, build_model
from learning.precision import BF16_CPU_FLAGS, autocast, cpu_flags, resolve_precision
from learning.targets import TargetConfig
from learning.train import TrainConfig

MODEL = ModelConfig(arch="unet", in_channels=2, width=16, depth=3, coord_channels=True)
TARGETS = TargetConfig(alpha2=30.0, sigma2=5.0)


def synthetic_arrays(n: int, size: int, seed: int = 0) -> dict[str, np.ndarray]:
    """``n`` random two-channel rasters with 1-10 random positions each (the AGP input shape)."""
    rng = np.random.default_rng(seed)
    counts = rng.integers(1, 11, size=n)
    return {
        "inputs": rng.random((n, 2, size, size), dtype=np.float32),
        "positions": rng.uniform(0, size - 1, size=(n, 10, 2)),
        "mask": np.arange(10)[None, :] < counts[:, None],
    }


def train_rate(setting: dict, dataset: ShardDataset, seconds: float, seed: int) -> tuple[float, float]:
    """Training samples/s over about ``seconds``, and the share of that time spent waiting on the loader."""
    torch.manual_seed(seed)
    memory_format = torch.channels_last if setting["channels_last"] else torch.contiguous_format
    model = build_model(MODEL).to(memory_format=memory_format).train()
    optimizer = torch.optim.Adam(model.parameters(), lr=1e-3)
    loader = DataLoader(dataset, batch_size=setting["batch"], shuffle=True,
                        generator=torch.Generator().manual_seed(seed))
    device = torch.device("cpu")
    samples, waited, t0 = 0, 0.0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        t_wait = time.perf_counter()
        for x, y in loader:
            waited += time.perf_counter() - t_wait
            x = x.contiguous(memory_format=memory_format)  # (B, C, h, w)
            y = y.contiguous(memory_format=memory_format)  # (B, 1, h, w)
            with autocast(setting["precision"], device):
                u = model(x)
            loss = F.mse_loss(u.float(), y)
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            optimizer.step()
            samples += len(x)
            if time.perf_counter() - t0 >= seconds:
                break
            t_wait = time.perf_counter()
    elapsed = time.perf_counter() - t0
    return samples / elapsed, waited / elapsed


@torch.inference_mode()
def latency_ms(model: torch.nn.Module, x: torch.Tensor, repeats: int = 200) -> float:
    """Median wall time of ``model(x)`` in milliseconds."""
    for _ in range(10):
        model(x)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        model(x)
        times.append(time.perf_counter() - t0)
    return 1000 * statistics.median(times)


def main() -> None:
    default = TrainConfig()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="training time per setting and round")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--threads", type=int, default=2, help="torch CPU threads")
    parser.add_argument("--batch", type=int, nargs="+", default=[default.batch_size],
                        help="batch sizes of the new setting (default: TrainConfig's)")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    cpu = torch.device("cpu")
    new_precision = resolve_precision(default.precision, cpu)
    flags = sorted(BF16_CPU_FLAGS & cpu_flags())
    print(f"{platform.processor() or platform.machine()}; bfloat16 flags: {', '.join(flags) or 'none'}; "
          f"AVX-512: {'avx512f' in cpu_flags()}; torch {torch.__version__}, "
          f"{torch.get_num_threads()} threads")
    print(f"new default precision on this CPU: {new_precision}")

    dataset = ShardDataset(synthetic_arrays(4096, 64), TARGETS, augment=True, augment_seed=0)
    old = "float32, batch 16 (old default)"
    settings = {old: {"precision": "float32", "batch": 16, "channels_last": False}}
    for batch in args.batch:
        settings[f"{new_precision}, channels-last, batch {batch}"] = {
            "precision": new_precision, "batch": batch, "channels_last": True}
    rates: dict[str, list[float]] = {name: [] for name in settings}
    waits: dict[str, list[float]] = {name: [] for name in settings}
    for round_ in range(args.rounds):
        for name, setting in settings.items():
            rate, wait = train_rate(setting, dataset, args.seconds, seed=round_)
            rates[name].append(rate)
            waits[name].append(wait)
    reference = statistics.median(rates[old])
    print("\n| setting | train samples/s (median of rounds) | vs float32 batch 16 | loader share of time |")
    print("|---|---|---|---|")
    for name in settings:
        rate, wait = statistics.median(rates[name]), statistics.median(waits[name])
        print(f"| {name} | {rate:.1f} | {rate / reference:.2f}x | {100 * wait:.1f} % |")

    torch.manual_seed(0)
    model = build_model(MODEL).eval()
    x = torch.rand(1, 2, 64, 64)
    fp32 = latency_ms(model, x)
    fast = build_model(MODEL).eval().to(dtype=torch.bfloat16, memory_format=torch.channels_last)
    bf16 = latency_ms(fast, x.to(torch.bfloat16).contiguous(memory_format=torch.channels_last))
    print(f"\nbatch-1 inference: float32 {fp32:.2f} ms, bfloat16 channels-last {bf16:.2f} ms "
          f"({fp32 / bf16:.2f}x)")


if __name__ == "__main__":
    main()
