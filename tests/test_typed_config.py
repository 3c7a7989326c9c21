from dataclasses import dataclass
from typing import Literal

import pytest

import typed_config
from typed_config import Config, ConfigError, load_toml, param


@dataclass(frozen=True)
class Inner(Config):
    gain: float = param(1.0, gt=0.0, le=10.0, doc="gain")


@dataclass(frozen=True)
class Outer(Config):
    n_uavs: int = param(10, ge=1, le=10, doc="UAVs")
    mode: Literal["velocity", "waypoint"] = param("velocity", doc="action mode")
    sizes: tuple[int, int] = param((64, 64), doc="raster shape")
    scale: float | None = param(None, gt=0.0, doc="optional scale")
    inner: Inner = param(Inner(), doc="nested")


def test_defaults_and_coercion():
    cfg = Outer.from_dict({"sizes": [32, 16], "inner": {"gain": 2}})
    assert cfg.sizes == (32, 16)
    assert cfg.inner.gain == 2.0 and isinstance(cfg.inner.gain, float)
    assert cfg.to_dict() == {"n_uavs": 10, "mode": "velocity", "sizes": [32, 16], "scale": None,
                             "inner": {"gain": 2.0}}
    assert Outer.from_dict(cfg.to_dict()) == cfg


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"n_uavs": 11}, r"Outer.n_uavs = 11 is out of range: allowed 1 <= n_uavs <= 10"),
        ({"n_uavs": 2.5}, r"Outer.n_uavs = 2.5 must be an integer"),
        ({"n_uavs": True}, r"must be an integer"),
        ({"mode": "teleport"},
         r"Outer.mode = 'teleport' is not allowed: choose one of \['velocity', 'waypoint'\]"),
        ({"sizes": [1, 2, 3]}, r"Outer.sizes .* must have exactly 2 items"),
        ({"scale": -1}, r"Outer.scale = -1.0 is out of range: allowed 0.0 < scale"),
        ({"inner": {"gain": 0}}, r"Outer.inner.gain = 0.0 is out of range"),
        ({"inner": {"gian": 1}}, r"Outer.inner: unknown key\(s\) \['gian'\]"),
        ({"n_uvas": 3}, r"unknown key\(s\) \['n_uvas'\] \(did you mean 'n_uavs'\?\); allowed keys are"),
    ],
    ids=["range", "float-for-int", "bool-for-int", "literal", "tuple-length", "optional-range",
         "nested-range", "nested-unknown", "unknown"],
)
def test_errors_name_the_field_and_range(data, message):
    with pytest.raises(ConfigError, match=message):
        Outer.from_dict(data)


def test_direct_construction_is_validated_too():
    with pytest.raises(ConfigError, match="n_uavs"):
        Outer(n_uavs=0)
    with pytest.raises(ConfigError, match="NaN"):
        Inner(gain=float("nan"))


def test_load_toml_file_and_section(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text('[env]\nn_uavs = 4\nmode = "waypoint"\n[env.inner]\ngain = 3\n')
    cfg = load_toml(Outer, path, section="env")
    assert (cfg.n_uavs, cfg.mode, cfg.inner.gain) == (4, "waypoint", 3.0)
    path.write_text("[env]\nn_uavs = 40\n")
    with pytest.raises(ConfigError, match=r"c.toml: \[env\].n_uavs = 40 is out of range"):
        load_toml(Outer, path, section="env")
    with pytest.raises(ConfigError, match="missing table"):
        load_toml(Outer, path, section="radio")
    path.write_text("n_uavs = = 3")
    with pytest.raises(ConfigError, match="invalid TOML"):
        load_toml(Outer, path)
    with pytest.raises(ConfigError, match="not found"):
        load_toml(Outer, tmp_path / "missing.toml")





@dataclass(frozen=True)
class Deep(Config):
    inner: Inner = param(Inner(), doc="nested")
    other: Inner = param(Inner(), doc="another nested table")
    n_uavs: int = param(10, ge=1, le=10, doc="UAVs")


def test_overrides_merge_into_the_file_tables_and_errors_name_the_file(tmp_path):
    path = tmp_path / "run.toml"
    path.write_text("n_uavs = 3\n[inner]\ngain = 4.0\n[other]\ngain = 5.0\n")
    cfg = typed_config.load_with_overrides(Deep, path, {"other": {"gain": 6.0}})
    assert (cfg.n_uavs, cfg.inner.gain, cfg.other.gain) == (3, 4.0, 6.0)  # [inner] kept, [other] merged
    assert typed_config.load_with_overrides(Deep, None, {"n_uavs": 2}).n_uavs == 2
    with pytest.raises(ConfigError, match=r"run.toml: Deep.n_uavs = 0 is out of range"):
        typed_config.load_with_overrides(Deep, path, {"n_uavs": 0})
    with pytest.raises(ConfigError, match=r"^Deep: unknown key\(s\) \['speed'\]"):
        typed_config.load_with_overrides(Deep, None, {"speed": 1.0})
