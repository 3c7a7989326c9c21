"""Inference engines: equal maps across engines, the measured choice, clean fallbacks."""

from __future__ import annotations

import logging
import sys

import numpy as np
import pytest
import torch

from learning import inference
from learning.engines import ENGINES, build_engine
from learning.inference import BFLOAT16_TOLERANCE, EXACT_TOLERANCE, select_engine
from learning.model import ModelConfig, build_model

SHAPE = (2, 16, 16)


@pytest.fixture
def model():
    torch.manual_seed(3)
    return build_model(ModelConfig(arch="unet", width=8, depth=2, in_channels=2, coord_channels=True)).eval()


@pytest.fixture(autouse=True)
def fresh_choices(monkeypatch):
    monkeypatch.setattr(inference, "_CHOICES", {})


def rasters(n, seed=0):
    return np.random.default_rng(seed).gamma(0.5, 1.0, size=(n, *SHAPE)).astype(np.float32)


@pytest.mark.parametrize("name", ENGINES)
def test_every_engine_equals_eager_float32_at_any_batch_size(model, name):
    pytest.importorskip("onnxruntime") if name == "onnxruntime" else None
    reference = build_engine("torch-eager", model, SHAPE)
    engine = build_engine(name, model, SHAPE)
    for n in (1, 5):
        x = rasters(n, seed=n)
        expected = reference.maps(x)
        got = engine.maps(x)
        assert got.shape == (n, 16, 16) and got.dtype == np.float32
        assert expected.std() > 1e-3  # a map worth comparing
        gap = np.abs(got - expected).max()
        if engine.exact:
            assert gap <= EXACT_TOLERANCE
        else:
            assert gap <= BFLOAT16_TOLERANCE * max(1.0, np.abs(expected).max())
    with torch.inference_mode():  # and eager float32 is the module itself
        direct = model(torch.from_numpy(rasters(2)))[:, 0].numpy()
    np.testing.assert_allclose(reference.maps(rasters(2)), direct, atol=1e-5)


def test_the_choice_is_the_fastest_equal_engine_and_is_cached(model):
    choice = select_engine(model, SHAPE, trials=3)
    available = {"torch-jit", "torch-eager"} | ({"onnxruntime"} if "onnxruntime" in sys.modules
                                                or _installed("onnxruntime") else set())
    assert set(choice.timings_ms) == available and not choice.skipped
    assert choice.name == min(choice.timings_ms, key=choice.timings_ms.get)
    assert choice.engine.exact
    assert select_engine(model, SHAPE, trials=3) is choice


def test_a_missing_package_is_skipped_with_a_log_line(model, monkeypatch, caplog):
    monkeypatch.setitem(sys.modules, "onnxruntime", None)  # import onnxruntime -> ImportError
    with caplog.at_level(logging.INFO, logger="learning.inference"):
        choice = select_engine(model, SHAPE, trials=2)
    assert "onnxruntime" not in choice.timings_ms and "not installed" in choice.skipped["onnxruntime"]
    assert "inference engine onnxruntime skipped: onnxruntime is not installed (pip install onnxruntime" in \
        caplog.text
    assert choice.name in ("torch-jit", "torch-eager")
    only = select_engine(model, SHAPE, engines=["onnxruntime"], trials=2)  # asked for, missing: eager runs
    assert only.name == "torch-eager" and "no requested inference engine is usable" in caplog.text


def test_an_engine_whose_maps_differ_is_not_chosen(model, monkeypatch, caplog):
    real = inference.build_engine

    class Off:
        name, exact = "torch-jit", True

        def __init__(self, engine):
            self.engine = engine

        def maps(self, x):
            return self.engine.maps(x) + 2 * EXACT_TOLERANCE

    def build(name, *args):
        return Off(real("torch-eager", *args[:2])) if name == "torch-jit" else real(name, *args)

    monkeypatch.setattr(inference, "build_engine", build)
    choice = select_engine(model, SHAPE, engines=["torch-jit", "torch-eager"], trials=2)
    assert choice.name == "torch-eager" and choice.skipped == {"torch-jit": "maps differ from eager float32"}
    assert "torch-jit skipped: its maps differ" in caplog.text


def test_bad_requests_are_refused(model):
    with pytest.raises(ValueError, match="engine"):
        select_engine(model, SHAPE, engines=["tensorrt"])
    with pytest.raises(ValueError, match="precision"):
        select_engine(model, SHAPE, precision="float16")
    with pytest.raises(ValueError, match="input shape"):
        build_engine("torch-eager", model, (3, 16, 16))


def _installed(name):
    import importlib.util

    return importlib.util.find_spec(name) is not None
