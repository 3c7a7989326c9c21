"""Numeric precision of the utility network: bfloat16 where the processor computes it natively.

On CPUs with AVX-512 BF16 or AMX (``lscpu`` flags ``avx512_bf16``, ``amx_bf16``) and on CUDA
devices that support it, bfloat16 autocast trains and runs the network several times faster
than float32 (``benchmarks/learning/train_speed.py``); elsewhere bfloat16 is emulated and slower, so
``"auto"`` picks it only where it is native. Training under autocast keeps float32 master
weights, optimiser state and loss: only the convolutions run in bfloat16.

Examples:
    >>> resolve_precision("float32", torch.device("cpu"))
    'float32'
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Literal

import torch

__all__ = ["PRECISIONS", "Precision", "BF16_CPU_FLAGS", "cpu_flags", "native_bfloat16", "resolve_precision",
           "autocast"]

Precision = Literal["float32", "bfloat16"]
PRECISIONS = ("auto", "float32", "bfloat16")
"""Accepted precision settings; ``"auto"`` resolves to one of the other two."""

BF16_CPU_FLAGS = frozenset({"avx512_bf16", "amx_bf16"})
"""CPU flags (``/proc/cpuinfo``) that mean native bfloat16 arithmetic."""


@functools.cache
def cpu_flags() -> frozenset[str]:
    """The processor's feature flags from ``/proc/cpuinfo`` (empty where that file does not exist)."""
    try:
        text = Path("/proc/cpuinfo").read_text(encoding="utf-8", errors="replace")
    except OSError:
        return frozenset()
    for line in text.splitlines():
        key, _, value = line.partition(":")
        if key.strip() in ("flags", "Features"):
            return frozenset(value.split())
    return frozenset()


def native_bfloat16(device: torch.device) -> bool:
    """Whether ``device`` computes bfloat16 natively (CPU flags, or CUDA's own check)."""
    if device.type == "cuda":
        return bool(torch.cuda.is_available() and torch.cuda.is_bf16_supported())
    if device.type == "cpu":
        return bool(BF16_CPU_FLAGS & cpu_flags())
    return False


def resolve_precision(choice: str, device: torch.device) -> Precision:
    """``"auto"`` -> ``"bfloat16"`` where native on ``device``, else ``"float32"``; others unchanged.

    Raises:
        ValueError: ``choice`` is not one of :data:`PRECISIONS`.
    """
    if choice not in PRECISIONS:
        raise ValueError(f"precision = {choice!r} is not allowed: choose one of {list(PRECISIONS)}")
    if choice == "auto":
        return "bfloat16" if native_bfloat16(device) else "float32"
    return choice  # type: ignore[return-value]


def autocast(precision: Precision, device: torch.device) -> torch.autocast:
    """The autocast context of ``precision`` on ``device`` (disabled for float32)."""
    return torch.autocast(device.type, dtype=torch.bfloat16, enabled=precision == "bfloat16")
