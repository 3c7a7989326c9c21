"""The conventions of the ``uav-swarm`` command line (docs/cli.md), kept in one place.

- :class:`CliParser`: no abbreviated flags; a mistyped flag is answered with the usage of the
  (sub)command it was given to and the closest flag; descriptions and help are plain text.
- :class:`CliHelpFormatter`: keeps the line breaks of descriptions; every flag's help ends with its
  default, read from the config field the flag sets when it sets one (never retyped).
- :func:`config_flag`: a flag tied to a config field: its help, default and allowed range come from the
  field's ``param(...)`` and the range is checked when the command line is parsed, naming the flag.
- :func:`number`: a number type checked when parsed (``--n -5`` is refused naming ``--n``).
- :func:`output_flag`: a folder or file the command writes, checked when parsed (before any work): an
  existing file given for a folder, a folder given for a file, a path under a file or a place this
  user cannot write is refused naming the flag.
- :func:`run_folder_flag`: a run's output folder; one that already holds files is refused naming
  ``--overwrite`` (:func:`run_folder_problem`, before any work): a run never replaces another silently.

Examples:
    >>> parser = CliParser(prog="demo")
    >>> _ = parser.add_argument("--n", type=number(int, ge=1), default=3, help="scenes")
    >>> parser.parse_args(["--n", "4"]).n
    4
    >>> plain_text("``uav-swarm place``: see :mod:`uav_swarm.world`")
    'uav-swarm place: see uav_swarm.world'
"""

from __future__ import annotations

import argparse
import dataclasses
import difflib
import importlib
import os
import re
import tempfile
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from types import UnionType
from typing import Any, Literal, Union, get_args, get_origin, get_type_hints

__all__ = ["CliParser", "CliHelpFormatter", "config_flag", "number", "plain_text", "iter_parsers",
           "add_verbosity", "SWITCH_ACTIONS", "output_flag", "output_problem", "config_default",
           "LazyChoices", "run_folder_flag", "run_folder_problem"]

SWITCH_ACTIONS = (argparse._StoreTrueAction, argparse._StoreFalseAction, argparse._StoreConstAction,
                  argparse._HelpAction, argparse._VersionAction, argparse._CountAction)
"""Flags without a value: off unless given (their help needs no default)."""

_FIELD_DOC = "<the field's doc>"
_ROLE = re.compile(r":[a-z]+:`~?([^`]+)`")


def plain_text(text: str | None) -> str | None:
    """Text for a terminal: reStructuredText roles and literals without their markup."""
    if text is None:
        return None
    text = _ROLE.sub(r"\1", text).replace("``", "")
    return re.sub(r"::$", ":", text, flags=re.MULTILINE)


def number(kind: type, *, ge: float | None = None, gt: float | None = None, le: float | None = None,
           lt: float | None = None) -> Callable[[str], Any]:
    """An argparse ``type``: text to ``kind`` (int or float), refused outside the bounds given."""
    bounds = [(ge, ">=", lambda v, b: v >= b), (gt, ">", lambda v, b: v > b),
              (le, "<=", lambda v, b: v <= b), (lt, "<", lambda v, b: v < b)]
    allowed = " and ".join(f"{op} {b}" for b, op, _ in bounds if b is not None)
    noun = "an integer" if kind is int else "a number"

    def convert(text: str) -> Any:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"{text!r} is not {noun}" + (f": allowed {allowed}" if allowed else "")) from None
        if value != value or not all(b is None or ok(value, b) for b, _, ok in bounds):
            raise argparse.ArgumentTypeError(f"{text} is out of range: allowed {allowed}")
        return value

    convert.__name__ = kind.__name__
    return convert


