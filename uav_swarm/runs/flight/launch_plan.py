"""Where the vehicles of a flight take off, in which order they climb, and the altitudes they return at.

**Launch positions** (``[launch] positions``): ``"homes"`` takes each vehicle's own home (its
HOME_POSITION, in the flight's East-North frame); ``"grid"`` says where the operator put them: vehicle
``k`` (the bridge config's order) stands at ``grid_origin + (k mod grid_columns, k div grid_columns)
* grid_spacing_m``, and a vehicle whose home is farther than ``grid_tolerance_m`` from its slot is
refused. A grid closer than ``uav.min_separation_m`` is refused with the config (nothing flies);
homes closer than it are refused before any vehicle is armed (:func:`check_launch_positions`).

**Take-off**: one number from the guard's proof, the launch spacing
(:func:`uav_swarm.world.guard.failsafe.launch_spacing_m`: the minimum plus the guard's margin plus twice
the tracking and position errors, 8 m with the defaults), decides how vehicles climb. Vehicles whose homes
are at least that far apart arm, take off and climb together, each in its own column; a vehicle whose
home is closer to another's climbs only while no such neighbour is climbing (staggered, one column at a
time; :class:`TakeoffGate`), and only when no airborne vehicle is within the launch spacing of its home.
The guard (:mod:`uav_swarm.runs.flight.guard`) keeps flying vehicles off a climbing one and off one
waiting to climb (two discs the minimum and its margin apart: farther than the launch spacing), so a
column clears. The pre-flight check names the number when it refuses homes closer than the minimum.

**Return**: every vehicle's return altitude is its own layer (:func:`return_altitudes_m`), above
every cruise altitude and ``max(min_separation_m + [guard] margin_m, layer_step_m)`` apart, so that vehicles
returning together (the end of the flight, or their link-loss failsafe) fly home at different
heights; the autopilots climb to it where they are (the guard kept them apart there) and fly home.

Examples:
    >>> from uav_swarm.world.uav import UAVConfig
    >>> return_altitudes_m(3, UAVConfig(alt_m=10.0, min_separation_m=5.0), margin_m=1.0).tolist()
    [16.0, 22.0, 28.0]
    >>> grid_slots_m(LaunchConfig(positions="grid", grid_spacing_m=8.0, grid_columns=2), 3)
    [(0.0, 0.0), (8.0, 0.0), (0.0, 8.0)]
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass
from typing import Literal

import numpy as np

from bridge.flight.guided import FlightError
from bridge.flight.preflight import PreflightError
from typed_config import Config, ConfigError, param
from uav_swarm.world.uav import UAVConfig

__all__ = ["LaunchConfig", "TakeoffGate", "check_launch_grid", "check_launch_positions", "grid_slots_m",
           "return_altitudes_m"]

_POLL_S = 0.05


@dataclass(frozen=True)
class LaunchConfig(Config):
    """Where the vehicles take off (``[launch]``)."""

    positions: Literal["homes", "grid"] = param(
        "homes", doc="'homes': each vehicle's own home; 'grid': the grid below, each home checked against it")
    grid_origin_x_m: float = param(0.0, ge=-10000.0, le=10000.0, doc="grid slot 0, metres East of [home]")
    grid_origin_y_m: float = param(0.0, ge=-10000.0, le=10000.0, doc="grid slot 0, metres North of [home]")
    grid_spacing_m: float = param(10.0, ge=0.0, le=1000.0, doc="distance between neighbouring slots, metres")
    grid_columns: int = param(5, ge=1, le=10, doc="slots per row (East), rows going North")
    grid_tolerance_m: float = param(3.0, gt=0.0, le=100.0,
                                    doc="a vehicle's home may be this far from its slot, metres")


def check_launch_grid(launch: LaunchConfig, uav: UAVConfig, n_vehicles: int) -> None:
    """Refuse a launch grid whose neighbours are closer than ``uav.min_separation_m`` (naming the field).

    Raises:
        ConfigError: ``launch.grid_spacing_m`` below the minimum for a grid of two or more vehicles.
    """
    if launch.positions == "grid" and n_vehicles >= 2 and launch.grid_spacing_m < uav.min_separation_m:
        raise ConfigError(
            f"launch.grid_spacing_m = {launch.grid_spacing_m:g} m: the vehicles would take off closer than "
            f"uav.min_separation_m = {uav.min_separation_m:g} m; allowed launch.grid_spacing_m >= "
            f"{uav.min_separation_m:g}")


def grid_slots_m(launch: LaunchConfig, n_vehicles: int) -> list[tuple[float, float]]:
    """(x, y) of each vehicle's grid slot, in the bridge config's order."""
    step, cols = launch.grid_spacing_m, launch.grid_columns
    return [(launch.grid_origin_x_m + (k % cols) * step, launch.grid_origin_y_m + (k // cols) * step)
            for k in range(n_vehicles)]


def check_launch_positions(homes_m: Mapping[int, tuple[float, float]], min_separation_m: float,
                           launch: LaunchConfig,
                           slots_m: Mapping[int, tuple[float, float]] | None = None,
                           spacing_m: float | None = None) -> None:
    """Refuse take-off positions closer than the minimum, or (grid) a home away from its slot.

    Args:
        homes_m: Each vehicle's home (x, y) by system id.
        min_separation_m: ``uav.min_separation_m``.
        launch: The launch settings.
        slots_m: With a grid, each vehicle's slot by system id.
        spacing_m: The launch spacing (named in the refusal; homes closer than it climb one at a time).

    Raises:
        PreflightError: Naming the vehicles, their positions and the field.
    """
    if launch.positions == "grid" and slots_m is not None:
        for sid, home in homes_m.items():
            slot = slots_m[sid]
            off_m = math.dist(home, slot)
            if off_m > launch.grid_tolerance_m:
                raise PreflightError(sid, f"its home ({home[0]:.1f}, {home[1]:.1f}) m is {off_m:.1f} m from "
                                          f"its launch grid slot ({slot[0]:.1f}, {slot[1]:.1f}) m; allowed "
                                          f"launch.grid_tolerance_m = {launch.grid_tolerance_m:g} m. Nothing "
                                          "was armed")
    ids = sorted(homes_m)
    for a, first in enumerate(ids):
        for second in ids[a + 1:]:
            gap_m = math.dist(homes_m[first], homes_m[second])
            if gap_m < min_separation_m:
                together = "" if spacing_m is None else (
                    f"; homes at least {spacing_m:g} m apart (the launch spacing: the minimum, the guard's "
                    "margin and twice its tracking and position errors) climb together, closer ones one at "
                    "a time")
                raise PreflightError(first, f"it and vehicle {second} would take off {gap_m:.1f} m apart "
                                            "(their homes), closer than uav.min_separation_m = "
                                            f"{min_separation_m:g} m. Nothing was armed: place them farther "
                                            f"apart{together}")


def return_altitudes_m(n_vehicles: int, uav: UAVConfig, margin_m: float = 0.0) -> np.ndarray:
    """(n,) return altitudes: above every cruise layer, ``max(min_sep + margin_m, layer_step)`` apart."""
    step = max(uav.min_separation_m + margin_m, uav.layer_step_m)
    top = float(uav.altitudes_m(n_vehicles).max()) if n_vehicles else uav.alt_m
    return top + step * np.arange(1, n_vehicles + 1, dtype=np.float64)


class TakeoffGate:
    """Take-offs from clear columns (module docstring), staggered where homes are closer than the spacing.

    Each climbs once no airborne vehicle is near its home and no vehicle closer than the launch spacing
    is climbing.

    Args:
        cancel: Set when the flight ends: a vehicle waiting for its turn gives up.
        column_clear: ``column_clear(system_id)``: True when no airborne vehicle is within the minimum
            of where this one climbs.
        near: ``near(system_id)``: the vehicles whose homes are closer to its home than the launch spacing.

    Examples:
        >>> import threading
        >>> gate = TakeoffGate(threading.Event(), lambda sid: True, near=lambda sid: {1: [2], 2: [1]}[sid])
        >>> with gate.for_vehicle(1)():
        ...     sorted(gate.climbing), gate.may_climb(2)  # 2 waits while its neighbour climbs
        ([1], False)
        >>> gate.may_climb(2)
        True
    """

    def __init__(self, cancel: threading.Event, column_clear: Callable[[int], bool],
                 near: Callable[[int], Iterable[int]] = lambda sid: ()) -> None:
        self._cancel = cancel
        self._column_clear = column_clear
        self._near = near
        self._lock = threading.Lock()
        self.waiting: set[int] = set()
        """System ids waiting for their column to clear."""
        self.climbing: set[int] = set()
        """System ids arming, taking off or climbing (inside the gate)."""
        self.climbs: list[tuple[int, float, float]] = []
        """``(system_id, start, end)`` of each climb (monotonic seconds), for the record."""

    def may_climb(self, system_id: int) -> bool:
        """Whether it may climb now: no neighbour climbing, none ranked before it waiting, its column clear.

        Neighbours are the vehicles closer than the launch spacing; one with fewer neighbours (then a lower
        id) goes first: the ends of a line climb first, so a vehicle up first has few columns to clear.
        """
        near = set(self._near(system_id))
        rank = (len(near), system_id)
        first = [n for n in near & self.waiting if (len(set(self._near(n))), n) < rank]
        return not (near & self.climbing) and not first and self._column_clear(system_id)

    def for_vehicle(self, system_id: int) -> Callable[[], contextlib.AbstractContextManager[None]]:
        """The gate of one vehicle, as :func:`bridge.flight.guided.launch` takes it."""
        return lambda: self._slot(system_id)

    def _claim(self, system_id: int) -> bool:
        with self._lock:  # the check and the claim at once: two neighbours never both start
            if not self.may_climb(system_id):
                return False
            self.climbing.add(system_id)
            return True

    @contextlib.contextmanager
    def _slot(self, system_id: int) -> Iterator[None]:
        self.waiting.add(system_id)
        try:
            while not self._claim(system_id):
                if self._cancel.wait(_POLL_S):
                    raise FlightError(system_id, "launch cancelled (the flight is ending)")
        finally:
            self.waiting.discard(system_id)
        start_s = time.monotonic()
        try:
            yield
        finally:
            with self._lock:
                self.climbing.discard(system_id)
                self.climbs.append((system_id, start_s, time.monotonic()))
