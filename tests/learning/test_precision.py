import pytest
import torch

from learning import precision
from learning.precision import autocast, native_bfloat16, resolve_precision


def test_auto_follows_the_cpu_flags(monkeypatch):
    cpu = torch.device("cpu")
    monkeypatch.setattr(precision, "cpu_flags", lambda: frozenset({"avx2", "avx512f"}))
    assert not native_bfloat16(cpu) and resolve_precision("auto", cpu) == "float32"
    monkeypatch.setattr(precision, "cpu_flags", lambda: frozenset({"avx512f", "avx512_bf16"}))
    assert native_bfloat16(cpu) and resolve_precision("auto", cpu) == "bfloat16"
    monkeypatch.setattr(precision, "cpu_flags", lambda: frozenset({"amx_bf16", "amx_tile"}))
    assert resolve_precision("auto", cpu) == "bfloat16"


def test_explicit_choices_are_kept_and_unknown_ones_refused():
    cpu = torch.device("cpu")
    assert resolve_precision("float32", cpu) == "float32"
    assert resolve_precision("bfloat16", cpu) == "bfloat16"
    with pytest.raises(ValueError, match="precision = 'float16' is not allowed"):
        resolve_precision("float16", cpu)


def test_cpu_flags_of_this_machine_are_read():
    flags = precision.cpu_flags()
    assert isinstance(flags, frozenset)
    # on Linux x86 the flags always name the base instruction set
    if flags:
        assert "fpu" in flags or "fp" in flags or "sse2" in flags


def test_autocast_runs_convolutions_in_bfloat16_only_when_asked():
    conv = torch.nn.Conv2d(1, 2, 3)
    x = torch.rand(1, 1, 8, 8)
    cpu = torch.device("cpu")
    with autocast("bfloat16", cpu):
        assert conv(x).dtype == torch.bfloat16
    with autocast("float32", cpu):
        assert conv(x).dtype == torch.float32
    assert conv.weight.dtype == torch.float32  # master weights untouched
