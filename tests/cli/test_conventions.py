"""The command line's conventions (docs/cli.md), checked on every subcommand's parser."""

from __future__ import annotations

import argparse
import re
from collections import defaultdict
from typing import get_args, get_origin, get_type_hints

import pytest

from uav_swarm.cli import build_parser, main
from uav_swarm.cli.conventions import SWITCH_ACTIONS, _field, iter_parsers
from uav_swarm.missions.registry import TASKS

UNIT_SUFFIXES = ("-s", "-m", "-m-s", "-hz", "-deg", "-px", "-mbps", "-minutes", "-steps")
"""What a numeric flag of a physical quantity ends with (docs/cli.md)."""

DIMENSIONLESS = {"--lr", "--qos-floor", "--margin-z", "--speedup", "--focal-weight", "--thresholds",
                 "--contrasts", "--command-loss"}
"""Float flags that are ratios or weights, without a unit (docs/cli.md lists them)."""

TIME_WORDS = ("every", "duration", "timeout", "wait", "period", "interval", "delay", "refresh")
"""Words of an interval: a flag holding one names its unit even when it is an integer."""

SYNONYMS = {"--out-dir": "--out", "--output": "--out", "--threads": "--torch-threads",
            "--num-uavs": "--n-uavs", "--resume-dir": "--resume"}
"""Names that would give a second name to a concept the command line already names."""

PARSER = build_parser()
PARSERS = list(iter_parsers(PARSER))
SUBCOMMANDS = [(path, parser) for path, parser in PARSERS if path]
LEAVES = [(path, parser) for path, parser in SUBCOMMANDS
          if not any(isinstance(a, argparse._SubParsersAction) for a in parser._actions)]
IDS = [" ".join(path) or "uav-swarm" for path, _ in PARSERS]


def _flags(parser: argparse.ArgumentParser) -> list[argparse.Action]:
    return [a for a in parser._actions if a.option_strings and not isinstance(a, argparse._HelpAction)]


def _kind(action: argparse.Action) -> type | None:
    """int or float for a numeric flag, else None."""
    spec = getattr(action, "config_field", None)
    if spec is not None:
        cls, field = _field(spec)
        kind = get_type_hints(cls)[field.name]
        args = [a for a in get_args(kind) if a is not type(None)]
        kind = args[0] if get_origin(kind) is not None and len(args) == 1 else kind
        return kind if kind in (int, float) else None
    name = getattr(action.type, "__name__", None)
    return {"int": int, "float": float}.get(name)


def test_every_subcommand_is_walked():
    names = {path[0] for path, _ in SUBCOMMANDS}
    assert {"simulate", "fly", "place", "dataset", "train", "evaluate", "mission", "telemetry"} <= names
    assert ("telemetry", "record") in [path for path, _ in LEAVES]


@pytest.mark.parametrize(("path", "parser"), PARSERS, ids=IDS)
def test_no_abbreviations_and_a_description(path, parser):
    assert parser.allow_abbrev is False
    assert parser.description and len(parser.description) > 40, f"{path}: no description"


@pytest.mark.parametrize(("path", "parser"), PARSERS, ids=IDS)
def test_every_flag_shows_its_default_in_plain_text(path, parser):
    formatter = parser._get_formatter()
    for action in _flags(parser):
        if isinstance(action, SWITCH_ACTIONS) or action.required:
            continue  # a switch is off unless given; a required flag has no default
        text = formatter._expand_help(action) if action.help else ""
        assert "default" in text, f"{path} {action.option_strings}: help shows no default: {text!r}"
    help_text = parser.format_help()
    for markup in ("``", ":mod:", ":class:", ":func:", ":data:", ":meth:", "::\n"):
        assert markup not in help_text, f"{path}: {markup!r} in the terminal help"


@pytest.mark.parametrize(("path", "parser"), PARSERS, ids=IDS)
def test_numeric_flags_name_their_unit(path, parser):
    for action in _flags(parser):
        kind = _kind(action)
        for flag in (s for s in action.option_strings if s.startswith("--")):
            with_unit = flag.endswith(UNIT_SUFFIXES)
            if kind is float:
                assert with_unit or flag in DIMENSIONLESS, f"{path} {flag}: a number without its unit"
            if kind is int and any(word in flag for word in TIME_WORDS):
                assert with_unit, f"{path} {flag}: an interval without its unit"


def test_one_name_per_concept():
    switches: dict[str, set[bool]] = defaultdict(set)
    for path, parser in PARSERS:
        for action in _flags(parser):
            for flag in action.option_strings:
                assert flag not in SYNONYMS, f"{path} {flag}: the concept's name is {SYNONYMS[flag]}"
                switches[flag].add(action.nargs == 0)
    mixed = sorted(flag for flag, kinds in switches.items() if len(kinds) > 1)
    assert not mixed, f"a switch in one command and a flag with a value in another: {mixed}"


def test_task_choices_are_the_registry():
    for path, parser in SUBCOMMANDS:
        for action in _flags(parser):
            if "--task" in action.option_strings and path[0] not in ("place", "calibrate-check"):
                assert tuple(action.choices) == tuple(TASKS), path


@pytest.mark.parametrize(("path", "parser"), LEAVES, ids=[" ".join(p) for p, _ in LEAVES])
def test_verbosity_is_accepted_after_the_subcommand(path, parser):
    argv = [*path, *_required(parser)]
    assert PARSER.parse_args([*argv, "-v"]).verbose is True
    assert PARSER.parse_args([*argv, "--quiet"]).quiet is True
    assert PARSER.parse_args(["-q", *argv]).quiet is True
    defaults = PARSER.parse_args(argv)
    assert defaults.verbose is False and defaults.quiet is False


def _required(parser: argparse.ArgumentParser) -> list[str]:
    """Values for the required arguments (positional choices first), so that parsing reaches the rest."""
    argv: list[str] = []
    for action in parser._actions:
        if action.option_strings and not action.required:
            continue
        if isinstance(action, argparse._SubParsersAction):
            continue
        value = str(next(iter(action.choices))) if action.choices else "1"
        argv += [value] if not action.option_strings else [action.option_strings[-1], value]
    return argv


@pytest.mark.parametrize(("path", "parser"), LEAVES, ids=[" ".join(p) for p, _ in LEAVES])
def test_a_mistyped_flag_gets_the_subcommands_usage_and_a_suggestion(path, parser, capsys):
    flag = max((s for a in _flags(parser) for s in a.option_strings if s.startswith("--")), key=len)
    prefix = flag[:-2]  # an abbreviation: refused, the flag suggested
    assert main([*path, *_required(parser), prefix, "1"]) == 2
    err = capsys.readouterr().err
    assert f"usage: uav-swarm {' '.join(path)}" in err
    assert re.search(rf"unrecognized arguments: {re.escape(prefix)} \(did you mean --", err), err
    typo = flag[:3] + flag[4:]  # one letter missing inside
    assert main([*path, *_required(parser), typo, "1"]) == 2
    assert "(did you mean --" in capsys.readouterr().err


def test_a_top_level_flag_after_the_subcommand_is_taken():
    args = PARSER.parse_args(["simulate", "-v", "--n-uavs", "3"])
    assert args.verbose and args.n_uavs == 3


def test_a_mistyped_flag_is_named_before_a_missing_required_one(capsys):
    assert main(["dataset", "--tsk", "wifi-s1", "--n", "5", "--seed", "1", "--out", "d"]) == 2
    err = capsys.readouterr().err
    assert "unrecognized arguments: --tsk (did you mean --task?)" in err and "required" not in err
