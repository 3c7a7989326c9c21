"""A vehicle's own home as it reports it, and the check that a mission was built near it.

The home is the vehicle's HOME_POSITION or, for autopilots that may not report one, its first
GLOBAL_POSITION_INT fix (latitude and longitude not both 0: ArduPilot reports 0, 0 before its
fix). :class:`HomeWatcher` keeps both as they arrive; :mod:`bridge.flight.readiness` waits for them.
A mission built around another home would send the vehicle to places it does not expect:
beyond ``max_home_offset_m`` the upload is refused (:func:`check_home_offset`).
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass

from bridge.errors import HomeMismatchError
from bridge.geo import Home, ground_distance_m
from bridge.link.frames import MavMessage

__all__ = ["ReportedHome", "HomeWatcher", "check_home_offset"]

_AUTOPILOT_COMPONENT = 1


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
    """Keeps each vehicle's latest HOME_POSITION and its first position fix; a link listener (thread-safe).

    Both are kept with the time (``time.monotonic()``) they were last heard, so that a caller can ask
    for what a vehicle said since a moment (a restarted vehicle's old home is not its home now).
    A GLOBAL_POSITION_INT without a fix (0, 0) forgets the fix: the next fix is a first fix again.
    """

    MESSAGE_TYPES = frozenset({"HOME_POSITION", "GLOBAL_POSITION_INT"})
    """The message types :meth:`update` uses (for :meth:`~bridge.link.mavlink.MavlinkLink.add_listener`)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._homes: dict[int, tuple[Home, float]] = {}
        self._fixes: dict[int, tuple[Home, float]] = {}

    def update(self, msg: MavMessage) -> None:
        """Note a HOME_POSITION or a GLOBAL_POSITION_INT (other messages are ignored)."""
        kind = msg.get_type()
        if kind not in self.MESSAGE_TYPES or msg.get_srcComponent() != _AUTOPILOT_COMPONENT:
            return
        system_id, now_s = msg.get_srcSystem(), time.monotonic()
        if kind == "HOME_POSITION":
            home = _home(msg.latitude, msg.longitude, msg.altitude)
            if home is not None:
                with self._lock:
                    self._homes[system_id] = (home, now_s)
            return
        fix = _home(msg.lat, msg.lon, msg.alt)
        with self._lock:
            if fix is None:
                self._fixes.pop(system_id, None)
            else:
                first = self._fixes.get(system_id, (fix, now_s))[0]
                self._fixes[system_id] = (first, now_s)

    def home(self, system_id: int, since_s: float = -math.inf) -> Home | None:
        """The vehicle's HOME_POSITION heard at or after ``since_s`` (``time.monotonic()``), or None."""
        with self._lock:
            home, heard_s = self._homes.get(system_id, (None, -math.inf))
        return home if heard_s >= since_s else None

    def first_fix(self, system_id: int, since_s: float = -math.inf) -> Home | None:
        """Where the vehicle was at its first fix, when it still reported a fix at or after ``since_s``."""
        with self._lock:
            fix, heard_s = self._fixes.get(system_id, (None, -math.inf))
        return fix if heard_s >= since_s else None


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