def output_problem(path: Path, kind: Literal["folder", "file"]) -> str | None:
    """Why the command could not write the folder or file ``path`` (None: it can), read-only.

    A folder must be a folder or not exist yet; a file must not be a folder; what does not exist yet
    must lie under a folder this user can create files in (tried with a file made and removed at once).

    Examples:
        >>> output_problem(Path("README.md"), "folder") if Path("README.md").is_file() else None
        'README.md is a file, not a folder'
    """
    if path.exists() and (path.is_dir() if kind == "file" else not path.is_dir()):
        return f"{path} is a {'folder' if path.is_dir() else 'file'}, not a {kind}"
    place = path if kind == "folder" and path.is_dir() else path.parent
    while not place.exists() and place != place.parent:
        place = place.parent
    if not place.is_dir():
        return f"{path} lies under {place}, a file, not a folder"
    try:
        handle, probe = tempfile.mkstemp(dir=place, prefix=".uav-swarm-write-check-")
    except OSError as exc:
        return f"{path}: cannot write in {place} ({exc.strerror or exc})"
    os.close(handle)
    os.unlink(probe)
    return None


def output_flag(parser: argparse.ArgumentParser, flag: str, kind: Literal["folder", "file"], *,
                default: str | None = None, **kwargs: Any) -> argparse.Action:
    """Add ``flag``: a folder or file the command writes, checked when the command line is parsed.

    Its value (its default too) becomes a :class:`Path`; one the command could not write (see
    :func:`output_problem`) is refused naming the flag, before the command starts any work.
    """

    def convert(text: str) -> Path:
        problem = output_problem(Path(text), kind)
        if problem is not None:
            raise argparse.ArgumentTypeError(problem)
        return Path(text)

    convert.__name__ = kind
    action = parser.add_argument(flag, type=convert, default=default, **kwargs)
    action.output_kind = kind  # type: ignore[attr-defined]
    return action


def run_folder_flag(parser: argparse.ArgumentParser, flag: str = "--out", *,
                    resumed_by: str | None = None, **kwargs: Any) -> argparse.Action:
    """Add ``flag``, a run's output folder, and ``--overwrite``: a run never replaces another silently.

    A folder that already holds files is refused naming ``--overwrite`` (see :func:`run_folder_problem`),
    unless ``--overwrite`` is given or the flag ``resumed_by`` (a dest, e.g. ``"resume"``) asks to continue
    the run in it.
    """
    action = output_flag(parser, flag, "folder", **kwargs)
    parser.add_argument("--overwrite", action="store_true",
                        help=f"write into a {flag} that already holds files, replacing the files this run "
                             "writes (default: refused, so that a run never replaces another)")
    parser.set_defaults(run_folder=(action.dest, flag, resumed_by))
    return action


def run_folder_problem(args: argparse.Namespace) -> str | None:
    """Why the run must not start in its folder (it holds another run's files), or None.

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     args = argparse.Namespace(out=Path(folder), overwrite=False,
        ...                               run_folder=("out", "--out", None))
        ...     empty = run_folder_problem(args)
        ...     _ = (Path(folder) / "summary.json").write_text("{}")
        ...     held = run_folder_problem(args)
        ...     args.overwrite = True
        ...     (empty, held.split(" (")[0].endswith("already holds a run"), run_folder_problem(args))
        (None, True, None)
    """
    dest, flag, resumed_by = getattr(args, "run_folder", None) or (None, "", None)
    path = getattr(args, dest) if dest else None
    resumed = resumed_by is not None and getattr(args, resumed_by, None)
    if path is None or args.overwrite or resumed or not path.is_dir():
        return None
    held = sorted(entry.name + ("/" if entry.is_dir() else "") for entry in path.iterdir())
    if not held:
        return None
    shown = ", ".join(held[:4]) + (f", ... ({len(held)} entries)" if len(held) > 4 else "")
    return (f"{flag} {path} already holds a run ({shown}): give another {flag}, or --overwrite to replace "
            "its files")


def _field(spec: str) -> tuple[type, dataclasses.Field]:
    """``"package.module:Class.field"`` -> the config class and its field (imported only now)."""
    module_name, _, qualified = spec.partition(":")
    class_name, _, field_name = qualified.partition(".")
    cls = getattr(importlib.import_module(module_name), class_name)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    return cls, fields[field_name]


