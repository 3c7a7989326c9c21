"""A multicopter as its autopilot flies it: a point mass in simulated time, with bounded imperfections.

This is the one kinematic core behind the simulated MAVLink vehicles (:mod:`bridge.simulated`) and any
simulated-time test of a guard: pure and deterministic (no clock, no thread; every random draw comes from
the :class:`numpy.random.Generator` it is given), advanced by the caller in simulated seconds.

**Frame and state.** East-North-Up metres around the vehicle's home; the true state is the position
``p`` and velocity ``v`` of the position controller's set point plus a bounded tracking error ``e``
(wind, below): ``position_m = p + e``, ``velocity_m_s = v + de/dt``.

**What the autopilot does** (:class:`AutopilotLimits`). A goto target ``T`` is flown by a stopping
controller, horizontally and vertically apart as ArduCopter's and PX4's position controllers do. Each
step of length ``h`` the controller wants the speed toward ``T``

    ``s = min(v_max, -a h + sqrt((a h)^2 + 2 a d))``,  ``d = |T - p|``,

the largest speed from which braking at ``a`` still stops at ``T`` after this step moves ``s h``
(``s^2 + 2 a h s = 2 a d``, the discrete form of ``v^2 <= 2 a d``), and changes the velocity toward
it by at most ``a h``: acceleration and braking share ``a``; the horizontal speed never exceeds
``max_speed_m_s``, the climb ``climb_m_s``, the descent ``descent_m_s``. A vehicle already heading for
its target never passes it. One whose target turns keeps its momentum and swings wide: braking and
turning share ``a``, so it runs on along its old heading about ``|v|^2 / (2 a)``, a little more in a
sharp turn (30.3 m instead of 28.8 m at 12 m/s and 2.5 m/s^2 turning back by 124 degrees); the hard
bounds are the limits themselves (``|v| <= v_max``, ``|dv/dt| <= a``, whatever the commands). A ``None``
target brakes straight: the vehicle holds exactly where braking at ``a`` stops it
(``p + v |v| / (2 a)``, :meth:`PointMassCopter.stopping_point_m`), never beyond.

**Bounded imperfections** (:class:`Realism`, all 0 by default):

- a command takes effect ``command_latency_s`` after :meth:`PointMassCopter.send`; with probability
  ``command_loss`` it (and its acknowledgement) is lost: ``send`` returns False and nothing changes;
- reports (:meth:`PointMassCopter.report`) are emitted every ``1 / position_rate_hz`` s from ``t = 0``;
  each carries the true state of ``position_age_s`` earlier (its ``stamp_s``) plus Gaussian noise of
  ``position_noise_m`` (sigma, on each axis of the position);
- wind: a steady ``wind_m_s`` from a direction drawn once, plus a gust vector that wanders (an
  Ornstein-Uhlenbeck process with a 2 s time constant) and is clipped to ``gust_m_s``. While airborne
  (set point ``z > 0``) the autopilot's velocity loop learns the wind it feels (an integrator with a
  5 s time constant, as ArduCopter's and PX4's velocity loops remove a steady wind) and the tracking
  error follows ``wind_response_s * (wind + gust - learned)`` with the time constant ``wind_response_s``:
  a steady wind pushes a vehicle that has just taken off, then fades; gusts keep pushing. The error is
  horizontal and ``|e| <= wind_response_s * (wind_m_s + 2 gust_m_s)`` at all times
  (:attr:`Realism.tracking_error_bound_m`: the learned wind is an average of winds felt, so it is
  never further than ``wind_m_s + 2 gust_m_s`` from the wind now).

Example: five metres east, from rest, at 2.5 m/s^2 and 10 m/s:

>>> import numpy as np
>>> limits = AutopilotLimits(max_speed_m_s=10.0, max_accel_m_s2=2.5, climb_m_s=2.5, descent_m_s=1.5)
>>> copter = PointMassCopter(np.zeros(3), limits, Realism(), np.random.default_rng(0))
>>> copter.send(0.0, np.array([5.0, 0.0, 0.0]))
True
>>> copter.advance(10.0)
>>> [round(float(x), 6) for x in copter.position_m], round(copter.now_s, 6)
([5.0, 0.0, 0.0], 10.0)
>>> max(abs(float(x)) for x in copter.velocity_m_s) < 1e-6
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

__all__ = ["AutopilotLimits", "Realism", "PositionReport", "PointMassCopter", "MAX_STEP_S",
           "ARDUCOPTER_LIMITS", "PX4_LIMITS"]

MAX_STEP_S = 0.05
"""The longest integration step: :meth:`PointMassCopter.advance` splits longer spans (20 Hz at least)."""
_GUST_TIME_S = 2.0
_LEARN_TIME_S = 5.0


@dataclass(frozen=True)
class AutopilotLimits:
    """How the autopilot flies a goto (its real settings, not a guard's assumptions).

    Attributes:
        max_speed_m_s: Horizontal speed (ArduCopter ``WPNAV_SPEED`` 1000 cm/s, PX4 ``MPC_XY_VEL_MAX`` 12 m/s).
        max_accel_m_s2: Horizontal acceleration, braking included (ArduCopter ``WPNAV_ACCEL`` 250 cm/s^2,
            PX4 ``MPC_ACC_HOR`` 3 m/s^2).
        climb_m_s: Climb rate (ArduCopter ``WPNAV_SPEED_UP`` 250 cm/s, PX4 ``MPC_Z_VEL_MAX_UP`` 3 m/s).
        descent_m_s: Descent rate (ArduCopter ``WPNAV_SPEED_DN`` 150 cm/s, PX4 ``MPC_Z_VEL_MAX_DN`` 1.5 m/s).
        vertical_accel_m_s2: Vertical acceleration (ArduCopter ``WPNAV_ACCEL_Z`` 100 cm/s^2,
            PX4 ``MPC_ACC_DOWN_MAX`` 3 m/s^2, the smaller of its up and down limits).
    """

    max_speed_m_s: float
    max_accel_m_s2: float
    climb_m_s: float
    descent_m_s: float
    vertical_accel_m_s2: float = 2.5

    def __post_init__(self) -> None:
        for name in ("max_speed_m_s", "max_accel_m_s2", "climb_m_s", "descent_m_s", "vertical_accel_m_s2"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be a finite number > 0, got {value!r}")


ARDUCOPTER_LIMITS = AutopilotLimits(max_speed_m_s=10.0, max_accel_m_s2=2.5, climb_m_s=2.5, descent_m_s=1.5,
                                    vertical_accel_m_s2=1.0)
"""ArduCopter 4.6's defaults: ``WPNAV_SPEED`` 1000, ``WPNAV_ACCEL`` 250, ``WPNAV_SPEED_UP`` 250,
``WPNAV_SPEED_DN`` 150 (cm/s), ``WPNAV_ACCEL_Z`` 100 (cm/s^2)."""
PX4_LIMITS = AutopilotLimits(max_speed_m_s=5.0, max_accel_m_s2=3.0, climb_m_s=3.0, descent_m_s=1.5,
                             vertical_accel_m_s2=3.0)
"""PX4 1.15's defaults for a goto in an autonomous mode: ``MPC_XY_CRUISE`` 5 m/s (``MPC_XY_VEL_MAX`` 12 m/s
caps any speed asked for), ``MPC_ACC_HOR`` 3 m/s^2, ``MPC_Z_V_AUTO_UP`` 3, ``MPC_Z_V_AUTO_DN`` 1.5 m/s,
``MPC_ACC_DOWN_MAX`` 3 m/s^2."""


@dataclass(frozen=True)
class Realism:
    """Bounded imperfections of a real vehicle; all 0 (ideal) by default.

    Attributes:
        command_latency_s: A command takes effect this long after it is sent.
        command_loss: Probability that a command (and its acknowledgement) is lost, in [0, 1).
        position_age_s: Reported positions are this old (GPS and estimator lag).
        position_rate_hz: Reports per second.
        position_noise_m: Standard deviation of the Gaussian noise on each axis of a reported position.
        wind_m_s: Steady wind speed (its direction drawn once from the generator).
        gust_m_s: Largest gust on top of the steady wind.
        wind_response_s: Position error the autopilot leaves per m/s of wind it has not yet learned, and
            the time constant with which that error follows the wind (0.3 s: a gust of 4 m/s moves a
            vehicle about 1.2 m, as ArduCopter's position loop in gusty wind).
    """

    command_latency_s: float = 0.0
    command_loss: float = 0.0
    position_age_s: float = 0.0
    position_rate_hz: float = 10.0
    position_noise_m: float = 0.0
    wind_m_s: float = 0.0
    gust_m_s: float = 0.0
    wind_response_s: float = 0.3

    def __post_init__(self) -> None:
        for name in ("command_latency_s", "position_age_s", "position_noise_m", "wind_m_s", "gust_m_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
        if not 0.0 <= self.command_loss < 1.0:
            raise ValueError(f"command_loss must be in [0, 1), got {self.command_loss!r}")
        for name in ("position_rate_hz", "wind_response_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be a finite number > 0, got {value!r}")

    @property
    def tracking_error_bound_m(self) -> float:
        """The largest horizontal distance between the true position and the controller's set point."""
        return self.wind_response_s * (self.wind_m_s + 2.0 * self.gust_m_s)


class PositionReport(NamedTuple):
    """A measurement the vehicle emitted: its state at ``stamp_s`` (noise on the position)."""

    position_m: np.ndarray
    velocity_m_s: np.ndarray
    stamp_s: float


def _toward(offset: float, v_max: float, accel: float, h: float) -> float:
    """The stopping controller's wanted speed toward a target ``offset >= 0`` metres away (1-D)."""
    if offset <= 0.0:
        return 0.0
    return min(v_max, -accel * h + math.sqrt((accel * h) ** 2 + 2.0 * accel * offset), offset / h)


class PointMassCopter:
    """A multicopter flown by its autopilot, advanced in simulated time (see the module docstring).

    ``limits`` may be replaced between two :meth:`advance` calls (an autopilot whose parameters change).

    Args:
        position_m: Where it starts, at rest (East, North, Up metres).
        limits: How its autopilot flies.
        realism: Its imperfections.
        rng: The source of every random draw (command loss, wind, report noise).
    """

    def __init__(self, position_m: np.ndarray, limits: AutopilotLimits, realism: Realism,
                 rng: np.random.Generator) -> None:
        start = np.asarray(position_m, dtype=float)
        if start.shape != (3,) or not np.all(np.isfinite(start)):
            raise ValueError(f"position_m must be 3 finite metres (East, North, Up), got {position_m!r}")
        self.limits, self.realism = limits, realism
        self._loss_rng, self._wind_rng, self._noise_rng = rng.spawn(3)
        self._p = [float(x) for x in start]
        self._v = [0.0, 0.0, 0.0]
        self._e = [0.0, 0.0]
        self._de = [0.0, 0.0]
        self._gust = [0.0, 0.0]
        self._learned = [0.0, 0.0]
        heading = float(self._wind_rng.uniform(0.0, 2.0 * math.pi))
        self._wind = (realism.wind_m_s * math.cos(heading), realism.wind_m_s * math.sin(heading))
        self._target: tuple[float, float, float] | None = None
        self._pending: list[tuple[float, int, tuple[float, float, float] | None]] = []
        self._sent = 0
        self.now_s = 0.0
        self._history: list[tuple[float, tuple[float, ...], tuple[float, ...]]] = []
        self._reports_emitted = 0
        self._report: PositionReport | None = None
        self._remember()
        self._emit_due()

    # -- true state ----------------------------------------------------------------------------
    @property
    def position_m(self) -> np.ndarray:
        """The true position (East, North, Up metres)."""
        return np.array(self._true()[0])

    @property
    def velocity_m_s(self) -> np.ndarray:
        """The true velocity (East, North, Up m/s)."""
        return np.array(self._true()[1])

    @property
    def target_m(self) -> np.ndarray | None:
        """The goto target in effect (None before any command took effect)."""
        return None if self._target is None else np.array(self._target)

    @property
    def setpoint_m(self) -> np.ndarray:
        """Where the position controller is (``position_m`` less the tracking error).

        It is the autopilot's own idea of where the vehicle should be: autopilots judge arrival by it.
        """
        return np.array(self._p)

    def settle(self, position_m: np.ndarray) -> None:
        """Put the vehicle at rest at ``position_m``, holding there (a touchdown; a vehicle placed by hand).

        Commands not yet in effect are dropped; the clock runs on.
        """
        array = np.asarray(position_m, dtype=float)
        if array.shape != (3,) or not np.all(np.isfinite(array)):
            raise ValueError(f"position_m must be 3 finite metres (East, North, Up), got {position_m!r}")
        self._p = [float(x) for x in array]
        self._v, self._e, self._de, self._learned = [0.0, 0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]
        self._target, self._pending = (self._p[0], self._p[1], self._p[2]), []

    def stopping_point_m(self) -> np.ndarray:
        """Where the set point stops if it brakes now at the autopilot's limits (the tracking error aside)."""
        a, az = self.limits.max_accel_m_s2, self.limits.vertical_accel_m_s2
        speed = math.hypot(self._v[0], self._v[1])
        return np.array([self._p[0] + self._v[0] * speed / (2.0 * a),
                         self._p[1] + self._v[1] * speed / (2.0 * a),
                         self._p[2] + self._v[2] * abs(self._v[2]) / (2.0 * az)])

    def _true(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        p, v, e, de = self._p, self._v, self._e, self._de
        return (p[0] + e[0], p[1] + e[1], p[2]), (v[0] + de[0], v[1] + de[1], v[2])

    # -- commands ------------------------------------------------------------------------------
    def send(self, now_s: float, target_m: np.ndarray | None) -> bool:
        """Send a goto (``target_m``, East-North-Up metres) or a hold (None) at simulated time ``now_s``.

        Returns whether it arrives (not lost); an arriving command takes effect ``command_latency_s``
        later. ``now_s`` may not lie before the vehicle's clock.
        """
        if now_s < self.now_s - 1e-9:
            raise ValueError(f"now_s {now_s} lies before the vehicle's clock {self.now_s}")
        target = None
        if target_m is not None:
            array = np.asarray(target_m, dtype=float)
            if array.shape != (3,) or not np.all(np.isfinite(array)):
                raise ValueError(f"target_m must be 3 finite metres (East, North, Up) or None: {target_m!r}")
            target = (float(array[0]), float(array[1]), float(array[2]))
        if self._loss_rng.random() < self.realism.command_loss:
            return False
        self._sent += 1
        self._pending.append((now_s + self.realism.command_latency_s, self._sent, target))
        self._pending.sort()
        self._apply_due()
        return True

    def _apply_due(self) -> None:
        while self._pending and self._pending[0][0] <= self.now_s + 1e-12:
            _, _, target = self._pending.pop(0)
            if target is None:
                stop = self.stopping_point_m()
                target = (float(stop[0]), float(stop[1]), float(stop[2]))
            self._target = target

    # -- integration ---------------------------------------------------------------------------
    def advance(self, dt_s: float) -> None:
        """Fly ``dt_s`` simulated seconds, emitting the reports that fall due.

        Steps are at most :data:`MAX_STEP_S` long and split where a command takes effect.
        """
        if not (math.isfinite(dt_s) and dt_s >= 0.0):
            raise ValueError(f"dt_s must be a finite number >= 0, got {dt_s!r}")
        end_s = self.now_s + dt_s
        while self.now_s < end_s - 1e-12:
            step_end_s = min(end_s, self.now_s + MAX_STEP_S)
            if self._pending:
                step_end_s = min(step_end_s, max(self._pending[0][0], self.now_s))
            h = step_end_s - self.now_s
            if h > 0.0:
                self._step(h)
            self.now_s = step_end_s
            self._apply_due()
            self._remember()
            self._emit_due()

    def _step(self, h: float) -> None:
        limits = self.limits
        if self._target is not None:
            a = limits.max_accel_m_s2
            dx, dy = self._target[0] - self._p[0], self._target[1] - self._p[1]
            distance = math.hypot(dx, dy)
            want = _toward(distance, limits.max_speed_m_s, a, h)
            wx, wy = (dx / distance * want, dy / distance * want) if distance > 0.0 else (0.0, 0.0)
            cx, cy = wx - self._v[0], wy - self._v[1]
            change = math.hypot(cx, cy)
            if change > a * h:
                cx, cy = cx * a * h / change, cy * a * h / change
            self._v[0] += cx
            self._v[1] += cy
            dz = self._target[2] - self._p[2]
            az = limits.vertical_accel_m_s2
            v_max_z = limits.climb_m_s if dz >= 0.0 else limits.descent_m_s
            want_z = math.copysign(_toward(abs(dz), v_max_z, az, h), dz)
            self._v[2] += max(-az * h, min(az * h, want_z - self._v[2]))
        for axis in range(3):
            self._p[axis] += self._v[axis] * h
        self._disturb(h)

    def _disturb(self, h: float) -> None:
        realism = self.realism
        if realism.gust_m_s > 0.0:
            kick = self._wind_rng.normal(size=2) * realism.gust_m_s * math.sqrt(2.0 * h / _GUST_TIME_S)
            gx = self._gust[0] * (1.0 - h / _GUST_TIME_S) + float(kick[0])
            gy = self._gust[1] * (1.0 - h / _GUST_TIME_S) + float(kick[1])
            size = math.hypot(gx, gy)
            scale = min(1.0, realism.gust_m_s / size) if size > 0.0 else 1.0
            self._gust = [gx * scale, gy * scale]
        if realism.wind_m_s == 0.0 and realism.gust_m_s == 0.0:
            return
        airborne = self._p[2] > 0.0
        felt = [w + g if airborne else 0.0 for w, g in zip(self._wind, self._gust, strict=True)]
        learn = min(1.0, h / _LEARN_TIME_S)
        self._learned = [a + (f - a) * learn for a, f in zip(self._learned, felt, strict=True)]
        goal = [realism.wind_response_s * (f - a) for f, a in zip(felt, self._learned, strict=True)]
        blend = min(1.0, h / realism.wind_response_s)
        for axis in range(2):
            moved = (goal[axis] - self._e[axis]) * blend
            self._e[axis] += moved
            self._de[axis] = moved / h

    # -- reports -------------------------------------------------------------------------------
    def _remember(self) -> None:
        position, velocity = self._true()
        self._history.append((self.now_s, position, velocity))
        keep_s = self.realism.position_age_s + 2.0 / self.realism.position_rate_hz + MAX_STEP_S
        while len(self._history) > 2 and self._history[1][0] < self.now_s - keep_s:
            self._history.pop(0)

    def _state_at(self, time_s: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """The true state at ``time_s`` (linear between steps; before the start, the start)."""
        history = self._history
        if time_s <= history[0][0]:
            return history[0][1], (0.0, 0.0, 0.0) if time_s < 0.0 else history[0][2]
        for (t0, p0, v0), (t1, p1, v1) in zip(history, history[1:], strict=False):
            if t0 <= time_s <= t1:
                w = (time_s - t0) / (t1 - t0) if t1 > t0 else 1.0
                return (tuple(a + (b - a) * w for a, b in zip(p0, p1, strict=True)),
                        tuple(a + (b - a) * w for a, b in zip(v0, v1, strict=True)))
        return history[-1][1], history[-1][2]

    def _emit_due(self) -> None:
        rate = self.realism.position_rate_hz
        while self._reports_emitted / rate <= self.now_s + 1e-9:
            emitted_s = self._reports_emitted / rate
            stamp_s = emitted_s - self.realism.position_age_s
            position, velocity = self._state_at(stamp_s)
            noise = self._noise_rng.normal(size=3) * self.realism.position_noise_m
            self._report = PositionReport(np.array(position) + noise, np.array(velocity), stamp_s)
            self._reports_emitted += 1

    def report(self) -> PositionReport:
        """The latest measurement the vehicle emitted (age, rate and noise applied).

        Its ``stamp_s`` is when it was true: ``position_age_s`` before it was emitted.
        """
        assert self._report is not None  # one is emitted at t = 0
        return self._report
