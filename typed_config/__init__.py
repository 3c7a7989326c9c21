"""Typed, validated configuration dataclasses loaded from TOML.

This is the bottom floor shared by ``learning``, ``bridge`` and ``uav_swarm``
(the first two must not import ``uav_swarm``, yet all three need validated configs).

Every concern (radio, crowd, environment, task, bridge, ...) declares one frozen
dataclass deriving from :class:`Config`, next to its code. Fields declare their
allowed range with :func:`param`; construction validates types and ranges, and
loading from a mapping rejects unknown keys. Errors are :class:`ConfigError`
with a message naming the field and the allowed range; an unknown key at any depth
(:class:`UnknownKeyError`) is named by its full dotted key (``task.radio.ieee80211.chanels``),
with the closest valid key and the keys its table allows.

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
    typed_config.UnknownKeyError: Radio: unknown key(s) ['rang_m'] (did you mean 'range_m'?); allowed keys ...
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
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Literal, TypeVar, get_args, get_origin, get_type_hints

__all__ = ["Config", "ConfigError", "UnknownKeyError", "param", "load_toml", "load_with_overrides",
           "read_toml", "unknown_keys_text"]

C = TypeVar("C", bound="Config")


class ConfigError(ValueError):
    """A configuration value is unknown, of the wrong type, or out of range."""


class UnknownKeyError(ConfigError):
    """Unknown keys in one table of a config, named from the outermost table that was read.

    Attributes:
        table_cls: The config class of the table that holds the unknown keys.
        unknown: The unknown keys, sorted.
        table: The path of that table from the root (``("task", "radio")``; ``"[0]"`` for a list item).
        root_cls: The config class read at the root.
        where: What the root is called: its class name, ``"[section]"`` (a TOML table) or another label.
        file: The file read at the root, named in front of the message (no class name then), or None.
    """

    def __init__(self, table_cls: type[Config], unknown: list[str], table: tuple[str, ...],
                 root_cls: type[Config], where: str, file: str | Path | None = None) -> None:
        self.table_cls, self.unknown, self.table = table_cls, unknown, table
        self.root_cls, self.where, self.file = root_cls, where, file
        super().__init__(self._message())

    def rooted(self, root_cls: type[Config], where: str, inside: tuple[str, ...] = (),
               file: str | Path | None = None) -> UnknownKeyError:
        """The same keys named from a table further out (``inside``: the path from there to the old root)."""
        return UnknownKeyError(self.table_cls, self.unknown, inside + self.table, root_cls, where, file)

    def _message(self) -> str:
        section = self.where[1:-1] if self.where.startswith("[") and self.where.endswith("]") else None
        at_class = self.where == self.root_cls.__name__
        prefix: tuple[str, ...] = () if at_class else (section or self.where,)
        label = f"{self.file}: " if self.file is not None else (f"{self.where}: " if at_class else "")
        allowed = _field_names(self.table_cls)
        close = {key: _dotted(prefix + match) for key in self.unknown
                 if (match := self._closest(key, allowed)) is not None}
        return label + unknown_keys_text(_dotted(prefix + self.table), self.unknown, allowed, close)

    def _closest(self, key: str, allowed: list[str]) -> tuple[str, ...] | None:
        """The closest key of the same table, else of any table under the root (a key in the wrong table)."""
        if match := difflib.get_close_matches(key, allowed, n=1):
            return self.table + (match[0],)
        everywhere = {_dotted(path): path for path in _key_paths(self.root_cls)}
        scored = sorted((difflib.SequenceMatcher(None, key, path[-1]).ratio(), dotted)
                        for dotted, path in everywhere.items())
        best = [dotted for ratio, dotted in scored if ratio >= 0.8]
        return everywhere[best[-1]] if best else None


def unknown_keys_text(table: str, unknown: Sequence[str], allowed: Sequence[str],
                      close: Mapping[str, str] | None = None) -> str:
    """One line naming unknown keys by their full dotted key, the closest valid keys and the table's keys.

    Args:
        table: The dotted key of the table that holds them (``""``: the top level of the file).
        unknown: The unknown keys of that table.
        allowed: The keys that table takes.
        close: The closest valid key (full dotted key) of each unknown key; default: the closest allowed one.

    Examples:
        >>> print(unknown_keys_text("task.radio", ["chanels"], ["channels", "environment"]))
        ... # doctest: +NORMALIZE_WHITESPACE
        unknown key(s) ['task.radio.chanels'] (did you mean 'task.radio.channels'?);
        allowed keys in [task.radio] are ['channels', 'environment']
    """
    def full(key: str) -> str:
        return _dotted((table, key)) if table else key

    unknown = sorted(unknown)
    if close is None:
        close = {key: full(match[0]) for key in unknown
                 if (match := difflib.get_close_matches(key, allowed, n=1))}
    hints = [repr(close[key]) if len(unknown) == 1 else f"{close[key]!r} for {full(key)!r}"
             for key in unknown if key in close]
    hint = f" (did you mean {', '.join(hints)}?)" if hints else ""
    where = f" in [{table}]" if table else ""
    return f"unknown key(s) {[full(key) for key in unknown]}{hint}; allowed keys{where} are {sorted(allowed)}"


def _field_names(cls: type[Config]) -> list[str]:
    return [f.name for f in dataclasses.fields(cls)]  # type: ignore[arg-type]


def _dotted(path: tuple[str, ...]) -> str:
    """``("groups", "[0]", "size")`` as ``groups[0].size``."""
    return "".join(part if part.startswith("[") else f".{part}" for part in path if part).lstrip(".")


def _key_paths(cls: type[Config], inside: tuple[str, ...] = ()) -> list[tuple[str, ...]]:
    """Every key a config class takes, tables included, as paths from it (tables of one config class only)."""
    paths = []
    hints = get_type_hints(cls)
    for name in _field_names(cls):
        paths.append(inside + (name,))
        tables = [tp for tp in (hints[name], *get_args(hints[name]))
                  if isinstance(tp, type) and issubclass(tp, Config)]
        for table in tables[:1]:
            paths.extend(_key_paths(table, inside + (name,)))
    return paths


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
        errors: list[ConfigError] = []
        for option in options:
            if option is type(None):
                continue
            try:
                return _coerce(value, option, where)
            except ConfigError as exc:
                errors.append(exc)
        if len(errors) == 1:
            raise errors[0]
        raise ConfigError(f"{where} = {value!r}: {'; '.join(map(str, errors))}")
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
            args = (args[0],) * len(value)
        elif len(args) != len(value):
            raise ConfigError(f"{where} = {value!r} must have exactly {len(args)} items")
        items = []
        for i, (v, a) in enumerate(zip(value, args, strict=True)):
            try:
                items.append(_coerce(v, a, f"{where}[{i}]"))
            except UnknownKeyError as exc:
                raise exc.rooted(exc.root_cls, exc.where, (f"[{i}]",)) from None
        return tuple(items)
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
            try:
                value = _coerce(getattr(self, f.name), hints[f.name], where)
            except UnknownKeyError as exc:  # a table of this field: named from here
                raise exc.rooted(type(self), name, (f.name,)) from None
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
        unknown = sorted(set(data) - set(_field_names(cls)))
        if unknown:
            raise UnknownKeyError(cls, unknown, (), cls, where)
        try:
            return cls(**dict(data))
        except UnknownKeyError as exc:  # in a table: its full key, from this root
            raise exc.rooted(cls, where) from None
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
    except UnknownKeyError as exc:
        raise exc.rooted(exc.root_cls, exc.where, file=path) from None
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
    except UnknownKeyError as exc:
        raise (exc.rooted(exc.root_cls, exc.where, file=path) if path is not None else exc) from None
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}" if path is not None else str(exc)) from None