def config_default(spec: str) -> tuple[Any, Mapping[str, Any]]:
    """The default and metadata of the field ``spec``: read from its source, imported if not literal.

    ``"module:NAME"`` (no field) is a module constant: its value and no metadata.
    """
    from uav_swarm.cli.field_source import read_constant, read_field

    module_name, _, qualified = spec.partition(":")
    if "." not in qualified:
        try:
            return read_constant(module_name, qualified), {}
        except LookupError:
            return getattr(importlib.import_module(module_name), qualified), {}
    found = read_field(spec)
    if found is not None:
        return found
    _, field = _field(spec)
    return field.default, field.metadata


class LazyChoices(Sequence[str]):
    """A flag's ``choices`` computed when first needed (parsing the flag, or its command's help).

    ``listed`` gives the choices the help and the messages list; ``allowed`` (default: membership in
    ``listed``) decides whether a value given is one, e.g. against a registry that can grow at run time.

    Examples:
        >>> choices = LazyChoices(lambda: ("a", "b"))
        >>> "a" in choices, list(choices), len(choices)
        (True, ['a', 'b'], 2)
        >>> "c" in LazyChoices(lambda: ("a",), allowed=lambda value: value in ("a", "c"))
        True
    """

    def __init__(self, listed: Callable[[], Sequence[str]],
                 allowed: Callable[[object], bool] | None = None) -> None:
        self._compute = listed
        self._allowed = allowed
        self._values: tuple[str, ...] | None = None

    def _all(self) -> tuple[str, ...]:
        if self._values is None:
            self._values = tuple(self._compute())
        return self._values

    def __getitem__(self, index: Any) -> Any:
        return self._all()[index]

    def __len__(self) -> int:
        return len(self._all())

    def __contains__(self, value: object) -> bool:
        return self._allowed(value) if self._allowed is not None else value in self._all()


def _shown(value: Any) -> str:
    if isinstance(value, bool):
        return "on" if value else "off"
    if value == "" or value is None:
        return "none"
    return str(value)


def config_flag(parser: argparse.ArgumentParser, flag: str, spec: str, help: str | None = None, *,
                key: str | None = None, **kwargs: Any) -> argparse.Action:
    """Add ``flag`` setting the config field ``spec`` (``"module:Class.field"``).

    The flag's value is converted to the field's type and checked against its range when parsed; its
    help is ``help`` (or the field's doc) followed by the field's default and the ``--config`` key
    (``key``, by default the field's name) that replaces it. The config class is imported only when the
    flag is given or its help is shown, so that ``uav-swarm --help`` stays fast.
    """

    def convert(text: str) -> Any:
        cls, field = _field(spec)
        kind = get_type_hints(cls)[field.name]
        if get_origin(kind) in (Union, UnionType):  # an optional number
            kind = next(k for k in get_args(kind) if k is not type(None))
        if get_origin(kind) is not None or kind not in (int, float):
            options = get_args(kind)
            if options and text not in options:
                raise argparse.ArgumentTypeError(f"{text!r} is not allowed: choose one of {list(options)}")
            if not options:
                _check_text(cls, field.name, text)
            return text
        meta = field.metadata
        return number(kind, ge=meta.get("ge"), gt=meta.get("gt"), le=meta.get("le"), lt=meta.get("lt"))(text)

    convert.__name__ = "value"
    action = parser.add_argument(flag, type=convert, help=help or _FIELD_DOC, **kwargs)
    action.config_field = spec  # type: ignore[attr-defined]
    action.config_key = spec.rpartition(".")[2] if key is None else key  # type: ignore[attr-defined]
    return action


def _check_text(cls: type, name: str, text: str) -> None:
    """A text field's own check (its config's ``check``), the message without the config's name."""
    from typed_config import ConfigError

    try:
        cls(**{name: text})
    except ConfigError as exc:
        message = str(exc)
        prefix = f"{cls.__name__}.{name}"
        if prefix in message:  # about this field, not another one the defaults leave unset
            message = message.replace(f"{prefix} = ", "").replace(prefix, name)
            raise argparse.ArgumentTypeError(message) from None


class CliHelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Descriptions as written; each flag's help followed by its default (from its config field if any).

    A flag with a ``default_from`` attribute (``"module:NAME"``) shows that constant as its default.
    """

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        source = getattr(action, "default_from", None)  # a module constant, read when the help is shown
        if source is not None and "(default" not in text:
            return f"{text} (default: {_shown(config_default(source)[0])})"
        spec = getattr(action, "config_field", None)
        if spec is not None:
            default, meta = config_default(spec)
            if text == _FIELD_DOC:
                text = meta.get("doc", "").replace("%", "%%")
            bounds = [f"{op} {meta[k]}" for k, op in (("ge", ">="), ("gt", ">"), ("le", "<="), ("lt", "<"))
                      if meta.get(k) is not None]
            allowed = f"; allowed {' and '.join(bounds)}" if bounds else ""
            if "(default" not in text:
                shown = _shown(default).replace("%", "%%")
                key = getattr(action, "config_key", None)
                source = f", or {key} of --config" if key else ""
                text += f" (default: {shown}{source}{allowed})"
            return text
        if isinstance(action, SWITCH_ACTIONS) or action.required or "default" in text:
            return text
        if action.default is not None and action.default is not argparse.SUPPRESS and action.option_strings:
            listed = isinstance(action.default, list)
            default = " ".join(map(str, action.default)) if listed else "%(default)s"
            return f"{text} (default: {default})"
        return text


class CliParser(argparse.ArgumentParser):
    """An ArgumentParser with the command line's conventions (see the module's docstring)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs["allow_abbrev"] = False
        kwargs.setdefault("formatter_class", CliHelpFormatter)
        if kwargs.get("formatter_class") is argparse.RawDescriptionHelpFormatter:
            kwargs["formatter_class"] = CliHelpFormatter
        kwargs["description"] = plain_text(kwargs.get("description"))
        super().__init__(*args, **kwargs)

    def add_argument(self, *args: Any, **kwargs: Any) -> argparse.Action:
        """As ArgumentParser's, with the help in plain text."""
        if isinstance(kwargs.get("help"), str):
            kwargs["help"] = plain_text(kwargs["help"])
        return super().add_argument(*args, **kwargs)

    def parse_known_args(  # type: ignore[override]  # one signature for argparse's three overloads
            self, args: Sequence[str] | None = None, namespace: argparse.Namespace | None = None
    ) -> tuple[argparse.Namespace, list[str]]:
        """Parse; an argument this parser does not know is an error in its own usage, with a suggestion."""
        if args is not None and not any(isinstance(a, argparse._SubParsersAction) for a in self._actions):
            args = list(args)
            flags = args[:args.index("--")] if "--" in args else args
            known = self._option_string_actions
            unknown = [a for a in flags if a.startswith("--") and a.split("=", 1)[0] not in known]
            if unknown:  # before the check of required arguments, which would hide the typo
                self.error(f"unrecognized arguments: {' '.join(unknown)}{self._suggestion(unknown)}")
        parsed, extras = super().parse_known_args(args, namespace)
        if extras:
            self.error(f"unrecognized arguments: {' '.join(extras)}{self._suggestion(extras)}")
        return parsed, extras

    def _suggestion(self, extras: list[str]) -> str:
        known = sorted(self._option_string_actions)
        for extra in extras:
            if not extra.startswith("-"):
                continue
            name = extra.split("=", 1)[0]
            close = [k for k in known if k.startswith(name) and name.startswith("--")]
            close = close or difflib.get_close_matches(name, known, n=1, cutoff=0.6)
            if close:
                return f" (did you mean {close[0]}?)"
        return ""


def add_verbosity(parser: argparse.ArgumentParser, *, top_level: bool = False) -> None:
    """``-v/--verbose`` and ``-q/--quiet``; after a subcommand they are unset unless given there."""
    default: Any = False if top_level else argparse.SUPPRESS
    group = parser.add_mutually_exclusive_group()
    group.add_argument("-v", "--verbose", action="store_true", default=default, help="log debug messages")
    group.add_argument("-q", "--quiet", action="store_true", default=default,
                       help="log warnings only, no progress bars")


def iter_parsers(parser: argparse.ArgumentParser, path: tuple[str, ...] = ()
                 ) -> Iterator[tuple[tuple[str, ...], argparse.ArgumentParser]]:
    """Every parser of the command line with its subcommand path, the top-level one first."""
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from iter_parsers(sub, (*path, name))
