"""``uav-swarm --help`` and each command's help import none of the heavy libraries, and say the truth.

The help reads flag defaults from the config classes' source (:mod:`uav_swarm.cli.field_source`);
these tests bound what ``--help`` imports (in a fresh interpreter) and check that what the source
reading shows equals what importing the config gives.
"""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys

import pytest

from uav_swarm.cli import build_parser
from uav_swarm.cli.conventions import iter_parsers
from uav_swarm.cli.field_source import read_constant, read_field, read_keys

HEAVY = ("torch", "matplotlib", "scipy", "numpy", "numba", "zenoh", "pymavlink", "shapely", "onnxruntime",
         "foxglove", "learning.train", "learning.data", "uav_swarm.runs.simulate")
"""Libraries (and our modules that import them) that ``--help`` must not import: seconds each."""

_PROBE = """
import contextlib, io, json, sys
from uav_swarm.cli import main
with contextlib.redirect_stdout(io.StringIO()):
    code = main(sys.argv[1:])
print(json.dumps({"code": code, "modules": sorted(sys.modules)}))
"""

_COMMANDS = [path for path, _ in iter_parsers(build_parser())]


@pytest.mark.parametrize("command", _COMMANDS, ids=lambda c: " ".join(c) or "uav-swarm")
def test_help_imports_no_heavy_library(command: tuple[str, ...]) -> None:
    result = subprocess.run([sys.executable, "-c", _PROBE, *command, "--help"], capture_output=True,
                            text=True, check=True)
    probe = json.loads(result.stdout.strip().splitlines()[-1])
    assert probe["code"] == 0
    heavy = sorted(m for m in probe["modules"] if m.split(".")[0] in HEAVY or m in HEAVY)
    assert heavy == [], f"uav-swarm {' '.join(command)} --help imports {heavy[:8]}"


def _config_actions() -> list[tuple[str, str]]:
    specs = [(" ".join(path), getattr(action, name, None)) for path, parser in iter_parsers(build_parser())
             for action in parser._actions for name in ("config_field", "default_from")]
    return [(command, spec) for command, spec in specs if spec]


@pytest.mark.parametrize(("command", "spec"), _config_actions(), ids=lambda v: str(v))
def test_source_reading_equals_the_imported_config(command: str, spec: str) -> None:
    import importlib

    module_name, _, qualified = spec.partition(":")
    module = importlib.import_module(module_name)
    if "." not in qualified:
        assert read_constant(module_name, qualified) == getattr(module, qualified)
        return
    class_name, _, field_name = qualified.partition(".")
    field = {f.name: f for f in dataclasses.fields(getattr(module, class_name))}[field_name]
    found = read_field(spec)
    if found is not None:  # None: not literal, the help imports the module (slower, same text)
        default, meta = found
        assert default == field.default, spec
        assert meta == dict(field.metadata), spec


def test_task_names_read_from_source_equal_the_registry() -> None:
    from learning.data import SPLITS
    from uav_swarm.missions.registry import TASKS

    assert read_keys("uav_swarm.missions.registry", "TASKS") == tuple(TASKS)
    assert read_keys("learning.data", "SPLITS") == tuple(SPLITS)


def test_a_declaration_that_is_not_literal_is_not_guessed(tmp_path, monkeypatch) -> None:
    (tmp_path / "probe_config.py").write_text(
        "from typed_config import Config, param\nBASE = 3\n\n"
        "class C(Config):\n    a: int = param(BASE, ge=1, doc='a')\n    b: int = param(len('ab'), doc='b')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert read_field("probe_config:C.a") == (3, {"ge": 1, "gt": None, "le": None, "lt": None, "doc": "a"})
    assert read_field("probe_config:C.b") is None
    with pytest.raises(LookupError):
        read_keys("probe_config", "BASE")
