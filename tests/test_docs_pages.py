"""The pages read as a user's manual: every page listed, every command documented, nothing elsewhere."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from uav_swarm.cli import build_parser
from uav_swarm.cli.conventions import iter_parsers

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PAGES = sorted(DOCS.glob("*.md"))
READ = [*PAGES, ROOT / "README.md", ROOT / "benchmarks" / "README.md", ROOT / "tools" / "sitl" / "README.md"]


def test_the_index_and_the_site_list_every_page():
    index = (DOCS / "index.md").read_text(encoding="utf-8")
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    for page in PAGES:
        if page.name != "index.md":
            assert f"]({page.name}" in index, f"docs/index.md does not list {page.name}"
            assert page.name in nav, f"mkdocs.yml's nav lacks {page.name}"


def test_the_command_line_page_lists_every_subcommand():
    text = (DOCS / "cli.md").read_text(encoding="utf-8")
    for path, _ in iter_parsers(build_parser()):
        if path:
            assert path[-1] in text, f"docs/cli.md does not mention uav-swarm {' '.join(path)}"


@pytest.mark.parametrize("page", READ, ids=[str(p.relative_to(ROOT)) for p in READ])
def test_no_issue_numbers_and_nothing_outside_the_repository(page):
    text = page.read_text(encoding="utf-8")
    assert not re.search(r"\bissues? ?#?\d+", text, re.IGNORECASE), f"{page.name} names an issue number"
    assert "../shared" not in text and "](../../" not in text, f"{page.name} points outside the repository"
