"""README.md links only to files the repository holds, by relative paths (mkdocs checks docs/ itself)."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LINK = re.compile(r"\]\((?P<target>[^)\s]+)\)")


def _local_targets() -> list[str]:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    return [m["target"] for m in LINK.finditer(text) if not re.match(r"[a-z]+://", m["target"])]


def test_readme_links_into_the_docs_pages():
    targets = _local_targets()
    assert "docs/index.md" in targets and "docs/bridge.md" in targets and "docs/telemetry.md" in targets


def test_every_local_link_of_the_readme_is_a_relative_path_that_exists():
    for target in _local_targets():
        path = target.split("#")[0]
        assert not path.startswith("/"), f"README.md links to an absolute path: {target}"
        assert (ROOT / path).is_file(), f"README.md links to a missing file: {target}"
