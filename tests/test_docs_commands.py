"""The shell blocks of README.md and docs/ as a newcomer runs them.

- Every ``uav-swarm`` command of a shell block parses as written (its flags and choices exist, its output
  paths can be written), from a fresh folder: a renamed flag breaks the test, not the reader.
- A block that costs more than a test can spend (an install, minutes of flight, hours of training) or
  needs what the suite does not start (SITL autopilots, a second terminal, ROS 2) says so in its title
  (```` ```bash title="Takes minutes" ````, ``title="Needs SITL autopilots running"``): a title starting
  with "Takes" or "Needs". Every other block is run here, literally: each ``$ `` command of a console
  block, its last printed line compared with the page's (``[...]`` stands for any text).
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from uav_swarm.cli import build_parser, main

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
FENCE = re.compile(r"^```(?P<lang>bash|sh|console|shell)(?P<info>[^\n]*)\n(?P<code>.*?)^```$",
                   re.MULTILINE | re.DOTALL)
TITLE = re.compile(r'title="(?P<title>[^"]+)"')
SYNOPSIS = re.compile(r"\[|\.\.\.")  # "[--vehicle 1 ...]", "uav-swarm evaluate ... --flag": a synopsis


def _blocks() -> list[tuple[str, str, str, str]]:
    """``(page:line, language, title or "", code)`` of every shell block."""
    found = []
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        for match in FENCE.finditer(text):
            line = text.count("\n", 0, match.start()) + 1
            title = TITLE.search(match["info"])
            found.append((f"{page.relative_to(ROOT)}:{line}", match["lang"], title["title"] if title else "",
                          match["code"]))
    return found


BLOCKS = _blocks()


def _commands(lang: str, code: str) -> list[str]:
    """The ``uav-swarm`` command lines of a block: continuations joined, prompts and comments dropped.

    In a console block only the lines after a ``$`` prompt are commands (the others are what they print).
    """
    lines = code.replace("\\\n", " ").splitlines()
    commands = []
    for line in lines:
        line = line.strip()
        if lang == "console":
            if not line.startswith("$ "):
                continue
            line = line[2:]
        if line.startswith("uav-swarm "):
            words = shlex.split(line, comments=True)
            commands.append(" ".join(shlex.quote(w) for w in words if w != "&"))
    return commands


MISTAKES = "docs/cli.md"
"""The page whose console block shows mistakes and their answers (run, not parsed, here)."""

DOCUMENTED = [(name, command) for name, lang, _, code in BLOCKS if lang != "console"
              for command in _commands(lang, code) if not SYNOPSIS.search(command)]


def test_the_pages_hold_commands_and_every_costly_block_says_so():
    assert len(DOCUMENTED) >= 35
    for name, _, title, _code in BLOCKS:
        assert not title or title.startswith(("Takes", "Needs")), f"{name}: title {title!r}"
    run_here = [(name.split(":")[0], lang) for name, lang, title, code in BLOCKS
                if not title and _commands(lang, code)]
    assert run_here == [(MISTAKES, "console")], "a block without a Takes/Needs title is run by this test"


@pytest.mark.parametrize(("name", "command"), DOCUMENTED, ids=[f"{n} {c[10:50]}" for n, c in DOCUMENTED])
def test_a_documented_command_parses_as_written(name, command, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    try:
        build_parser().parse_args(shlex.split(command)[1:])
    except SystemExit as exc:
        pytest.fail(f"{name}: {command!r} does not parse (exit {exc.code})")
    assert list(tmp_path.iterdir()) == []  # parsing writes nothing


def test_the_mistakes_of_the_command_line_page(capsys, monkeypatch):
    """Each ``$`` command of docs/cli.md's console block, run from the repository: its last line as shown."""
    (code,) = [code for name, lang, _, code in BLOCKS if name.startswith(MISTAKES) and lang == "console"]
    monkeypatch.chdir(ROOT)
    before = sorted(p.name for p in ROOT.iterdir())
    steps = re.split(r"^\$ ", code, flags=re.MULTILINE)[1:]
    assert len(steps) >= 4
    for step in steps:
        command, *shown = step.strip().splitlines()
        assert main(shlex.split(command)[1:]) == 2, command
        printed = capsys.readouterr().err.strip().splitlines()[-1]
        expected = re.escape(shown[-1]).replace(re.escape("[...]"), ".*")
        assert re.fullmatch(expected, printed), f"{command}:\n  page:    {shown[-1]}\n  printed: {printed}"
    assert sorted(p.name for p in ROOT.iterdir()) == before
