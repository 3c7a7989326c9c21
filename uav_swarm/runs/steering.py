"""Operator targets: a person (or a ROS 2 node) overrides the planner for the UAVs it names.

:class:`OperatorTargets` holds the accepted targets by UAV id; the loops of ``simulate`` and ``fly``
fly them instead of the planner's for those UAVs until the operator hands the UAV back
(:meth:`OperatorTargets.release`). A target is validated like every other input before it is
accepted: frame ``map`` (East-North-Up metres from the run's home), finite values, inside the area and
the geofence at the UAV's altitude, and far enough from every other UAV's target (the operator's and the
planner's latest): ``min_separation_m`` apart, less between two altitude layers
(:func:`uav_swarm.world.separation.required_distances_m`). A refused target changes nothing; the reason
is returned for the caller to log and publish. Each UAV flies at its own altitude
(:meth:`uav_swarm.world.uav.UAVConfig.altitudes_m`): an operator target sets where, not how high.

It is filled from another thread (the ROS 2 executor) and read by the loop: every method takes a lock.

Examples:
    >>> from uav_swarm.world.uav import UAVConfig
    >>> targets = OperatorTargets(width_m=100.0, height_m=80.0, uav=UAVConfig(min_separation_m=5.0), n_uavs=3)
    >>> targets.planned({0: (10.0, 10.0), 1: (50.0, 40.0), 2: (90.0, 70.0)})
    >>> targets.offer(0, "map", 20.0, 20.0, 10.0)
    >>> targets.offer(2, "map", 21.0, 22.0, 10.0)
    "target (21.00, 22.00) is 2.24 m from UAV 0's target: allowed at least 5 m (uav.min_separation_m = 5 m)"
    >>> targets.apply({0: (10.0, 10.0), 1: (50.0, 40.0), 2: (90.0, 70.0)})
    {0: (20.0, 20.0), 1: (50.0, 40.0), 2: (90.0, 70.0)}
    >>> targets.release(0), targets.held()
    (True, {})
"""

from __future__ import annotations

import math
import threading
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from uav_swarm.planning.spacing import separate_targets
from uav_swarm.world.separation import required_distances_m

if TYPE_CHECKING:
    from bridge.geofence import GeofenceConfig
    from uav_swarm.world.uav import UAVConfig

__all__ = ["OperatorTargets", "TARGET_FRAME"]

TARGET_FRAME = "map"
"""The one frame operator targets are given in (REP 105: the run's fixed East-North-Up frame)."""

XY = tuple[float, float]


