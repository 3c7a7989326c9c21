"""Inference: rasters -> utility maps -> positions, in batches or one raster at a time.

A replan has a budget of a few milliseconds, so this path avoids autograd
(``torch.inference_mode``), keeps the model on its device in eval mode, and
reuses the CoordConv grid that the model builds once per raster shape. Precision
is that of :mod:`learning.precision` (bfloat16 autocast where native).

The engine (:mod:`learning.engines`) is chosen at load by measuring: :func:`select_engine` builds the
candidates the machine has (ONNX Runtime when installed, a traced TorchScript graph, eager torch),
keeps those whose maps equal eager float32 within :data:`EXACT_TOLERANCE` on every pixel of probe
rasters, times each at batch 1 and returns the fastest. A candidate whose package is missing is
skipped with a log line, never an error; eager float32 is always there.

Test-time augmentation (``tta=True``): the utility map is the mean of the maps of
the 8 symmetries of the square raster (flips and transposition), each mapped back,
computed in one batch. It needs a square raster and a task whose rule commutes with
the symmetries (the same condition as training augmentation).
"""

from __future__ import annotations

import hashlib
import logging
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np
import torch

from learning.engines import ENGINES, Engine, build_engine
from learning.model import UtilityNet
from learning.peaks import PeakConfig, find_peaks
from learning.precision import Precision, autocast
from learning.symmetry import SYMMETRIES, transform_vector_channels

__all__ = ["SYMMETRIES", "EXACT_TOLERANCE", "BFLOAT16_TOLERANCE", "EngineChoice", "select_engine",
           "apply_symmetry", "invert_symmetry", "utility_maps", "utility_map", "predict_positions"]

logger = logging.getLogger(__name__)

EXACT_TOLERANCE = 1e-3
"""Largest difference on any pixel between a float32 engine's map and eager float32's (map units)."""

BFLOAT16_TOLERANCE = 0.05
"""bfloat16's tolerance, relative to ``max(1, |map|)``: bfloat16 keeps 8 bits of mantissa, so its maps
are never "equal" to float32's; it runs only when asked for (``precision = "bfloat16"``)."""

EXACT_ENGINES = ("onnxruntime", "torch-jit", "torch-eager")
"""The float32 candidates, tried in this order (the last is always available)."""


@dataclass
class EngineChoice:
    """The engine :func:`select_engine` chose, and why.

    Attributes:
        engine: The fastest candidate that passed the comparison.
        timings_ms: Median batch-1 milliseconds of every candidate that was measured.
        skipped: Why each other candidate was left out (package missing, maps differ).
    """

    engine: Engine
    timings_ms: dict[str, float] = field(default_factory=dict)
    skipped: dict[str, str] = field(default_factory=dict)

    @property
    def name(self) -> str:
        """The chosen engine's name."""
        return self.engine.name


_CHOICES: dict[tuple, EngineChoice] = {}


def _fingerprint(model: UtilityNet) -> str:
    """A digest of the network's configuration and weights (equal networks share their engines)."""
    digest = hashlib.sha256(repr(model.config).encode())
    for name, tensor in model.state_dict().items():
        digest.update(f"{name}:{tensor.dtype}".encode())
        digest.update(tensor.detach().cpu().float().contiguous().numpy().tobytes())
    return digest.hexdigest()


def _within(name: str, maps: np.ndarray, reference: np.ndarray) -> bool:
    """Whether ``maps`` match the float32 reference within ``name``'s tolerance."""
    if maps.shape != reference.shape or not np.all(np.isfinite(maps)):
        return False
    gap = float(np.abs(maps - reference).max()) if maps.size else 0.0
    if name.endswith("-bf16"):
        return gap <= BFLOAT16_TOLERANCE * max(1.0, float(np.abs(reference).max()))
    return gap <= EXACT_TOLERANCE


