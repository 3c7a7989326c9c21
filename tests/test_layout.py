"""The house's shape: packages by concept, no import circles, every package says what lives in it."""

from __future__ import annotations

import ast
import re
from collections import defaultdict
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("uav_swarm", "learning", "bridge", "typed_config")


def _modules() -> dict[str, Path]:
    modules = {}
    for package in PACKAGES:
        for path in (REPO / package).rglob("*.py"):
            parts = path.relative_to(REPO).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            modules[name] = path
    return modules


def _imports(path: Path, known: set[str]) -> set[str]:
    """Every project module ``path`` imports, at any depth (function-level and TYPE_CHECKING too)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        names: list[str] = []
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module, *(f"{node.module}.{alias.name}" for alias in node.names)]
        elif isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        found.update(name for name in names if name in known)
    return found


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_no_import_circles():
    modules = _modules()
    graph = defaultdict(set)
    for name, path in modules.items():
        graph[name] = {target for target in _imports(path, set(modules)) if target != name}
    assert _cycles(graph) == []


def test_cycle_finder_sees_a_circle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_libraries_never_import_the_product():
    modules = _modules()
    for name, path in modules.items():
        if name.startswith(("learning", "bridge", "typed_config")):
            assert not any(t.startswith("uav_swarm") for t in _imports(path, set(modules))), name


def test_uav_swarm_top_level_holds_packages_only():
    loose = {p.name for p in (REPO / "uav_swarm").glob("*.py")} - {"__init__.py", "__main__.py"}
    assert loose == set()
    folders = {p.name for p in (REPO / "uav_swarm").iterdir() if (p / "__init__.py").exists()}
    assert {"world", "missions", "env", "planning", "runs", "marl", "cli"} <= folders


def test_every_package_says_what_lives_there():
    for init in REPO.glob("*/**/__init__.py"):
        if init.parts[len(REPO.parts)] not in PACKAGES:
            continue
        doc = ast.get_docstring(ast.parse(init.read_text()))
        assert doc and len(doc) > 40, f"{init.relative_to(REPO)} has no docstring"


MAX_LINES = 450
"""No file of the packages, tests or benchmarks is longer (a longer one holds more than one concept)."""


def _may_import(init: Path) -> tuple[str, ...]:
    """The project packages and modules that ``init``'s package may import: its ``May import:`` paragraph."""
    doc = ast.get_docstring(ast.parse(init.read_text())) or ""
    paragraph = next((p for p in doc.split("\n\n") if p.startswith("May import:")), None)
    assert paragraph is not None, f"{init.relative_to(REPO)} does not say what it may import (May import:)"
    return tuple(re.findall(r"``([a-z_.]+)``", paragraph))


def _within(target: str, prefixes: set[str]) -> bool:
    return any(target == p or target.startswith(p + ".") for p in prefixes)


def test_no_import_runs_up_a_floor():
    modules = _modules()
    inits = {name: path for name, path in modules.items() if path.name == "__init__.py"}
    rules = {name: _may_import(path) for name, path in inits.items()}
    for name, path in modules.items():
        package = name if name in inits else name.rsplit(".", 1)[0]
        allowed = {package, *rules[package]}
        wrong = sorted(t for t in _imports(path, set(modules)) if not _within(t, allowed))
        assert wrong == [], f"{name} imports {wrong}: its package may import only {sorted(allowed)}"


def test_the_floor_rule_reads_prefixes_not_names():
    assert _within("uav_swarm.world.wifi.phy", {"uav_swarm.world"})
    assert not _within("uav_swarm.worlds", {"uav_swarm.world"})


def test_no_file_is_over_the_line_limit():
    files = [p for folder in (*PACKAGES, "tests", "benchmarks") for p in (REPO / folder).rglob("*.py")]
    assert len(files) > 100
    lines = {str(p.relative_to(REPO)): len(p.read_text().splitlines()) for p in files}
    assert {name: n for name, n in lines.items() if n > MAX_LINES} == {}


def _skipped_by_mypy(pyproject: dict) -> list[str]:
    """The modules a ``[[tool.mypy.overrides]]`` table with ``ignore_errors`` keeps from the checker."""
    skipped: list[str] = []
    for table in pyproject.get("tool", {}).get("mypy", {}).get("overrides", []):
        if table.get("ignore_errors"):
            module = table.get("module", [])
            skipped += [module] if isinstance(module, str) else module
    return skipped


def test_mypy_checks_every_package_module():
    import tomllib

    pyproject = tomllib.loads((REPO / "pyproject.toml").read_text())
    assert set(pyproject["tool"]["mypy"]["files"]) == set(PACKAGES)
    assert _skipped_by_mypy(pyproject) == []


def test_skipped_modules_are_seen():
    overrides = {"tool": {"mypy": {"overrides": [{"module": ["a.b", "c"], "ignore_errors": True},
                                                 {"module": "d", "ignore_errors": True},
                                                 {"module": "e", "ignore_missing_imports": True}]}}}
    assert _skipped_by_mypy(overrides) == ["a.b", "c", "d"]
