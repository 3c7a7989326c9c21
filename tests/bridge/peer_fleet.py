"""What the fly tests on faithful peers share: swift vehicles, a peer fleet's bridge config file, its end."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path


def swift(kind: str, speed_m_s: float = 12.0) -> dict[str, float]:
    """Parameters of a swift test vehicle (``kind``: ``"ardupilot"`` or ``"px4"``): ``speed_m_s``, climb and
    descent 8 m/s, accelerations 10 m/s^2 and no jerk limit to speak of (100 m/s^3: the simulated vehicles
    have none), so that flights stay short."""
    if kind == "px4":
        return {"MPC_XY_CRUISE": speed_m_s, "MPC_XY_VEL_MAX": max(speed_m_s, 12.0), "MPC_ACC_HOR": 10.0,
                "MPC_JERK_AUTO": 100.0,
                "MPC_TKO_SPEED": 8.0, "MPC_Z_V_AUTO_UP": 8.0, "MPC_Z_V_AUTO_DN": 8.0, "MPC_ACC_UP_MAX": 10.0,
                "MPC_ACC_DOWN_MAX": 10.0}
    return {"WPNAV_SPEED": speed_m_s * 100, "WPNAV_ACCEL": 1000.0, "WPNAV_SPEED_UP": 800.0,
            "WPNAV_SPEED_DN": 800.0, "WPNAV_ACCEL_Z": 1000.0, "PSC_JERK_XY": 100.0}


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


def wait_until(condition: Callable[[], bool], timeout_s: float) -> bool:
    """Poll ``condition`` every 0.05 s until it holds or ``timeout_s`` has passed; its last answer."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.05)
    return condition()