class OperatorTargets:
    """The operator's accepted targets by UAV id, validated on arrival (see the module docstring).

    Args:
        width_m: East extent of the area (metres from the home).
        height_m: North extent of the area.
        uav: The UAVs' altitudes (checked against the geofence with the target) and separation.
        n_uavs: UAV ids are ``0 .. n_uavs - 1``.
        geofence: The bridge's geofence, or None (the area alone).
    """

    def __init__(self, *, width_m: float, height_m: float, uav: UAVConfig, n_uavs: int,
                 geofence: GeofenceConfig | None = None) -> None:
        self.width_m, self.height_m = float(width_m), float(height_m)
        self.min_separation_m = float(uav.min_separation_m)
        self.n_uavs = int(n_uavs)
        self.altitudes_m = uav.altitudes_m(self.n_uavs)
        self._required_m = required_distances_m(self.min_separation_m,
                                                self.altitudes_m if uav.layer_step_m else None, self.n_uavs)
        self.geofence = geofence
        self._held: dict[int, XY] = {}
        self._planned: dict[int, XY] = {}
        self._lock = threading.Lock()
        self.version = 0
        """Counts accepted targets and releases: a loop that saw another value sends targets again."""

    def planned(self, targets_m: Mapping[int, XY]) -> None:
        """The planner's latest targets by UAV id (what an operator target must keep its distance from)."""
        with self._lock:
            self._planned = {int(k): (float(v[0]), float(v[1])) for k, v in targets_m.items()}

    def offer(self, uav_id: int, frame_id: str, x_m: float, y_m: float, z_m: float) -> str | None:
        """Accept a target for ``uav_id`` (None) or refuse it (the reason, naming the rule)."""
        reason = self._check(uav_id, frame_id, x_m, y_m, z_m)
        if reason is None:
            with self._lock:
                self._held[uav_id] = (float(x_m), float(y_m))
                self.version += 1
        return reason

    def release(self, uav_id: int) -> bool:
        """Hand ``uav_id`` back to the planner; False when the operator held no target for it."""
        with self._lock:
            held = self._held.pop(uav_id, None) is not None
            if held:
                self.version += 1
        return held

    def held(self) -> dict[int, XY]:
        """The operator's targets by UAV id (a copy)."""
        with self._lock:
            return dict(self._held)

    def apply(self, targets_m: Mapping[int, XY]) -> dict[int, XY]:
        """``targets_m`` (by UAV id) with the operator's targets in place of the planner's.

        The operator's targets stay reserved: another UAV's target closer than ``min_separation_m`` to one
        is moved the least distance that keeps it (:func:`uav_swarm.planning.spacing.separate_targets`,
        the operator's targets placed first and never moved).
        """
        ids = list(targets_m)
        held = {uav_id: xy for uav_id, xy in self.held().items() if uav_id in targets_m}
        if not held:
            return dict(targets_m)
        out = np.array([held.get(uav_id, targets_m[uav_id]) for uav_id in ids], dtype=np.float64)
        first = [ids.index(uav_id) for uav_id in sorted(held)]
        order = np.array(first + [k for k in range(len(ids)) if k not in first], dtype=np.int64)
        out = separate_targets(out, self.min_separation_m, order, np.array([self.width_m, self.height_m]),
                               keep=len(held))
        return {uav_id: (float(x), float(y)) for uav_id, (x, y) in zip(ids, out, strict=True)}

    def apply_array(self, targets_m: np.ndarray) -> np.ndarray:
        """``(n, 2)`` targets of UAVs ``0 .. n - 1`` by :meth:`apply` (a copy if any is held)."""
        if not any(uav_id < len(targets_m) for uav_id in self.held()):
            return targets_m
        steered = self.apply({k: (float(x), float(y)) for k, (x, y) in enumerate(np.asarray(targets_m))})
        return np.array([steered[k] for k in range(len(targets_m))], dtype=np.float64)

    def _check(self, uav_id: int, frame_id: str, x_m: float, y_m: float, z_m: float) -> str | None:
        if not 0 <= uav_id < self.n_uavs:
            return f"UAV {uav_id} is not in this run: allowed 0..{self.n_uavs - 1}"
        if frame_id != TARGET_FRAME:
            return f"frame_id = {frame_id!r}: give targets in {TARGET_FRAME!r} (ENU metres from the home)"
        if not all(math.isfinite(v) for v in (x_m, y_m, z_m)):
            return f"target ({x_m}, {y_m}, {z_m}) is not finite"
        if self.geofence is not None:
            from bridge.errors import GeofenceError
            from bridge.geofence import check_geofence

            try:
                check_geofence([(x_m, y_m, float(self.altitudes_m[uav_id]))], self.geofence,
                               labels=[f"target at UAV {uav_id}'s altitude"])
            except GeofenceError as exc:
                return str(exc)
        if not (0.0 <= x_m <= self.width_m and 0.0 <= y_m <= self.height_m):
            return (f"target ({x_m:.2f}, {y_m:.2f}) is outside the area: allowed 0 <= x_m <= "
                    f"{self.width_m:g}, 0 <= y_m <= {self.height_m:g}")
        with self._lock:
            others = {**self._planned, **self._held}
        for other, (ox, oy) in sorted(others.items()):
            distance_m = math.hypot(x_m - ox, y_m - oy)
            if other != uav_id and other < self.n_uavs and distance_m < self._required_m[uav_id, other]:
                return (f"target ({x_m:.2f}, {y_m:.2f}) is {distance_m:.2f} m from UAV {other}'s target: "
                        f"allowed at least {self._required_m[uav_id, other]:g} m (uav.min_separation_m = "
                        f"{self.min_separation_m:g} m)")
        return None
