"""What the fly tests on faithful peers share: the bridge config file of a peer fleet and its end."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path


def bridge_toml(path: Path, urls: list[str], protocol: Mapping[str, float]) -> Path:
    """Write a bridge config for peers at ``urls`` (system ids 1, 2, ...) with a roomy geofence."""
    lines = ["[geofence]", "x_min_m = -20.0", "y_min_m = -20.0", "x_max_m = 300.0", "y_max_m = 300.0",
             "[protocol]", *(f"{k} = {v}" for k, v in protocol.items())]
    for sid, url in enumerate(urls, start=1):
        lines += ["[[vehicles]]", f"system_id = {sid}", f'url = "{url}"']
    path.write_text("\n".join(lines) + "\n")
    return path


def close_all(vehicles: Iterable) -> None:
    """Close every peer."""
    for vehicle in vehicles:
        vehicle.close()
