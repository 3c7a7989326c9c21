"""Jerk-limited autopilots: ArduCopter's and PX4's position controllers as kinematic models.

:class:`~bridge.simulated.dynamics.PointMassCopter` changes its velocity at its acceleration limit at once.
Real position controllers shape a path whose acceleration also changes at a limited rate (jerk), so a
vehicle told to turn back keeps accelerating away for a moment and runs on further than ``|v|^2 / (2 a)``.
These models fly that, with the same interface (``send`` / ``advance`` / ``report``, the same
:class:`~bridge.simulated.dynamics.Realism`: latency, loss, late and noisy reports, wind), written from
the public description of each controller, not copied from it:

- :class:`ArduCopterLikeCopter` (ArduCopter 4.6 ``AC_PosControl::input_pos_xyz``, the kinematic shaping
  of ``shape_pos_vel_accel_xy`` in ``AP_Math/control.cpp``): each control tick a square-root controller on
  the position error (gain ``j / (2 a)``, second-order limit ``a / 2``) gives a velocity demand, capped
  at the speed limit (``WPNAV_SPEED``); a second square-root controller on the velocity error (gain
  ``j / a``, limit ``j``) gives an acceleration demand, capped at ``a`` (``WPNAV_ACCEL``) with at least
  ``a / sqrt(2)`` kept for the component across the velocity demand; the acceleration moves toward that
  demand by at most ``j dt`` (``PSC_JERK_XY``). So ``|acceleration| <= a`` and ``|jerk| <= j`` as vectors.
- :class:`PX4LikeCopter` (PX4 1.15 ``PositionSmoothing`` / ``VelocitySmoothing``): the velocity demand
  points at the target with the speed from which braking with a jerk delay still stops there
  (``v^2 + 4 a^2 v / j = 2 a d``, ``computeMaxSpeedFromDistance``), capped at the cruise speed; each
  horizontal axis then follows its component on its own, with its acceleration within ``+-a``
  (``MPC_ACC_HOR``) and its jerk within ``+-j`` (``MPC_JERK_AUTO``): on a diagonal the acceleration reaches
  ``sqrt(2) a``. (PX4 also stretches the axes' timings to end together; that only slows the shorter
  axis, and is left out.)

Vertically both follow the same laws on one axis (climb and descent rates, ``vertical_accel_m_s2``,
the vertical jerk). The models are the set point the real autopilot's inner loops track; the vehicle is
that set point plus the tracking error of the wind, as in ``PointMassCopter``. The control law runs every
``control_dt_s`` (ArduCopter runs at 400 Hz, PX4 at about 100 Hz; 100 Hz here by default).

Examples:
    >>> import numpy as np
    >>> from bridge.simulated.dynamics import ARDUCOPTER_LIMITS, Realism
    >>> copter = ArduCopterLikeCopter(np.zeros(3), ARDUCOPTER_LIMITS, Realism(), np.random.default_rng(0))
    >>> copter.send(0.0, np.array([30.0, 0.0, 0.0]))
    True
    >>> copter.advance(30.0)
    >>> [round(float(x), 3) for x in copter.position_m]
    [30.0, 0.0, 0.0]
    >>> copter.jerk.jerk_m_s3, float(np.hypot(*copter.velocity_m_s[:2])) < 1e-3
    (5.0, True)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bridge.simulated.dynamics import AutopilotLimits, PointMassCopter, Realism

__all__ = ["ARDUCOPTER_JERK", "PX4_JERK", "ArduCopterLikeCopter", "JerkLimits", "PX4LikeCopter",
           "sqrt_controller"]


@dataclass(frozen=True)
class JerkLimits:
    """How fast a jerk-limited autopilot changes its acceleration, and how often it decides.

    Attributes:
        jerk_m_s3: Horizontal jerk limit (ArduCopter ``PSC_JERK_XY`` 5 m/s^3, PX4 ``MPC_JERK_AUTO`` 4 m/s^3;
            PX4 applies it on each axis).
        vertical_jerk_m_s3: Vertical jerk limit (ArduCopter ``PSC_JERK_Z`` 5 m/s^3, PX4 ``MPC_JERK_AUTO``).
        control_dt_s: The control law's period, seconds.
    """

    jerk_m_s3: float
    vertical_jerk_m_s3: float
    control_dt_s: float = 0.01

    def __post_init__(self) -> None:
        for name in ("jerk_m_s3", "vertical_jerk_m_s3", "control_dt_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be a finite number > 0, got {value!r}")


ARDUCOPTER_JERK = JerkLimits(jerk_m_s3=5.0, vertical_jerk_m_s3=5.0)
"""ArduCopter 4.6's defaults: ``PSC_JERK_XY`` 5, ``PSC_JERK_Z`` 5 (m/s^3)."""
PX4_JERK = JerkLimits(jerk_m_s3=4.0, vertical_jerk_m_s3=4.0)
"""PX4 1.15's default ``MPC_JERK_AUTO`` 4 m/s^3 (on each axis)."""