def select_engine(model: UtilityNet, shape: tuple[int, int, int], precision: Precision = "float32",
                  threads: int = 1, engines: Sequence[str] | None = None, trials: int = 15) -> EngineChoice:
    """The fastest engine for ``model`` on ``(C, h, w)`` inputs whose maps equal eager float32's.

    Candidates: ``engines`` when given, else :data:`EXACT_ENGINES` for float32 and
    ``torch-eager-bf16`` for bfloat16. Each is built, compared with eager float32 on seeded probe
    rasters (:data:`EXACT_TOLERANCE`, :data:`BFLOAT16_TOLERANCE` for bfloat16), timed at batch 1
    (``trials`` calls each, interleaved so that the machine's load hits all alike) and the fastest
    median wins. A candidate that cannot be built (missing package) or differs is skipped with a log
    line; when none is left, eager float32 runs. Choices are cached per network, shape and settings.

    Args:
        model: The network.
        shape: The input shape ``(C, h, w)``.
        precision: ``"float32"`` or ``"bfloat16"``.
        threads: ONNX Runtime's threads (torch's are the process's, ``torch.set_num_threads``).
        engines: Candidate names from :data:`learning.engines.ENGINES`.
        trials: Timed calls per candidate.

    Raises:
        ValueError: An unknown engine or precision, or ``shape`` does not fit the network.
    """
    if precision not in ("float32", "bfloat16"):
        raise ValueError(f"precision = {precision!r} is not allowed: choose 'float32' or 'bfloat16'")
    default = EXACT_ENGINES if precision == "float32" else ("torch-eager-bf16",)
    names = tuple(engines) if engines else default
    unknown = [n for n in names if n not in ENGINES]
    if unknown:
        raise ValueError(f"engine(s) {unknown} not allowed: choose from {list(ENGINES)}")
    channels, height, width = (int(v) for v in shape)
    shape = (channels, height, width)
    key = (_fingerprint(model), shape, names, threads, trials)
    if key in _CHOICES:
        return _CHOICES[key]
    reference_engine = build_engine("torch-eager", model, shape)
    probes = np.random.default_rng(0).random((3, *shape), dtype=np.float32)
    probes[0] = 0.0
    reference = reference_engine.maps(probes)
    choice = EngineChoice(reference_engine)
    built: list[Engine] = []
    for name in names:
        try:
            engine = reference_engine if name == "torch-eager" else build_engine(name, model, shape, threads)
        except ImportError as exc:
            missing = exc.name or str(exc)
            choice.skipped[name] = f"not installed ({missing}; pip install {missing})"
            logger.info("inference engine %s skipped: %s is not installed (pip install %s: a dependency "
                        "of uav-swarm, which reinstalling it restores)", name, missing, missing)
            continue
        except Exception as exc:  # an exporter's failure must not stop the planner
            choice.skipped[name] = f"failed to build: {exc}"
            logger.warning("inference engine %s skipped: it failed to build (%s)", name, exc)
            continue
        if not _within(name, engine.maps(probes), reference):
            choice.skipped[name] = "maps differ from eager float32"
            logger.warning("inference engine %s skipped: its maps differ from eager float32", name)
            continue
        built.append(engine)
    if built:
        choice.timings_ms = _time(built, probes[1:2], trials)
        choice.engine = min(built, key=lambda e: choice.timings_ms[e.name])
    else:
        logger.warning("no requested inference engine is usable: eager float32 runs")
    logger.info("inference engine: %s (batch-1 median ms: %s)", choice.name,
                ", ".join(f"{n} {t:.2f}" for n, t in choice.timings_ms.items()) or "not measured")
    _CHOICES[key] = choice
    return choice


def _time(engines: list[Engine], probe: np.ndarray, trials: int) -> dict[str, float]:
    """Median milliseconds of one call of each engine on ``probe``, calls interleaved."""
    for engine in engines:  # warm-up: first-call allocations, kernel selection
        for _ in range(3):
            engine.maps(probe)
    spent: dict[str, list[float]] = {e.name: [] for e in engines}
    for _ in range(trials):
        for engine in engines:
            start = time.perf_counter()
            engine.maps(probe)
            spent[engine.name].append((time.perf_counter() - start) * 1e3)
    return {name: float(np.median(values)) for name, values in spent.items()}



def apply_symmetry(x: torch.Tensor, flip_x: bool, flip_y: bool, transpose: bool) -> torch.Tensor:
    """``x`` ``(..., h, w)`` flipped along x (columns), then y (rows), then transposed."""
    if flip_x:
        x = x.flip(-1)
    if flip_y:
        x = x.flip(-2)
    return x.transpose(-2, -1) if transpose else x


def invert_symmetry(x: torch.Tensor, flip_x: bool, flip_y: bool, transpose: bool) -> torch.Tensor:
    """The inverse of :func:`apply_symmetry` with the same arguments."""
    if transpose:
        x = x.transpose(-2, -1)
    if flip_y:
        x = x.flip(-2)
    return x.flip(-1) if flip_x else x


