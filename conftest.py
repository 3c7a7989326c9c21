"""Every ``>>>`` example in the packages runs as a test (pytest collects the packages' modules as doctests).

A module whose code imports a package of an optional extra that is not installed is not run: it is
reported as skipped, naming the extra to install (``pytest -ra`` lists the reasons), never left out
silently. The tests themselves live in ``tests/``.
"""

from __future__ import annotations

import ast
import importlib.util
from pathlib import Path

import pytest
from _pytest.doctest import DoctestModule

ROOT = Path(__file__).resolve().parent
PACKAGES = ("uav_swarm", "learning", "bridge", "typed_config")
OPTIONAL = {  # an import of the module -> the extra (pyproject.toml) that installs it
    "torchrl": "marl", "tensordict": "marl", "supersuit": "marl", "ray": "distributed",
    "vmas": "bench", "mkdocs": "docs",
    "rclpy": "ros2",
}


def _missing_extras(path: Path) -> dict[str, str]:
    """The optional modules ``path`` imports (anywhere in it) that are not installed, with their extras."""
    missing = {}
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        names = [alias.name for alias in node.names] if isinstance(node, ast.Import) else \
            [node.module] if isinstance(node, ast.ImportFrom) and node.module and node.level == 0 else []
        for name in names:
            top = name.split(".")[0]
            if top in OPTIONAL and importlib.util.find_spec(top) is None:
                missing[top] = OPTIONAL[top]
    return missing


class _SkippedDoctests(pytest.Item):
    """Stands for a module whose examples need a missing extra: a skip with the reason."""

    def __init__(self, *, reason: str, **kwargs) -> None:
        super().__init__(**kwargs)
        self.reason = reason

    def runtest(self) -> None:
        pytest.skip(self.reason)

    def reportinfo(self) -> tuple[Path, int, str]:
        return self.path, 0, f"[doctest] {self.name}"


class _SkippedModule(pytest.File):
    def __init__(self, *, reason: str, **kwargs) -> None:
        super().__init__(**kwargs)
        self.reason = reason

    def collect(self):
        yield _SkippedDoctests.from_parent(self, name=self.path.stem, reason=self.reason)


def pytest_collect_file(file_path: Path, parent: pytest.Collector) -> pytest.Collector | None:
    """The doctests of every module of the packages (``tests/`` collects its own files as usual)."""
    if file_path.suffix != ".py" or file_path.parts[len(ROOT.parts)] not in PACKAGES \
            or not file_path.is_relative_to(ROOT):
        return None
    if file_path.name == "__main__.py":  # importing it runs the program
        if ">>>" in file_path.read_text(encoding="utf-8"):
            return _SkippedModule.from_parent(parent, path=file_path,
                                              reason=f"{file_path.relative_to(ROOT)}: runs when imported")
        return None
    missing = _missing_extras(file_path)
    if missing:
        needs = ", ".join(f"{module} ({extra})" for module, extra in sorted(missing.items()))
        reason = f"{file_path.relative_to(ROOT)}: examples need optional packages not installed: {needs}"
        return _SkippedModule.from_parent(parent, path=file_path, reason=reason)
    return DoctestModule.from_parent(parent, path=file_path)