def sqrt_controller(error: float, gain: float, limit: float, dt_s: float) -> float:
    """The correction for ``error``: ``gain e`` near 0, ``sqrt(2 limit e)`` beyond, within ``|e| / dt``.

    The piecewise law of ArduPilot's ``sqrt_controller``: its output's rate of change stays within
    ``limit`` when the error itself closes at that output; the last clamp stops it overshooting in one step.

    Examples:
        >>> sqrt_controller(0.1, 2.0, 1.0, 0.01), round(sqrt_controller(10.0, 2.0, 1.0, 0.01), 4)
        (0.2, 4.4441)
    """
    linear = limit / (gain * gain)
    size = abs(error)
    if size > linear:
        rate = math.sqrt(2.0 * limit * (size - linear / 2.0))
    else:
        rate = size * gain
    return math.copysign(min(rate, size / dt_s), error)


def _limit(x: float, y: float, length: float) -> tuple[float, float]:
    size = math.hypot(x, y)
    if size > length > 0.0 or (length == 0.0 and size > 0.0):
        scale = length / size
        return x * scale, y * scale
    return x, y


class _JerkLimitedCopter(PointMassCopter):
    """What both models share: an acceleration state, the control tick, the vertical axis."""

    def __init__(self, position_m: np.ndarray, limits: AutopilotLimits, realism: Realism,
                 rng: np.random.Generator, jerk: JerkLimits) -> None:
        self.jerk = jerk
        self._a = [0.0, 0.0, 0.0]
        super().__init__(position_m, limits, realism, rng)

    @property
    def acceleration_m_s2(self) -> np.ndarray:
        """The controller's acceleration now (East, North, Up m/s^2; the wind's push aside)."""
        return np.array(self._a)

    def settle(self, position_m: np.ndarray) -> None:
        """Put the vehicle at rest at ``position_m``, holding there (no acceleration either)."""
        super().settle(position_m)
        self._a = [0.0, 0.0, 0.0]

    def stopping_point_m(self) -> np.ndarray:
        """Where the set point stops if it brakes now (its own braking distance, the jerk's delay in it)."""
        speed = math.hypot(self._v[0], self._v[1])
        horizontal = self._braking_m(speed) / speed if speed > 0.0 else 0.0
        az, jz = self.limits.vertical_accel_m_s2, self.jerk.vertical_jerk_m_s3
        vz = self._v[2]
        return np.array([self._p[0] + self._v[0] * horizontal, self._p[1] + self._v[1] * horizontal,
                         self._p[2] + vz * (abs(vz) / (2.0 * az) + az / jz)])

    def _braking_m(self, speed_m_s: float) -> float:
        a, j = self.limits.max_accel_m_s2, self.jerk.jerk_m_s3
        return speed_m_s * (speed_m_s / (2.0 * a) + a / j)

    def _step(self, h: float) -> None:
        ticks = max(1, math.ceil(h / self.jerk.control_dt_s - 1e-9))
        dt = h / ticks
        for _ in range(ticks):
            if self._target is not None:
                self._shape_xy(dt)
                self._shape_z(dt)
            else:  # never commanded: let the acceleration go (it is 0 at rest)
                for axis in range(3):
                    limit = (self.jerk.jerk_m_s3 if axis < 2 else self.jerk.vertical_jerk_m_s3) * dt
                    self._a[axis] -= max(-limit, min(limit, self._a[axis]))
            for axis in range(3):
                self._p[axis] += self._v[axis] * dt + 0.5 * self._a[axis] * dt * dt
                self._v[axis] += self._a[axis] * dt
        self._disturb(h)

    def _shape_xy(self, dt: float) -> None:
        raise NotImplementedError

    def _shape_z(self, dt: float) -> None:
        """One axis: a square-root controller to a climb or descent rate, then to an acceleration."""
        assert self._target is not None
        az, jz = self.limits.vertical_accel_m_s2, self.jerk.vertical_jerk_m_s3
        error = self._target[2] - self._p[2]
        want = sqrt_controller(error, 0.5 * jz / az, 0.5 * az, dt)
        want = max(-self.limits.descent_m_s, min(self.limits.climb_m_s, want))
        demand = sqrt_controller(want - self._v[2], jz / az, jz, dt)
        demand = max(-az, min(az, demand))
        self._a[2] += max(-jz * dt, min(jz * dt, demand - self._a[2]))


