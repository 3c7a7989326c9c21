"""Typed, validated configuration dataclasses loaded from TOML.

This is the bottom floor shared by ``learning``, ``bridge`` and ``uav_swarm``
(the first two must not import ``uav_swarm``, yet all three need validated configs).

Every concern (radio, crowd, environment, task, bridge, ...) declares one frozen
dataclass deriving from :class:`Config`, next to its code. Fields declare their
allowed range with :func:`param`; construction validates types and ranges, and
loading from a mapping rejects unknown keys. Errors are :class:`ConfigError`
with a message naming the field and the allowed range.

Examples:
    >>> from dataclasses import dataclass
    >>> @dataclass(frozen=True)
    ... class Radio(Config):
    ...     range_m: float = param(30.0, gt=0.0, le=1000.0, doc="radio range")
    >>> Radio.from_dict({"range_m": 25}).range_m
    25.0
    >>> Radio.from_dict({"rang_m": 25})  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    typed_config.ConfigError: Radio: unknown key(s) ['rang_m'] (did you mean 'range_m'?); allowed keys ...
    >>> Radio.from_dict({"range_m": -1})
    Traceback (most recent call last):
    ...
    typed_config.ConfigError: Radio.range_m = -1.0 is out of range: allowed 0.0 < range_m <= 1000.0

May import: nothing of the project (the bottom floor).
"""

from __future__ import annotations

import dataclasses
import difflib
import tomllib
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal, TypeVar, get_args, get_origin, get_type_hints

__all__ = ["Config", "ConfigError", "param", "load_toml", "load_with_overrides", "read_toml"]

C = TypeVar("C", bound="Config")


class ConfigError(ValueError):
    """A configuration value is unknown, of the wrong type, or out of range."""


def param(
    default: Any,
    *,
    ge: float | None = None,
    gt: float | None = None,
    le: float | None = None,
    lt: float | None = None,
    doc: str = "",
) -> Any:
    """Declare a config field with its default, its allowed range and a one-line doc.

    Args:
        default: The default value (tuples for sequences: configs are immutable).
        ge: Inclusive lower bound.
        gt: Exclusive lower bound.
        le: Inclusive upper bound.
        lt: Exclusive upper bound.
        doc: What the field means, with its unit.
    """
    metadata = {"ge": ge, "gt": gt, "le": le, "lt": lt, "doc": doc}
    return dataclasses.field(default=default, metadata=metadata)


def _range_text(name: str, meta: Mapping[str, Any]) -> str:
    low = f"{meta['ge']} <= " if meta.get("ge") is not None else (
        f"{meta['gt']} < " if meta.get("gt") is not None else "")
    high = f" <= {meta['le']}" if meta.get("le") is not None else (
        f" < {meta['lt']}" if meta.get("lt") is not None else "")
    return f"{low}{name}{high}"


def _in_range(value: float, meta: Mapping[str, Any]) -> bool:
    checks = (
        ("ge", lambda b: value >= b),
        ("gt", lambda b: value > b),
        ("le", lambda b: value <= b),
        ("lt", lambda b: value < b),
    )
    return all(meta.get(key) is None or ok(meta[key]) for key, ok in checks)


def _coerce(value: Any, tp: Any, where: str) -> Any:
    """Return ``value`` converted to type ``tp`` or raise ConfigError naming ``where``."""
    origin = get_origin(tp)
    if tp is Any:
        return value
    if origin in (typing.Union, types.UnionType):
        options = get_args(tp)
        if value is None and type(None) in options:
            return None
        errors = []
        for option in options:
            if option is type(None):
                continue
            try:
                return _coerce(value, option, where)
            except ConfigError as exc:
                errors.append(str(exc))
        raise ConfigError(errors[0] if len(errors) == 1 else f"{where} = {value!r}: {'; '.join(errors)}")
    if origin is Literal:
        allowed = get_args(tp)
        if value not in allowed:
            raise ConfigError(f"{where} = {value!r} is not allowed: choose one of {list(allowed)}")
        return value
    if origin is tuple:
        if isinstance(value, str) or not isinstance(value, (list, tuple)):
            raise ConfigError(f"{where} = {value!r} must be a list")
        args = get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_coerce(v, args[0], f"{where}[{i}]") for i, v in enumerate(value))
        if len(args) != len(value):
            raise ConfigError(f"{where} = {value!r} must have exactly {len(args)} items")
        return tuple(_coerce(v, a, f"{where}[{i}]") for i, (v, a) in enumerate(zip(value, args, strict=True)))
    if isinstance(tp, type) and issubclass(tp, Config):
        if isinstance(value, tp):
            return value
        if not isinstance(value, Mapping):
            raise ConfigError(f"{where} must be a table of {tp.__name__} fields, got {value!r}")
        return tp.from_dict(value, where=where)
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{where} = {value!r} must be true or false")
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{where} = {value!r} must be an integer")
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{where} = {value!r} must be a number")
        return float(value)
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(f"{where} = {value!r} must be a string")
        return value
    return value


