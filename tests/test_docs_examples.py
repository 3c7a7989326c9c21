"""Every ```python block of README.md and docs/ runs, from the repository root, each in a fresh namespace.

One block talks to MAVLink vehicles: its fence has ``title="Needs the config's vehicles 1 and 2"``. For it
the test starts two simulated vehicles on loopback (``bridge/simulated/peer.py``) and puts a config of
their links in place of the block's bridge config file; everything else in the block runs as written.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
FENCE = re.compile(r"^```python(?P<info>[^\n]*)\n(?P<code>.*?)^```$", re.MULTILINE | re.DOTALL)
NEEDS_VEHICLES = "Needs the config's vehicles 1 and 2"
BRIDGE_CONFIG = "configs/bridge/px4_sitl_10.toml"


def _blocks() -> list:
    found = []
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        for match in FENCE.finditer(text):
            line = text.count("\n", 0, match.start()) + 1
            name = f"{page.relative_to(ROOT)}:{line}"
            found.append(pytest.param(name, match["info"], match["code"], id=name))
    return found


BLOCKS = _blocks()


def test_the_pages_hold_python_examples():
    names = {param.values[0].split(":")[0] for param in BLOCKS}
    expected = {"README.md", "docs/environment.md", "docs/marl.md", "docs/telemetry.md", "docs/bridge.md"}
    assert expected <= names


def _run(name: str, code: str) -> None:
    exec(compile(code, name, "exec"), {"__name__": "__docs__"})  # noqa: S102 - the documentation's own code


def _run_with_vehicles(name: str, code: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(ROOT / "tests" / "bridge"))
    from lossy_relay import free_udp_port

    from bridge.simulated.peer import SimVehicle, endpoint_pair

    assert BRIDGE_CONFIG in code, f"{name}: the block no longer reads {BRIDGE_CONFIG}"
    vehicles, table = [], []
    try:
        for system_id in (1, 2):
            vehicle_url, gcs_url = endpoint_pair("udpin", free_udp_port())
            vehicles.append(SimVehicle(vehicle_url, system_id, telemetry_period_s=0.3))
            table.append(f'[[vehicles]]\nsystem_id = {system_id}\nurl = "{gcs_url}"\n')
        config = tmp_path / "two_vehicles.toml"
        config.write_text("\n".join(table), encoding="utf-8")
        _run(name, code.replace(BRIDGE_CONFIG, str(config)))
        assert [len(v.mission) > 0 for v in vehicles] == [True, True]
        assert vehicles[0].reposition_target is not None
    finally:
        for vehicle in vehicles:
            vehicle.close()


@pytest.mark.parametrize(("name", "info", "code"), BLOCKS)
def test_python_block_runs(name, info, code, tmp_path, monkeypatch):
    monkeypatch.chdir(ROOT)
    if NEEDS_VEHICLES in info:
        _run_with_vehicles(name, code, tmp_path, monkeypatch)
    else:
        assert "title=" not in info, f"{name}: unknown block title {info!r}"
        _run(name, code)