class ArduCopterLikeCopter(_JerkLimitedCopter):
    """ArduCopter's horizontal kinematic shaping (module docstring), flown in simulated time.

    Args:
        position_m: Where it starts, at rest (East, North, Up metres).
        limits: ``WPNAV_SPEED``, ``WPNAV_ACCEL`` (``max_speed_m_s``, ``max_accel_m_s2``), the vertical ones.
        realism: Its imperfections.
        rng: The source of every random draw.
        jerk: ``PSC_JERK_XY``, ``PSC_JERK_Z`` and the control tick.
    """

    def __init__(self, position_m: np.ndarray, limits: AutopilotLimits, realism: Realism,
                 rng: np.random.Generator, jerk: JerkLimits = ARDUCOPTER_JERK) -> None:
        super().__init__(position_m, limits, realism, rng, jerk)

    def _braking_m(self, speed_m_s: float) -> float:
        """Its position controller's stopping distance (braking at ``a / 2``, as ``inv_sqrt_controller``)."""
        a, j = self.limits.max_accel_m_s2, self.jerk.jerk_m_s3
        gain, limit = 0.5 * j / a, 0.5 * a
        if speed_m_s < limit / gain:
            return speed_m_s / gain
        return limit / (2.0 * gain * gain) + speed_m_s * speed_m_s / (2.0 * limit)

    def _shape_xy(self, dt: float) -> None:
        assert self._target is not None
        a, j, v_max = self.limits.max_accel_m_s2, self.jerk.jerk_m_s3, self.limits.max_speed_m_s
        ex, ey = self._target[0] - self._p[0], self._target[1] - self._p[1]
        distance = math.hypot(ex, ey)
        wx = wy = 0.0
        if distance > 0.0:
            speed = min(v_max, sqrt_controller(distance, 0.5 * j / a, 0.5 * a, dt))
            wx, wy = ex / distance * speed, ey / distance * speed
        cx, cy = wx - self._v[0], wy - self._v[1]
        change = math.hypot(cx, cy)
        dx = dy = 0.0
        if change > 0.0:
            size = sqrt_controller(change, j / a, j, dt)
            dx, dy = cx / change * size, cy / change * size
        wanted = math.hypot(wx, wy)
        if wanted == 0.0:
            dx, dy = _limit(dx, dy, a)
        else:  # keep a / sqrt(2) for the correction across the velocity demand
            ux, uy = wx / wanted, wy / wanted
            along = dx * ux + dy * uy
            crossx, crossy = dx - along * ux, dy - along * uy
            if along * along <= crossx * crossx + crossy * crossy:
                dx, dy = _limit(dx, dy, a)
            else:
                crossx, crossy = _limit(crossx, crossy, a / math.sqrt(2.0))
                room = math.sqrt(max(0.0, a * a - crossx * crossx - crossy * crossy))
                along = max(-room, min(room, along))
                dx, dy = crossx + along * ux, crossy + along * uy
        jx, jy = _limit(dx - self._a[0], dy - self._a[1], j * dt)
        self._a[0] += jx
        self._a[1] += jy


class PX4LikeCopter(_JerkLimitedCopter):
    """PX4's position smoothing with per-axis limits (module docstring), flown in simulated time.

    Args:
        position_m: Where it starts, at rest (East, North, Up metres).
        limits: The cruise speed and ``MPC_ACC_HOR`` (``max_speed_m_s``, ``max_accel_m_s2``: on each axis),
            the vertical limits.
        realism: Its imperfections.
        rng: The source of every random draw.
        jerk: ``MPC_JERK_AUTO`` (on each axis) and the control tick.
    """

    def __init__(self, position_m: np.ndarray, limits: AutopilotLimits, realism: Realism,
                 rng: np.random.Generator, jerk: JerkLimits = PX4_JERK) -> None:
        super().__init__(position_m, limits, realism, rng, jerk)

    def _shape_xy(self, dt: float) -> None:
        assert self._target is not None
        a, j, v_max = self.limits.max_accel_m_s2, self.jerk.jerk_m_s3, self.limits.max_speed_m_s
        ex, ey = self._target[0] - self._p[0], self._target[1] - self._p[1]
        distance = math.hypot(ex, ey)
        want = (0.0, 0.0)
        if distance > 0.0:
            delay = 4.0 * a * a / j  # v^2 + delay v = 2 a d: braking after a jerk delay of 2 a / j
            speed = min(v_max, 0.5 * (-delay + math.sqrt(delay * delay + 8.0 * a * distance)), distance / dt)
            want = (ex / distance * speed, ey / distance * speed)
        for axis in range(2):
            demand = sqrt_controller(want[axis] - self._v[axis], j / a, j, dt)
            demand = max(-a, min(a, demand))
            self._a[axis] += max(-j * dt, min(j * dt, demand - self._a[axis]))