class Config:
    """Base of every configuration dataclass: validates on construction.

    Subclasses are ``@dataclass(frozen=True)``. A subclass with cross-field rules
    overrides :meth:`check` (and raises :class:`ConfigError`).
    """

    def __post_init__(self) -> None:
        hints = get_type_hints(type(self))
        name = type(self).__name__
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            where = f"{name}.{f.name}"
            value = _coerce(getattr(self, f.name), hints[f.name], where)
            object.__setattr__(self, f.name, value)
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                if value != value:  # NaN
                    raise ConfigError(f"{where} is NaN")
                if not _in_range(value, f.metadata):
                    raise ConfigError(
                        f"{where} = {value!r} is out of range: allowed {_range_text(f.name, f.metadata)}")
        self.check()

    def check(self) -> None:
        """Cross-field validation; override in subclasses (raise ConfigError)."""

    @classmethod
    def from_dict(cls: type[C], data: Mapping[str, Any], *, where: str | None = None) -> C:
        """Build a validated config from a mapping; unknown keys are errors.

        Args:
            data: Field names to values, as read from TOML.
            where: Prefix for error messages (defaults to the class name).
        """
        where = where or cls.__name__
        known = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
        unknown = sorted(set(data) - known)
        if unknown:
            close = {key: match[0] for key in unknown
                     if (match := difflib.get_close_matches(key, known, n=1))}
            hints = [repr(match) if len(unknown) == 1 else f"{match!r} for {key!r}"
                     for key, match in close.items()]
            hint = f" (did you mean {', '.join(hints)}?)" if hints else ""
            raise ConfigError(f"{where}: unknown key(s) {unknown}{hint}; allowed keys are {sorted(known)}")
        try:
            return cls(**dict(data))
        except ConfigError as exc:
            message = str(exc)
            if where != cls.__name__ and message.startswith(cls.__name__ + "."):
                message = where + message[len(cls.__name__):]
            raise ConfigError(message) from None

    def to_dict(self) -> dict[str, Any]:
        """Plain nested dict of the config (tuples become lists), for JSON and checkpoints."""

        def plain(value: Any) -> Any:
            if isinstance(value, Config):
                return value.to_dict()
            if isinstance(value, tuple):
                return [plain(v) for v in value]
            return value

        return {f.name: plain(getattr(self, f.name)) for f in dataclasses.fields(self)}  # type: ignore[arg-type]

    def replace(self: C, **changes: Any) -> C:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)  # type: ignore[type-var]

    @classmethod
    def describe(cls) -> str:
        """One line per field: name, default, allowed range and doc."""
        lines = []
        for f in dataclasses.fields(cls):  # type: ignore[arg-type]
            rng = _range_text(f.name, f.metadata) if any(
                f.metadata.get(k) is not None for k in ("ge", "gt", "le", "lt")) else f.name
            lines.append(f"{rng} (default {f.default!r}): {f.metadata.get('doc', '')}")
        return "\n".join(lines)


def read_toml(path: str | Path) -> dict[str, Any]:
    """The tables of a TOML file as a dict.

    Raises:
        ConfigError: The file is missing or is not valid TOML (the message names the file).
    """
    path = Path(path)
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"config file not found: {path}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: invalid TOML: {exc}") from None


def load_toml(cls: type[C], path: str | Path, *, section: str | None = None) -> C:
    """Load a config dataclass from a TOML file (optionally one table of it).

    Args:
        cls: The Config subclass.
        path: The TOML file.
        section: A top-level table to read instead of the whole file.

    Raises:
        ConfigError: The file is missing, malformed, or its values are invalid.
    """
    path = Path(path)
    data = read_toml(path)
    where = cls.__name__
    if section is not None:
        if section not in data:
            raise ConfigError(f"{path}: missing table [{section}]")
        data = data[section]
        where = f"[{section}]"
    try:
        return cls.from_dict(data, where=where)
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None


def load_with_overrides(
    cls: type[C], path: str | Path | None, overrides: Mapping[str, Any] | None = None
) -> C:
    """A config from an optional TOML file with ``overrides`` on top (a command line's flags), validated once.

    A top-level override replaces the file's value, except that a dict given for a table is merged into
    that table key by key (``{"flight": {"end_action": "land"}}`` keeps the file's other ``[flight]`` keys).

    Raises:
        ConfigError: Unreadable file, unknown key or table, or an invalid value (named, with the file).
    """
    data = {} if path is None else read_toml(path)
    for key, value in (overrides or {}).items():
        nested = isinstance(value, Mapping) and isinstance(data.get(key), Mapping)
        data[key] = {**data[key], **value} if nested else value
    try:
        return cls.from_dict(data)
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}" if path is not None else str(exc)) from None
