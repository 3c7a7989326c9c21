"""Failsafe flights and the launch: what vehicles do on their own, separated by construction.

**A failsafe flight.** A vehicle that loses its ground station (or is sent RTL) flies by itself: it
climbs where it is to its own return layer, flies straight home at that layer and descends over its home
(ArduCopter ``RTL`` with ``RTL_CONE_SLOPE = 0``, PX4 ``AUTO.RTL`` with ``RTL_CONE_ANG = 0``, ``RTL_TYPE = 0``;
the pre-flight check sets and reads these back). Where it starts is known only as a disc (its certified
disc, :mod:`uav_swarm.world.guard`), its home as a disc of the position and tracking errors. So its flight
occupies three volumes (:class:`FailsafeFlight`): the **climb column** over its start disc (from where it
is up to its layer), the **way**, a capsule from its start disc to its home at its layer, and the **descent
column** over its home (from its layer to the ground). When it starts is unknown.

**Theorem (failsafes apart whatever their times).** Let every return layer be above every cruise
altitude, two layers at least ``need_m`` apart vertically, and every vertical gap below ``need_m`` be
closed horizontally. Two failsafe flights ``a`` (lower layer) and ``b`` keep ``need_m`` whatever their
start times if (:func:`flights_apart`):

1. ``a``'s way keeps ``need_m`` horizontally from ``b``'s climb column and from ``b``'s descent column
   (``b`` passes through ``a``'s layer in both);
2. ``a``'s climb column keeps it from ``b``'s climb column and ``b``'s descent column, and ``a``'s
   descent column from ``b``'s climb column (each pair overlaps in height between the cruise altitudes
   and ``a``'s layer);
3. the homes keep it (the launch rule below keeps them farther apart).

*Proof.* At any instant each vehicle is in one of its three volumes. ``b``'s way lies at ``b``'s layer,
at least ``need_m`` above everything of ``a`` (``a`` never flies above its own layer). Every other pair of
volumes of ``a`` and ``b`` is listed in 1-3 and kept ``need_m`` apart horizontally, so the two vehicles
are at least ``need_m`` apart whatever each is doing when. A steered vehicle keeps its disc apart from a
failsafe vehicle's disc and home column (the guard's rule); the failsafe's way, above every cruise
altitude, is ``need_m`` above it. Hence any subset of failsafes, started at any times, keeps the minimum.

**Return layers by crossing order** (:func:`crossing_order`): condition 1 fixes which of two vehicles
must fly higher: one whose way passes over the other's climb or descent column flies above it. These
relations are ordered (a topological order, ties by the given order); a cycle (each way over the other's
column) or a pair failing condition 2 has no order: such a vehicle is flown home by the guard and sent
RTL once its flight is apart from every other (:func:`flights_apart`).

**The launch** (:func:`launch_spacing_m`). Vehicles climbing together are not steered: each is within
``e_t`` (tracking) of the column over its true home, known within ``e_p`` (position). Two homes measured
``d`` apart keep ``d - 2 (e_t + e_p)`` while climbing; with the guard's margin this is the least home
spacing for climbing together, ``need_m + 2 (e_t + e_p)``, and the one number the pre-flight check, the
take-off gate and the guard share. Homes closer than ``min_separation_m`` are refused; homes between it
and the launch spacing climb one at a time (a vehicle climbs once no vehicle within the launch spacing of
its home is climbing): a climbing vehicle is a disc the guard keeps the steered ones off.

Examples:
    >>> launch_spacing_m(5.0, margin_m=1.0, tracking_error_m=0.5, position_error_m=0.5)
    8.0
    >>> low = FailsafeFlight((0.0, 0.0), 1.0, (0.0, 40.0), 1.0, layer_m=16.0)
    >>> high = FailsafeFlight((3.0, 20.0), 1.0, (30.0, 20.0), 1.0, layer_m=22.0)  # climbs under low's way
    >>> flights_apart(low, high, need_m=6.0), flights_apart(low.at_layer(28.0), high, need_m=6.0)
    (False, True)
    >>> crossing_order([low, high], need_m=6.0)  # low's way passes over high's climb: low flies higher
    [1, 0]
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from uav_swarm.world.guard.reach import segment_distances_m

__all__ = ["FailsafeFlight", "columns_apart", "crossing_order", "flights_apart", "launch_spacing_m",
           "must_fly_above"]


def launch_spacing_m(min_separation_m: float, *, margin_m: float, tracking_error_m: float,
                     position_error_m: float) -> float:
    """The least home spacing for climbing together: ``min + margin + 2 (e_t + e_p)`` (module docstring)."""
    return min_separation_m + margin_m + 2.0 * (tracking_error_m + position_error_m)


@dataclass(frozen=True)
class FailsafeFlight:
    """One vehicle's failsafe flight: climb over ``start_m`` (a disc), fly home at ``layer_m``, descend.

    Attributes:
        start_m: (x, y) centre of where it may start to climb, metres.
        start_radius_m: Radius of that disc (its certified disc, or its position's errors), metres.
        home_m: (x, y) of its home.
        home_radius_m: How far from ``home_m`` it descends (position and tracking errors), metres.
        layer_m: Its return altitude above home, metres.
    """

    start_m: tuple[float, float]
    start_radius_m: float
    home_m: tuple[float, float]
    home_radius_m: float
    layer_m: float = 0.0

    def at_layer(self, layer_m: float) -> FailsafeFlight:
        """The same flight at another return layer."""
        return replace(self, layer_m=layer_m)


def _way_gap_m(way: FailsafeFlight, centre_m: tuple[float, float], radius_m: float) -> float:
    """Horizontal gap between ``way``'s capsule (start disc to home) and a disc."""
    point = np.asarray(centre_m, dtype=np.float64)
    distance = float(segment_distances_m(point, point, np.asarray(way.start_m, dtype=np.float64),
                                         np.asarray(way.home_m, dtype=np.float64)))
    return distance - max(way.start_radius_m, way.home_radius_m) - radius_m


def _disc_gap_m(a: tuple[float, float], ra: float, b: tuple[float, float], rb: float) -> float:
    return float(np.hypot(a[0] - b[0], a[1] - b[1])) - ra - rb


def must_fly_above(a: FailsafeFlight, b: FailsafeFlight, need_m: float) -> bool:
    """Whether ``a``'s way passes within ``need_m`` of ``b``'s climb or descent column (a flies higher)."""
    return (_way_gap_m(a, b.start_m, b.start_radius_m) < need_m
            or _way_gap_m(a, b.home_m, b.home_radius_m) < need_m)


def columns_apart(a: FailsafeFlight, b: FailsafeFlight, need_m: float) -> bool:
    """Condition 2 and 3: climb and descent columns of ``a`` and ``b`` keep ``need_m`` horizontally."""
    return (_disc_gap_m(a.start_m, a.start_radius_m, b.start_m, b.start_radius_m) >= need_m
            and _disc_gap_m(a.start_m, a.start_radius_m, b.home_m, b.home_radius_m) >= need_m
            and _disc_gap_m(a.home_m, a.home_radius_m, b.start_m, b.start_radius_m) >= need_m
            and _disc_gap_m(a.home_m, a.home_radius_m, b.home_m, b.home_radius_m) >= need_m)


def flights_apart(a: FailsafeFlight, b: FailsafeFlight, need_m: float) -> bool:
    """Whether two failsafe flights keep ``need_m`` whatever their start times (the theorem's 1-3)."""
    if abs(a.layer_m - b.layer_m) < need_m:
        return False
    low, high = (a, b) if a.layer_m < b.layer_m else (b, a)
    return columns_apart(low, high, need_m) and not must_fly_above(low, high, need_m)


def crossing_order(flights: Sequence[FailsafeFlight], need_m: float) -> list[int] | None:
    """Indices of ``flights`` from the lowest return layer to the highest (None: a cycle, no order).

    ``i`` comes after ``j`` when ``i``'s way passes over ``j``'s columns (:func:`must_fly_above`); among
    those free to go next, the lowest index first. Pairs whose columns are too close (condition 2) are
    not ordered here: :func:`flights_apart` refuses them whatever their layers.
    """
    n = len(flights)
    above = [[i != j and must_fly_above(flights[i], flights[j], need_m) for j in range(n)] for i in range(n)]
    below_count = [sum(above[i]) for i in range(n)]  # how many each must be above
    order: list[int] = []
    free = [i for i in range(n) if below_count[i] == 0]
    while free:
        j = min(free)
        free.remove(j)
        order.append(j)
        for i in range(n):
            if above[i][j]:
                below_count[i] -= 1
                if below_count[i] == 0:
                    free.append(i)
    return order if len(order) == n else None