def _forward(model: UtilityNet, x: torch.Tensor, precision: Precision, tta: bool) -> torch.Tensor:
    """``(B, h, w)`` float32 utility maps of a ``(B, C, h, w)`` batch."""
    device = x.device
    if not tta:
        with autocast(precision, device):
            return model(x)[:, 0].float()
    if x.shape[-1] != x.shape[-2]:
        raise ValueError(f"test-time augmentation needs square rasters, got {tuple(x.shape[-2:])}")
    vectors = model.config.vector_channels
    views = torch.cat([transform_vector_channels(apply_symmetry(x, *s), vectors, *s)
                       for s in SYMMETRIES])  # (8B, C, h, w)
    with autocast(precision, device):
        maps = model(views.contiguous(memory_format=torch.channels_last))[:, 0].float()  # (8B, h, w)
    b = len(x)
    return torch.stack([invert_symmetry(maps[i * b:(i + 1) * b], *s)
                        for i, s in enumerate(SYMMETRIES)]).mean(dim=0)  # (B, h, w)


def _batches(inputs: np.ndarray, batch_size: int) -> Iterator[np.ndarray]:
    for start in range(0, len(inputs), batch_size):
        yield inputs[start:start + batch_size]


@torch.inference_mode()
def utility_maps(model: UtilityNet, inputs: np.ndarray, precision: Precision = "float32", tta: bool = False,
                 batch_size: int = 64) -> np.ndarray:
    """The ``(n, h, w)`` float32 utility maps of ``(n, C, h, w)`` rasters.

    Args:
        model: A utility network (set to eval mode).
        inputs: The rasters.
        precision: ``"float32"`` or ``"bfloat16"`` (autocast; see :mod:`learning.precision`).
        tta: Average the maps of the 8 grid symmetries (square rasters only).
        batch_size: Rasters per forward pass (times 8 with ``tta``).

    Raises:
        ValueError: ``inputs`` is not ``(n, C, h, w)`` with the model's channel count, or
            ``tta`` with a non-square raster.
    """
    inputs = np.asarray(inputs, dtype=np.float32)
    if inputs.ndim != 4 or inputs.shape[1] != model.config.in_channels:
        raise ValueError(f"inputs shape {inputs.shape} must be (n, C={model.config.in_channels}, h, w)")
    model.eval()
    device = next(model.parameters()).device
    out = [_forward(model, torch.from_numpy(chunk).to(device).contiguous(memory_format=torch.channels_last),
                    precision, tta).cpu().numpy() for chunk in _batches(inputs, batch_size)]
    return np.concatenate(out) if out else np.zeros((0, *inputs.shape[-2:]), dtype=np.float32)


def utility_map(model: UtilityNet, raster: np.ndarray, precision: Precision = "float32", tta: bool = False
                ) -> np.ndarray:
    """The ``(h, w)`` float32 utility map of one ``(C, h, w)`` raster.

    Raises:
        ValueError: ``raster`` is not ``(C, h, w)`` with the model's channel count.
    """
    raster = np.asarray(raster, dtype=np.float32)
    if raster.ndim != 3 or raster.shape[0] != model.config.in_channels:
        raise ValueError(f"raster shape {raster.shape} must be (C={model.config.in_channels}, h, w)")
    return utility_maps(model, raster[None], precision, tta)[0]


def predict_positions(model: UtilityNet, raster: np.ndarray, k: int = 10, peaks: PeakConfig | None = None,
                      precision: Precision = "float32", tta: bool = False) -> np.ndarray:
    """Placement for one raster: the at most ``k`` peaks of the model's utility map.

    Args:
        model: A trained utility network (e.g. ``load_checkpoint(path).model``).
        raster: ``(C, h, w)`` observation.
        k: Most positions to return (the UAVs available).
        peaks: Peak extraction settings; the checkpoint's ``peak_config`` is the
            one validated in training.
        precision: Network precision (see :func:`utility_maps`).
        tta: Test-time augmentation (see :func:`utility_maps`).

    Returns:
        ``(m, 2)`` float64 pixel positions ``(x=column, y=row)``, ``m <= k``, by decreasing utility.
    """
    return find_peaks(utility_map(model, raster, precision, tta), peaks, max_peaks=k, raster=raster)
