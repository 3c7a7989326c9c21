"""Inference engines: one utility network, several ways to run it, each behind one call.

An engine turns ``(B, C, h, w)`` float32 rasters into ``(B, h, w)`` float32 utility maps. The
engines differ only in how the network's arithmetic is scheduled:

- ``"torch-eager"``: the module as written, float32, channels-last (the reference every other engine
  is compared with);
- ``"torch-eager-bf16"``: the same with bfloat16 weights and activations (only worth it where the
  processor computes bfloat16 natively, see :mod:`learning.precision`); not exact;
- ``"torch-jit"``: the module traced once (``torch.jit.trace``), frozen and optimised for inference
  (constant weights folded into the graph, convolution + ReLU fused);
- ``"onnxruntime"``: the traced graph exported to ONNX in memory and run by ONNX Runtime's CPU
  provider (``onnxruntime`` and ``onnx``, dependencies of the package; without them it is skipped).

Each engine is built for one input shape ``(C, h, w)``; the batch size may change from call to call.
:func:`learning.inference.select_engine` builds the candidates, checks them against the reference
and keeps the fastest.
"""

from __future__ import annotations

import copy
import io
import os
import warnings
from typing import Protocol

import numpy as np
import torch

from learning.model import UtilityNet, with_memory_format

__all__ = ["ENGINES", "Engine", "EagerEngine", "TracedEngine", "OnnxEngine", "build_engine"]

ENGINES = ("onnxruntime", "torch-jit", "torch-eager", "torch-eager-bf16")
"""The engines :func:`build_engine` knows, the float32 ones first."""


class Engine(Protocol):
    """A way to run one utility network on a fixed input shape.

    Attributes:
        name: One of :data:`ENGINES`.
        exact: Whether its maps are float32 arithmetic (held to the float32 tolerance).
    """

    name: str
    exact: bool

    def maps(self, inputs: np.ndarray) -> np.ndarray:
        """``(B, h, w)`` float32 utility maps of ``(B, C, h, w)`` float32 rasters."""
        ...


def _frozen_copy(model: UtilityNet, dtype: torch.dtype = torch.float32) -> UtilityNet:
    """An eval-mode, gradient-free copy of ``model`` in ``dtype`` (the caller's model is left alone)."""
    clone = copy.deepcopy(model).eval().to(dtype=dtype)
    for parameter in clone.parameters():
        parameter.requires_grad_(False)
    if clone.coords is not None:
        clone.coords._grid = None  # built again in the copy's own mode
    return clone


class EagerEngine:
    """The module itself, float32 or bfloat16, channels-last, under ``torch.inference_mode``.

    Args:
        model: The network (copied).
        bfloat16: Run in bfloat16 (name ``torch-eager-bf16``, not exact).
    """

    def __init__(self, model: UtilityNet, bfloat16: bool = False) -> None:
        self._dtype = torch.bfloat16 if bfloat16 else torch.float32
        self._model = with_memory_format(_frozen_copy(model, self._dtype), torch.channels_last)
        self.name = "torch-eager-bf16" if bfloat16 else "torch-eager"
        self.exact = not bfloat16

    def maps(self, inputs: np.ndarray) -> np.ndarray:
        """See :class:`Engine`."""
        with torch.inference_mode():
            x = torch.from_numpy(inputs).to(self._dtype).contiguous(memory_format=torch.channels_last)
            return self._model(x)[:, 0].float().numpy()


def _example(model: UtilityNet, shape: tuple[int, int, int]) -> torch.Tensor:
    """A ``(1, C, h, w)`` example input that checks ``shape`` against the network."""
    if len(shape) != 3 or shape[0] != model.config.in_channels:
        raise ValueError(f"input shape {tuple(shape)} must be (C={model.config.in_channels}, h, w)")
    return torch.zeros((1, *shape))


class TracedEngine:
    """The module traced for one input shape, frozen and optimised for inference (float32).

    Args:
        model: The network (copied).
        shape: The ``(C, h, w)`` input shape.
    """

    name = "torch-jit"
    exact = True

    def __init__(self, model: UtilityNet, shape: tuple[int, int, int]) -> None:
        clone = _frozen_copy(model)
        example = _example(model, shape)
        with torch.no_grad(), warnings.catch_warnings():
            warnings.simplefilter("ignore")  # TorchScript's deprecation notice: the graph is what we test
            traced = torch.jit.trace(clone, example, check_trace=False)
            self._graph = torch.jit.optimize_for_inference(torch.jit.freeze(traced.eval()))

    def maps(self, inputs: np.ndarray) -> np.ndarray:
        """See :class:`Engine`."""
        with torch.inference_mode():
            return self._graph(torch.from_numpy(inputs))[:, 0].numpy()


class OnnxEngine:
    """The module exported to ONNX (in memory) and run by ONNX Runtime on the CPU.

    Args:
        model: The network (copied).
        shape: The ``(C, h, w)`` input shape; the batch axis stays free.
        threads: ONNX Runtime's intra-op threads (0: its default, every core).

    Raises:
        ImportError: ``onnxruntime`` or ``onnx`` (which the exporter needs) is not installed.
    """

    name = "onnxruntime"
    exact = True

    def __init__(self, model: UtilityNet, shape: tuple[int, int, int], threads: int = 1) -> None:
        import onnx  # noqa: F401  (the exporter's own import, checked here for a clear fallback)

        # ONNX Runtime posts usage events to Microsoft unless this is set when it loads (a user value stays)
        os.environ.setdefault("ORT_DISABLE_TELEMETRY", "1")
        import onnxruntime

        clone = _frozen_copy(model)
        example = _example(model, shape)
        graph = io.BytesIO()
        with torch.no_grad(), warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the TorchScript-based exporter's deprecation notice
            torch.onnx.export(clone, (example,), graph,  # type: ignore[arg-type]  # writes to a file object too
                              dynamo=False, input_names=["raster"],
                              output_names=["utility"], opset_version=17,
                              dynamic_axes={"raster": {0: "batch"}, "utility": {0: "batch"}})
        options = onnxruntime.SessionOptions()
        options.intra_op_num_threads = threads
        options.inter_op_num_threads = 1
        options.add_session_config_entry("session.intra_op.allow_spinning", "0")  # a shared CPU: no busy wait
        options.log_severity_level = 3
        self._session = onnxruntime.InferenceSession(graph.getvalue(), options,
                                                     providers=["CPUExecutionProvider"])

    def maps(self, inputs: np.ndarray) -> np.ndarray:
        """See :class:`Engine`."""
        return self._session.run(None, {"raster": inputs})[0][:, 0]


def build_engine(name: str, model: UtilityNet, shape: tuple[int, int, int], threads: int = 1) -> Engine:
    """The engine ``name`` for ``model`` on ``(C, h, w)`` inputs.

    Raises:
        ValueError: ``name`` is not one of :data:`ENGINES`, or ``shape`` does not fit the network.
        ImportError: The engine's optional package is not installed.
    """
    _example(model, shape)
    if name == "onnxruntime":
        return OnnxEngine(model, shape, threads)
    if name == "torch-jit":
        return TracedEngine(model, shape)
    if name in ("torch-eager", "torch-eager-bf16"):
        return EagerEngine(model, bfloat16=name == "torch-eager-bf16")
    raise ValueError(f"engine = {name!r} is not allowed: choose one of {list(ENGINES)}")
