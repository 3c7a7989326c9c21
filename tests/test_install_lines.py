"""One install story: the Makefile's extras are the list; the README's and the docs' install lines agree."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MAKEFILE = (ROOT / "Makefile").read_text(encoding="utf-8")
PAGES = ["README.md", *sorted(str(p.relative_to(ROOT)) for p in (ROOT / "docs").glob("*.md"))]


def _make_variable(name: str) -> str:
    match = re.search(rf"^{name}\s*[:?]?=\s*(\S*)\s*$", MAKEFILE, re.MULTILINE)
    assert match, f"Makefile: no {name} ="
    return match.group(1)


def _test_extras() -> set[str]:
    return set(_make_variable("TEST_EXTRAS").split(","))


def _declared_extras() -> set[str]:
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    return set(pyproject["project"]["optional-dependencies"])


def _extras_named(line: str) -> list[set[str]]:
    """Every extras list of a line: `.[a,b]`, `uav-swarm[a]`, `'uav-swarm[a,b]'`."""
    return [set(group.split(",")) for group in re.findall(r"(?:\.|uav-swarm)\[([a-z0-9_,-]+)\]", line)]


def test_the_makefile_installs_its_test_extras_and_they_exist():
    assert '-e ".[$(TEST_EXTRAS)]"' in MAKEFILE  # the recipe takes the variable, not a copy of it
    assert _test_extras() <= _declared_extras()


@pytest.mark.parametrize("page", PAGES)
def test_every_install_line_names_extras_that_exist(page):
    for line in (ROOT / page).read_text(encoding="utf-8").splitlines():
        for extras in _extras_named(line):
            assert extras <= _declared_extras(), f"{page}: {line.strip()!r} names extras pyproject lacks"


@pytest.mark.parametrize("page", ["README.md", "docs/index.md"])
def test_what_make_test_installs_is_the_makefiles_list(page):
    lines = (ROOT / page).read_text(encoding="utf-8").splitlines()
    named = [extras for line in lines if "make test" in line for extras in _extras_named(line)]
    assert named, f"{page}: no line says which extras make test installs"
    assert all(extras == _test_extras() for extras in named), f"{page}: {named} != Makefile's TEST_EXTRAS"


def test_the_readme_pip_lines_are_the_makefiles_steps():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    torch = _make_variable("TORCH")
    cpu_index = re.search(r"TORCH_INDEX=(\S+)", MAKEFILE).group(1)  # the Makefile's own example
    assert f"pip install {torch} --index-url {cpu_index}" in text
    assert f"make demo TORCH_INDEX={cpu_index}" in text
    demo = "uav-swarm simulate --out out/simulate"
    assert demo in MAKEFILE and demo in text
    listed = re.search(r"also the extras\s+`([a-z0-9,]+)`", text)
    assert listed and set(listed.group(1).split(",")) == _test_extras()
