"""Kinematics of K UAVs flying at a fixed altitude over a rectangular area (pure numpy).

Each UAV is a point with a horizontal position and velocity. A step takes a commanded
velocity per UAV, caps its speed at ``max_speed_m_s``, changes the current velocity by at
most ``max_accel_m_s2 * dt_s``, integrates the position and clamps it to the area (the
velocity component pushing out of the area is zeroed). The waypoint controller turns
targets into velocity commands that brake on arrival (``v = sqrt(2 a d)``), so a UAV
stops on its target instead of oscillating around it.

Separation is not enforced physically; :func:`separation_penalty` measures how much
pairs of UAVs intrude into each other's ``min_separation_m`` so a reward can penalise it.

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

__all__ = ["UAVConfig", "UAVFleet", "fly_step", "separation_penalty", "waypoint_velocity"]


@dataclass(frozen=True)
class UAVConfig(Config):
    """Flight limits of the UAVs."""

    alt_m: float = param(10.0, ge=0.0, le=500.0, doc="fixed flight altitude above the ground (m)")
    max_speed_m_s: float = param(10.0, gt=0.0, le=100.0, doc="horizontal speed cap (m/s)")
    max_accel_m_s2: float = param(5.0, gt=0.0, le=100.0, doc="horizontal acceleration cap (m/s^2)")
    min_separation_m: float = param(5.0, ge=0.0, le=1000.0,
                                    doc="distance (m) under which a pair of UAVs is penalised")


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
        """Fly every UAV for ``dt_s`` seconds toward its commanded velocity.

        Args:
            command_m_s: (K, 2) commanded horizontal velocities (m/s); speeds above the cap are scaled down.
            dt_s: Time step in seconds.
        """
        cfg = self.config
        desired = _cap_norm(np.asarray(command_m_s, dtype=np.float64), cfg.max_speed_m_s)
        delta = _cap_norm(desired - self.velocities_m_s, cfg.max_accel_m_s2 * dt_s)
        velocities = self.velocities_m_s + delta
        positions = self.positions_m + velocities * dt_s
        clamped = np.clip(positions, 0.0, self._upper_m)
        velocities[clamped != positions] = 0.0  # stopped by the border
        self.positions_m = clamped
        self.velocities_m_s = velocities

    def waypoint_command(self, targets_m: np.ndarray, dt_s: float) -> np.ndarray:
        """Velocity commands that fly each UAV to its target and brake to a stop on it.

        The speed is ``min(max_speed, sqrt(2 * max_accel * d), d / dt_s)``: the fastest speed
        from which the UAV can still stop within the remaining distance ``d``, and never
        more than reaches the target in one step.

        Args:
            targets_m: (K, 2) target positions in metres.
            dt_s: The time step the command will be applied for (s).

        Returns:
            (K, 2) velocity commands in m/s.
        """
        offset = np.asarray(targets_m, dtype=np.float64) - self.positions_m
        dist = np.sqrt(np.einsum("kc,kc->k", offset, offset))
        speed = np.minimum(np.minimum(self.config.max_speed_m_s, dist / dt_s),
                           np.sqrt(2.0 * self.config.max_accel_m_s2 * dist))
        with np.errstate(invalid="ignore", divide="ignore"):
            scale = np.where(dist > 1e-9, speed / dist, 0.0)
        return offset * scale[:, None]


def _cap_norm(vectors: np.ndarray, cap: float) -> np.ndarray:
    """Scale down the vectors (last axis, 2) whose norm exceeds ``cap`` (a new array)."""
    norm = np.hypot(vectors[..., 0], vectors[..., 1])
    return vectors * (cap / np.maximum(norm, cap))[..., None]


def fly_step(positions_m: np.ndarray, velocities_m_s: np.ndarray, command_m_s: np.ndarray, dt_s: float,
             config: UAVConfig, upper_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One kinematic step of (..., K, 2) UAVs: new positions and velocities (new arrays)."""
    desired = _cap_norm(np.asarray(command_m_s, dtype=np.float64), config.max_speed_m_s)
    delta = _cap_norm(desired - velocities_m_s, config.max_accel_m_s2 * dt_s)
    velocities = velocities_m_s + delta
    positions = positions_m + velocities * dt_s
    clamped = np.clip(positions, 0.0, upper_m)
    velocities[clamped != positions] = 0.0  # stopped by the border
    return clamped, velocities


def waypoint_velocity(positions_m: np.ndarray, targets_m: np.ndarray, dt_s: float, config: UAVConfig
                      ) -> np.ndarray:
    """(..., K, 2) velocity commands that fly to the targets and brake to a stop on them."""
    offset = np.asarray(targets_m, dtype=np.float64) - positions_m
    dist = np.sqrt(np.einsum("...c,...c->...", offset, offset))
    speed = np.minimum(np.minimum(config.max_speed_m_s, dist / dt_s), np.sqrt(2.0 * config.max_accel_m_s2 * dist))
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(dist > 1e-9, speed / dist, 0.0)
    return offset * scale[..., None]


def separation_penalty(positions_m: np.ndarray, min_separation_m: float) -> float:
    """Total intrusion of UAV pairs closer than ``min_separation_m``.

    Each pair at distance ``d < min_separation_m`` adds ``1 - d / min_separation_m``
    (1 when they coincide, 0 at the minimum separation); pairs further apart add 0.

    Args:
        positions_m: (K, 2) UAV positions in metres.
        min_separation_m: The minimum separation (m); 0 disables the penalty.

    Returns:
        The penalty, in ``[0, K (K - 1) / 2]``.
    """
    k = positions_m.shape[0]
    if k < 2 or min_separation_m <= 0:
        return 0.0
    dx = positions_m[:, 0:1] - positions_m[:, 0]  # (K, K), antisymmetric
    dy = positions_m[:, 1:2] - positions_m[:, 1]
    d2 = dx * dx + dy * dy
    close = d2 < min_separation_m**2  # includes the diagonal (d = 0): k entries of 1 - 0 = 1
    if np.count_nonzero(close) == k:
        return 0.0
    intrusion = 1.0 - np.sqrt(d2[close]) / min_separation_m
    return float((intrusion.sum() - k) / 2.0)  # each pair is counted twice
