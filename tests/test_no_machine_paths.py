"""No machine paths in committed results, configs, docs and READMEs: files are named relative to the repo."""

import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SCANNED_FOLDERS = ("results", "configs", "docs")
SCANNED_FILES = ("README.md", "benchmarks/README.md")
TEXT_SUFFIXES = {".json", ".md", ".toml", ".csv", ".plan", ".txt"}

# An absolute path of some machine: a Unix root folder that holds user or scratch files, a home
# folder (~/), or a Windows drive (C:\ or C:/, with the backslash escaped or not). The look-behind
# keeps relative paths (runs/tmp/...) and URLs (https://host/home/...) out.
MACHINE_PATH = re.compile(
    r"(?<![\w.:/~-])(?:/(?:work|home|root|tmp|Users|mnt|var|opt|usr|private|scratch|srv)/|~/)"
    r"|(?<![\w])[A-Za-z]:(?:\\\\|\\|/)(?=[\w.])"
)


def _scanned_files() -> list[Path]:
    """The text files of the scanned folders, then the scanned single files."""
    files = [
        path
        for folder in SCANNED_FOLDERS
        for path in sorted((REPO / folder).rglob("*"))
        if path.is_file() and path.suffix in TEXT_SUFFIXES
    ]
    return files + [REPO / name for name in SCANNED_FILES if (REPO / name).is_file()]


@pytest.mark.parametrize(
    "text",
    [
        '"checkpoint": "/work/main/uav_swarm/checkpoints/wifi-s1.pt"',
        "saved to /home/alice/runs/x",
        "see /tmp/out",
        "(/root/.cache)",
        "`~/data/scenes`",
        r'"C:\\Users\\bob\\run"',
        r"D:\runs\s1",
        "E:/runs/s1",
    ],
)
def test_the_pattern_finds_machine_paths(text):
    assert MACHINE_PATH.search(text)


@pytest.mark.parametrize(
    "text",
    [
        '"checkpoint": "uav_swarm/checkpoints/wifi-s1.pt (shipped)"',
        "runs/wifi-s1/tmp/best.pt",
        "https://github.com/srl-freiburg/pedsim_ros/home/x",
        "5 km/h, 3 m/s, ratio 1:2",
        "tests/data/pedsim/scene1.xml",
        "12:30/14:00",
    ],
)
def test_the_pattern_leaves_relative_paths_and_urls(text):
    assert not MACHINE_PATH.search(text)


def test_the_scan_covers_results_configs_and_readme():
    names = {path.relative_to(REPO).as_posix() for path in _scanned_files()}
    assert "README.md" in names and "docs/bridge.md" in names
    assert "results/simulate/summary.json" in names
    assert any(name.startswith("configs/") for name in names)


def test_no_absolute_paths_in_results_configs_and_readme():
    found = []
    for path in _scanned_files():
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
            match = MACHINE_PATH.search(line)
            if match:
                start = max(match.start() - 40, 0)
                found.append(f"{path.relative_to(REPO)}:{number}: ...{line[start:match.end() + 40]}...")
    assert not found, "absolute paths of a machine in committed files:\n" + "\n".join(found)
