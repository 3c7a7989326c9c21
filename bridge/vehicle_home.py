"""A vehicle's own home as it reports it, and the check that a mission was built near it.

The home is the vehicle's HOME_POSITION (asked for with ``MAV_CMD_REQUEST_MESSAGE`` when
it is not streamed) or, when none comes within one handshake timeout, its first
GLOBAL_POSITION_INT fix (latitude and longitude not both 0: ArduPilot reports 0, 0
before its GPS fix). A mission built around another home would send the vehicle to
places it does not expect: beyond ``max_home_offset_m`` the upload is refused.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

from bridge.config import ProtocolConfig
from bridge.errors import HomeMismatchError, HomeUnknownError
from bridge.geo import Home, ground_distance_m
from bridge.mavlink import MavlinkLink

__all__ = ["ReportedHome", "HomeWatcher", "check_home_offset"]

_AUTOPILOT_COMPONENT = 1
_HOME_POSITION_ID = 242  # MAVLINK_MSG_ID_HOME_POSITION
_REQUEST_MESSAGE = 512  # MAV_CMD_REQUEST_MESSAGE


@dataclass(frozen=True)
class ReportedHome:
    """A vehicle's home and where it came from (``"HOME_POSITION"`` or ``"GLOBAL_POSITION_INT"``)."""

    home: Home
    source: str

    def describe(self) -> str:
        """``lat ..., lon ..., alt ... m (from SOURCE)``."""
        return f"{_describe(self.home)} (from {self.source})"


def _describe(home: Home) -> str:
    return f"lat {home.lat_deg:.7f}, lon {home.lon_deg:.7f}, alt {home.alt_m:.1f} m"


def _home(lat_e7: int, lon_e7: int, alt_mm: int) -> Home | None:
    """The position as a :class:`Home`, or ``None`` for "no fix" (0, 0) and impossible values."""
    lat_deg, lon_deg, alt_m = lat_e7 / 1e7, lon_e7 / 1e7, alt_mm / 1000.0
    if (lat_e7, lon_e7) == (0, 0) or not (-90 <= lat_deg <= 90 and -180 <= lon_deg <= 180):
        return None
    return Home(lat_deg=lat_deg, lon_deg=lon_deg, alt_m=min(max(alt_m, -500.0), 9000.0))


class HomeWatcher:
    """Keeps each vehicle's HOME_POSITION and first position fix; a link listener (thread-safe)."""

    MESSAGE_TYPES = frozenset({"HOME_POSITION", "GLOBAL_POSITION_INT"})
    """The message types :meth:`update` uses (for :meth:`~bridge.mavlink.MavlinkLink.add_listener`)."""

    def __init__(self) -> None:
        self._changed = threading.Condition()
        self._homes: dict[int, Home] = {}
        self._fixes: dict[int, Home] = {}

    def update(self, msg: object) -> None:
        """Note a HOME_POSITION or a first GLOBAL_POSITION_INT fix (other messages are ignored)."""
        kind = msg.get_type()
        if kind not in self.MESSAGE_TYPES:
            return
        if msg.get_srcComponent() != _AUTOPILOT_COMPONENT:
            return
        system_id = msg.get_srcSystem()
        if kind == "HOME_POSITION":
            home = _home(msg.latitude, msg.longitude, msg.altitude)
            if home is None:
                return
            with self._changed:
                self._homes[system_id] = home
                self._changed.notify_all()
        elif system_id not in self._fixes:
            fix = _home(msg.lat, msg.lon, msg.alt)
            if fix is None:
                return
            with self._changed:
                self._fixes.setdefault(system_id, fix)
                self._changed.notify_all()

    def wait(self, link: MavlinkLink, system_id: int, protocol: ProtocolConfig) -> ReportedHome:
        """The vehicle's home, asking for HOME_POSITION once per handshake timeout.

        The first position fix stands in for it when no HOME_POSITION came within one
        handshake timeout; at most ``protocol.home_timeout_s`` is spent.

        Raises:
            HomeUnknownError: Neither arrived in time.
        """
        start_s = time.monotonic()
        deadline_s = start_s + protocol.home_timeout_s
        fallback_s = start_s + protocol.handshake_timeout_s
        next_request_s = start_s
        while True:
            now_s = time.monotonic()
            with self._changed:
                if system_id in self._homes:
                    return ReportedHome(self._homes[system_id], "HOME_POSITION")
                fix = self._fixes.get(system_id)
            if fix is not None and (now_s >= fallback_s or now_s >= deadline_s):
                return ReportedHome(fix, "GLOBAL_POSITION_INT")
            if now_s >= deadline_s:
                raise HomeUnknownError(system_id, protocol.home_timeout_s)
            if now_s >= next_request_s:
                next_request_s = now_s + protocol.handshake_timeout_s
                link.send(
                    lambda mav: mav.command_long_send(
                        system_id, _AUTOPILOT_COMPONENT, _REQUEST_MESSAGE, 0, _HOME_POSITION_ID, *(0,) * 6
                    )
                )
            wake_s = min(next_request_s, deadline_s, fallback_s if fix is not None else deadline_s)
            with self._changed:
                self._changed.wait(max(0.0, wake_s - time.monotonic()))


def check_home_offset(
    system_id: int, mission_home: Home, reported: ReportedHome, max_offset_m: float
) -> float:
    """The horizontal distance between the mission's home and the vehicle's; refused beyond ``max_offset_m``.

    Raises:
        HomeMismatchError: Naming both positions, the distance and the limit.
    """
    offset_m = ground_distance_m(mission_home, reported.home)
    if offset_m > max_offset_m:
        distance = f"{offset_m / 1000:,.1f} km" if offset_m >= 10_000 else f"{offset_m:,.1f} m"
        raise HomeMismatchError(
            system_id,
            offset_m,
            f"its home ({reported.describe()}) is {distance} from the mission's home "
            f"({_describe(mission_home)}); allowed max_home_offset_m = {max_offset_m:g} m. Nothing was "
            'sent: set [home] to where the vehicle is, or home = "vehicle" to build each mission around '
            "its vehicle's own home",
        )
    return offset_m
