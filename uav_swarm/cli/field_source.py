"""A config field's default, range and doc read from its source file, for help that imports nothing.

``uav-swarm COMMAND --help`` shows each flag's default from the config field the flag sets
(:func:`uav_swarm.cli.conventions.config_flag`). Importing the config's module to read it would import
what that module imports (torch, matplotlib, scipy: seconds); this module reads the ``param(...)``
declaration from the source instead, following a name to the module it is imported from. A declaration
it cannot read as literals returns None, and the caller imports the module (the same answer, slower).

Examples:
    >>> default, meta = read_field("uav_swarm.runs.simulate_config:SimulateConfig.n_uavs")
    >>> default, meta["ge"], meta["doc"]
    (10, 1, 'number of UAVs')
    >>> read_keys("uav_swarm.missions.registry", "TASKS")
    ('wifi-s1', 'wifi-s2', 'agp', 'fp')
"""

from __future__ import annotations

import ast
import functools
import importlib.util
from pathlib import Path
from typing import Any

__all__ = ["read_field", "read_constant", "read_keys"]

_META_KEYS = ("ge", "gt", "le", "lt", "doc")


class _NotLiteral(Exception):
    """The declaration holds something other than literals and literal constants."""


def _source_path(module_name: str) -> Path | None:
    """The source file of ``module_name``, found without importing its packages (only the top one)."""
    top, *rest = module_name.split(".")
    try:
        spec = importlib.util.find_spec(top)
    except (ImportError, ValueError):
        return None
    if spec is None or not spec.submodule_search_locations:
        return Path(spec.origin) if spec is not None and spec.origin and not rest else None
    for folder in spec.submodule_search_locations:
        base = Path(folder).joinpath(*rest)
        for candidate in (base.with_suffix(".py"), base / "__init__.py") if rest else (base / "__init__.py",):
            if candidate.is_file():
                return candidate
    return None


@functools.cache
def _module_tree(module_name: str) -> ast.Module | None:
    path = _source_path(module_name)
    return None if path is None else ast.parse(path.read_text(encoding="utf-8"))


def _package(module_name: str, level: int, target: str | None) -> str:
    base = module_name.rsplit(".", level)[0] if level else ""
    return ".".join(filter(None, (base, target)))


def read_constant(module_name: str, name: str, depth: int = 0) -> Any:
    """The literal value of the module-level ``name`` of ``module_name``, read from source.

    Raises:
        LookupError: when it is not a literal (or not found), so that the caller imports it.
    """
    tree = _module_tree(module_name)
    if tree is None or depth > 4:
        raise LookupError(f"{module_name}.{name}")
    for node in tree.body:
        value = _assigned(node, name)
        if value is not None:
            return _literal(value, module_name, depth)
        if isinstance(node, ast.ImportFrom):
            for alias in node.names:
                if (alias.asname or alias.name) == name:
                    source = _package(module_name, node.level, node.module)
                    return read_constant(source, alias.name, depth + 1)
    raise LookupError(f"{module_name}.{name}")


def _assigned(node: ast.stmt, name: str) -> ast.expr | None:
    """The value ``node`` assigns to the module-level ``name`` (None: it assigns none)."""
    if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == name for t in node.targets):
        return node.value
    if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name) and node.target.id == name:
        return node.value
    return None


def read_keys(module_name: str, name: str) -> tuple[str, ...]:
    """The literal keys of the module-level dict ``name`` of ``module_name``, in order, read from source.

    Raises:
        LookupError: when ``name`` is not a dict with literal keys there.
    """
    tree = _module_tree(module_name)
    for node in tree.body if tree is not None else ():
        value = _assigned(node, name)
        if isinstance(value, ast.Dict) and all(isinstance(k, ast.Constant) for k in value.keys):
            return tuple(str(k.value) for k in value.keys if isinstance(k, ast.Constant))
    raise LookupError(f"{module_name}.{name}")


def _literal(node: ast.expr, module_name: str, depth: int) -> Any:
    if isinstance(node, ast.Name):
        try:
            return read_constant(module_name, node.id, depth + 1)
        except LookupError:
            raise _NotLiteral(node.id) from None
    if isinstance(node, ast.Tuple):
        return tuple(_literal(e, module_name, depth) for e in node.elts)
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        return -_literal(node.operand, module_name, depth)
    if isinstance(node, ast.JoinedStr | ast.Call | ast.Attribute | ast.BinOp):
        raise _NotLiteral(ast.dump(node)[:40])
    try:
        return ast.literal_eval(node)
    except ValueError:
        raise _NotLiteral(ast.dump(node)[:40]) from None


def read_field(spec: str) -> tuple[Any, dict[str, Any]] | None:
    """``"module:Class.field"`` -> (default, metadata as ``param`` stores it), or None if not literal."""
    module_name, _, qualified = spec.partition(":")
    class_name, _, field_name = qualified.partition(".")
    tree = _module_tree(module_name)
    cls = next((n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == class_name), None) \
        if tree is not None else None
    if cls is None:
        return None
    for node in cls.body:
        if not (isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name)
                and node.target.id == field_name and isinstance(node.value, ast.Call)):
            continue
        call = node.value
        if not (isinstance(call.func, ast.Name) and call.func.id == "param" and call.args):
            return None
        try:
            default = _literal(call.args[0], module_name, 0)
            meta: dict[str, Any] = {key: None for key in _META_KEYS}
            meta["doc"] = ""
            for keyword in call.keywords:
                if keyword.arg not in _META_KEYS:
                    return None
                meta[keyword.arg] = _literal(keyword.value, module_name, 0)
        except _NotLiteral:
            return None
        return default, meta
    return None
