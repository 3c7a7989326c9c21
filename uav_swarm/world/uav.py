"""Kinematics of K UAVs flying at a fixed altitude over a rectangular area (pure numpy).

Each UAV is a point with a horizontal position and velocity. A step takes a commanded
velocity per UAV, caps its speed at ``max_speed_m_s``, changes the current velocity by at
most ``max_accel_m_s2 * dt_s``, integrates the position and clamps it to the area (the
velocity component pushing out of the area is zeroed). The waypoint controller turns
targets into velocity commands that brake on arrival (``v = sqrt(2 a d)``), so a UAV
stops on its target instead of oscillating around it.

The step (:func:`fly_step`) and the controller (:func:`waypoint_velocity`) are written once for
any leading batch shape ``(..., K, 2)``; :class:`UAVFleet` is one fleet of them. Separation
(``min_separation_m`` and the altitude layers ``layer_step_m``) is kept by
:mod:`uav_swarm.world.separation`, which every planner and flight passes through.

Examples:
    >>> import numpy as np
    >>> fleet = UAVFleet(np.array([[0.0, 0.0]]), UAVConfig(), width_m=100.0, height_m=100.0)
    >>> for _ in range(300):
    ...     fleet.step(fleet.waypoint_command(np.array([[50.0, 20.0]]), 0.1), dt_s=0.1)
    >>> np.round(fleet.positions_m, 2).tolist()
    [[50.0, 20.0]]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from typed_config import Config, param

__all__ = ["UAVConfig", "UAVFleet", "fly_step", "waypoint_velocity"]


@dataclass(frozen=True)
class UAVConfig(Config):
    """Flight limits of the UAVs."""

    alt_m: float = param(10.0, ge=0.0, le=500.0, doc="fixed flight altitude above the ground (m)")
    max_speed_m_s: float = param(10.0, gt=0.0, le=100.0, doc="horizontal speed cap (m/s)")
    max_accel_m_s2: float = param(5.0, gt=0.0, le=100.0, doc="horizontal acceleration cap (m/s^2)")
    min_separation_m: float = param(
        5.0, ge=0.0, le=1000.0,
        doc="minimum distance (m) between any two UAVs that no plan or flight may violate (0: none)")
    layer_step_m: float = param(
        0.0, ge=0.0, le=100.0,
        doc="altitude step (m) between UAVs: UAV k flies at alt_m + k * layer_step_m (0: one layer)")

    def altitudes_m(self, n_uavs: int) -> np.ndarray:
        """(K,) flight altitude of each UAV: ``alt_m + k * layer_step_m``."""
        return self.alt_m + self.layer_step_m * np.arange(n_uavs, dtype=np.float64)


class UAVFleet:
    """Positions and velocities of K UAVs, stepped by velocity commands.

    Args:
        positions_m: (K, 2) initial positions in metres (clamped to the area).
        config: The flight limits.
        width_m: Area width (x extent) in metres.
        height_m: Area height (y extent) in metres.
    """

    def __init__(self, positions_m: np.ndarray, config: UAVConfig, width_m: float, height_m: float) -> None:
        positions_m = np.asarray(positions_m, dtype=np.float64)
        if positions_m.ndim != 2 or positions_m.shape[1] != 2:
            raise ValueError(f"positions_m must have shape (K, 2), got {positions_m.shape}")
        self.config = config
        self._upper_m = np.array([width_m, height_m], dtype=np.float64)
        self.positions_m = np.clip(positions_m, 0.0, self._upper_m)
        self.velocities_m_s = np.zeros_like(self.positions_m)

    @property
    def n_uavs(self) -> int:
        """Number of UAVs K."""
        return self.positions_m.shape[0]

    def step(self, command_m_s: np.ndarray, dt_s: float) -> None:
        """Fly every UAV for ``dt_s`` seconds toward its commanded velocity (:func:`fly_step`).

        Args:
            command_m_s: (K, 2) commanded horizontal velocities (m/s); speeds above the cap are scaled down.
            dt_s: Time step in seconds.
        """
        self.positions_m, self.velocities_m_s = fly_step(
            self.positions_m, self.velocities_m_s, command_m_s, dt_s, self.config, self._upper_m)

    def waypoint_command(self, targets_m: np.ndarray, dt_s: float) -> np.ndarray:
        """(K, 2) velocity commands (m/s) that fly each UAV to its target (:func:`waypoint_velocity`)."""
        return waypoint_velocity(self.positions_m, targets_m, dt_s, self.config)


def fly_step(positions_m: np.ndarray, velocities_m_s: np.ndarray, command_m_s: np.ndarray, dt_s: float,
             config: UAVConfig, upper_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One kinematic step of UAVs of any batch shape ``(..., K, 2)``; new arrays, inputs unchanged.

    The commanded speed is capped at ``max_speed_m_s``, the change of velocity at
    ``max_accel_m_s2 * dt_s``; the position is integrated and clamped to ``[0, upper_m]`` (the
    velocity component that pushed out of the area is zeroed).

    Args:
        positions_m: (..., K, 2) positions in metres.
        velocities_m_s: (..., K, 2) velocities in m/s.
        command_m_s: (..., K, 2) commanded velocities in m/s.
        dt_s: Time step in seconds.
        config: The flight limits.
        upper_m: (2,) the area's upper corner (width_m, height_m); the lower corner is the origin.

    Returns:
        The positions and velocities after the step.

    Examples:
        >>> p, v = fly_step(np.zeros((1, 2)), np.zeros((1, 2)), np.array([[100.0, 0.0]]), 1.0,
        ...                 UAVConfig(), np.array([100.0, 100.0]))
        >>> p.tolist(), v.tolist()  # the acceleration cap: 5 m/s after 1 s
        ([[5.0, 0.0]], [[5.0, 0.0]])
    """
    desired = _cap_norm(np.asarray(command_m_s, dtype=np.float64), config.max_speed_m_s)
    delta = _cap_norm(desired - velocities_m_s, config.max_accel_m_s2 * dt_s)
    velocities = velocities_m_s + delta
    positions = positions_m + velocities * dt_s
    clamped = np.clip(positions, 0.0, upper_m)
    velocities[clamped != positions] = 0.0  # stopped by the border
    return clamped, velocities


def waypoint_velocity(positions_m: np.ndarray, targets_m: np.ndarray, dt_s: float,
                      config: UAVConfig) -> np.ndarray:
    """Velocity commands that fly each UAV to its target and brake to a stop on it.

    The speed is ``min(max_speed, sqrt(2 * max_accel * d), d / dt_s)``: the fastest speed
    from which the UAV can still stop within the remaining distance ``d``, and never
    more than reaches the target in one step.

    Args:
        positions_m: (..., K, 2) positions in metres.
        targets_m: (..., K, 2) target positions in metres.
        dt_s: The time step the command will be applied for (s).
        config: The flight limits.

    Returns:
        (..., K, 2) velocity commands in m/s.
    """
    offset = np.asarray(targets_m, dtype=np.float64) - positions_m
    dist = np.sqrt(np.einsum("...c,...c->...", offset, offset))
    speed = np.minimum(np.minimum(config.max_speed_m_s, dist / dt_s),
                       np.sqrt(2.0 * config.max_accel_m_s2 * dist))
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(dist > 1e-9, speed / dist, 0.0)
    return offset * scale[..., None]


def _cap_norm(vectors: np.ndarray, cap: float) -> np.ndarray:
    """Scale down the vectors (last axis of size 2) whose norm exceeds ``cap`` (a new array)."""
    norm = np.hypot(vectors[..., 0], vectors[..., 1])
    return vectors * (cap / np.maximum(norm, cap))[..., None]
