"""Every folder or file a command writes is checked when the command line is parsed, before any work.

Each command is given, for each of its output flags, each kind of wrong path: an existing file where a
folder is written (or a folder where a file is), a path under a file, and a place this user cannot
write. Each answer is the usage and one error line naming the flag, exit code 2, and nothing written.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

import pytest

from uav_swarm.cli import build_parser, main
from uav_swarm.cli.conventions import iter_parsers, output_problem

OUTPUT_NAMES = ("--out", "--record", "--write-checkpoint")
"""Flags that name what a command writes, in every command that has them."""


def _output_flags() -> list[tuple[tuple[str, ...], str, str]]:
    """(subcommand path, flag, "folder" or "file") of every output flag of the command line."""
    found = []
    for path, parser in iter_parsers(build_parser()):
        for action in parser._actions:
            kind = getattr(action, "output_kind", None)
            if kind is not None:
                found.append((path, action.option_strings[0], kind))
    return found


OUTPUT_FLAGS = _output_flags()


def _argv(path: tuple[str, ...], flag: str, value: str) -> list[str]:
    """The subcommand, its positional arguments (their first choice), then ``flag value``."""
    parser = dict(iter_parsers(build_parser()))[path]
    positionals = [a.choices[0] if isinstance(a.choices, (list, tuple)) else next(iter(a.choices))
                   for a in parser._actions
                   if not a.option_strings and a.choices and not isinstance(a, argparse._SubParsersAction)]
    return [*path, *map(str, positionals), flag, value]


def _unwritable(tmp_path: Path) -> Path:
    """A folder this user cannot create files in (a read-only one; for root, /sys), or skip."""
    folder = tmp_path / "read-only"
    folder.mkdir()
    folder.chmod(0o555)
    candidates = [folder] + ([Path("/sys")] if sys.platform.startswith("linux") else [])
    for place in candidates:
        try:
            handle, probe = tempfile.mkstemp(dir=place)
        except OSError:
            return place
        os.close(handle)
        os.unlink(probe)
    pytest.skip("no folder here refuses this user's writes")


def test_every_output_flag_is_checked() -> None:
    """Each flag named like an output is an output flag (checked when parsed), in every command."""
    unchecked = [(" ".join(path), action.option_strings[0])
                 for path, parser in iter_parsers(build_parser()) for action in parser._actions
                 if set(action.option_strings) & set(OUTPUT_NAMES) and not hasattr(action, "output_kind")]
    assert unchecked == []
    commands = {path[0] for path, _, _ in OUTPUT_FLAGS}
    assert {"simulate", "fly", "place", "dataset", "train", "evaluate", "search", "vehicles", "env-demo",
            "mission", "telemetry", "rl-train", "rl-compare", "expert-stability", "calibrate-check",
            "calibrate-mission"} <= commands


@pytest.mark.parametrize("wrong", ["other kind", "under a file", "unwritable"])
@pytest.mark.parametrize(("path", "flag", "kind"), OUTPUT_FLAGS,
                         ids=[f"{' '.join(p)} {f}" for p, f, _ in OUTPUT_FLAGS])
def test_a_wrong_output_path_is_refused_before_any_work(
        path: tuple[str, ...], flag: str, kind: str, wrong: str, tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    work = tmp_path / "work"
    work.mkdir()
    (work / "notes.txt").write_text("a file\n", encoding="utf-8")
    monkeypatch.chdir(work)
    name = "report.json" if kind == "file" else "results"
    value = {"other kind": "notes.txt" if kind == "folder" else ".",
             "under a file": f"notes.txt/{name}",
             "unwritable": str(_unwritable(tmp_path) / name)}[wrong]
    before = sorted(p.name for p in work.iterdir())

    code = main(_argv(path, flag, value))

    err = capsys.readouterr().err
    assert code == 2
    last = err.strip().splitlines()[-1]
    assert f"argument {flag}: " in last and value in last, err
    assert "Traceback" not in err
    assert sorted(p.name for p in work.iterdir()) == before


def test_a_default_output_folder_is_checked_too(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    """``simulate`` without --out writes out/simulate: a file named ``out`` here is refused at once."""
    (tmp_path / "out").write_text("", encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "--no-telemetry"]) == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == (
        "uav-swarm simulate: error: argument --out: out/simulate lies under out, a file, not a folder")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_a_writable_output_passes(tmp_path: Path) -> None:
    """A new folder under a writable one, an existing folder and a new or existing file are accepted."""
    (tmp_path / "old.json").write_text("{}", encoding="utf-8")
    assert output_problem(tmp_path / "new" / "deeper", "folder") is None
    assert output_problem(tmp_path, "folder") is None
    assert output_problem(tmp_path / "new" / "r.json", "file") is None
    assert output_problem(tmp_path / "old.json", "file") is None
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old.json"]
