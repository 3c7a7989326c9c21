import re
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
        ({"inner": {"gian": 1}},
         r"^Outer: unknown key\(s\) \['inner.gian'\] \(did you mean 'inner.gain'\?\); "
         r"allowed keys in \[inner\] are \['gain'\]$"),
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


@dataclass(frozen=True)
class Leaf(Config):
    channels: tuple[int, ...] = param((36,), doc="channels")
    environment: str = param("urban", doc="environment")


@dataclass(frozen=True)
class Middle(Config):
    leaf: Leaf = param(Leaf(), doc="a table in a table")
    maybe: Leaf | None = param(None, doc="an optional table")
    items: tuple[Leaf, ...] = param((), doc="an array of tables")


@dataclass(frozen=True)
class Top(Config):
    duration_s: float = param(10.0, gt=0.0, doc="duration")
    middle: Middle = param(Middle(), doc="a table")


@pytest.mark.parametrize(
    ("toml", "key", "suggestion", "table", "allowed"),
    [
        ("duraton_s = 3\n", "duraton_s", "duration_s", "", ["duration_s", "middle"]),
        ("[midle]\n", "midle", "middle", "", ["duration_s", "middle"]),
        ("[middle]\nlef = {}\n", "middle.lef", "middle.leaf", "middle", ["items", "leaf", "maybe"]),
        ("[middle.leaf]\nchanels = [1]\n", "middle.leaf.chanels", "middle.leaf.channels", "middle.leaf",
         ["channels", "environment"]),
        ("[middle.maybe]\nenvironmnt = 'a'\n", "middle.maybe.environmnt", "middle.maybe.environment",
         "middle.maybe", ["channels", "environment"]),
        ("[[middle.items]]\n[[middle.items]]\nchanels = [1]\n", "middle.items[1].chanels",
         "middle.items[1].channels", "middle.items[1]", ["channels", "environment"]),
        # a key in the wrong table: the closest key of any table, by its full key
        ("[middle.leaf]\nduraton_s = 3\n", "middle.leaf.duraton_s", "duration_s", "middle.leaf",
         ["channels", "environment"]),
    ],
    ids=["top", "top-table", "nested", "nested-twice", "optional-table", "array-of-tables", "wrong-table"],
)
def test_an_unknown_key_at_any_depth_is_named_by_its_full_key_with_the_file(tmp_path, toml, key, suggestion,
                                                                          table, allowed):
    path = tmp_path / "run.toml"
    path.write_text(toml)
    where = f" in [{table}]" if table else ""
    expected = (f"{path}: unknown key(s) [{key!r}] (did you mean {suggestion!r}?); "
                f"allowed keys{where} are {allowed}")
    for load in (lambda: typed_config.load_with_overrides(Top, path), lambda: load_toml(Top, path)):
        with pytest.raises(typed_config.UnknownKeyError) as caught:
            load()
        assert str(caught.value) == expected
    section = tmp_path / "section.toml"  # a table read alone is named by its key in the file
    section.write_text("[run]\n" + re.sub(r"^(\[+)", r"\1run.", toml, flags=re.MULTILINE))
    with pytest.raises(ConfigError) as caught:
        load_toml(Top, section, section="run")
    in_run = ".".join(filter(None, ("run", table)))
    assert str(caught.value) == (f"{section}: unknown key(s) ['run.{key}'] (did you mean "
                                 f"'run.{suggestion}'?); allowed keys in [{in_run}] are {allowed}")


def test_an_unknown_key_without_a_close_one_names_the_table_keys_only():
    with pytest.raises(ConfigError) as caught:
        Top.from_dict({"middle": {"leaf": {"zzz": 1}}})
    assert str(caught.value) == ("Top: unknown key(s) ['middle.leaf.zzz']; allowed keys in [middle.leaf] are "
                                 "['channels', 'environment']")
