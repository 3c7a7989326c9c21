"""What the guard knows of one vehicle: the points it may be flying to, and the disc it cannot leave.

A vehicle's **commitment** (:class:`Commitment`) is the chain of points it may be flying to: the last
one known to be in effect (acknowledged, or where it started at rest) and every one sent after it,
oldest first; its **certified disc** is centred on the newest point with :attr:`Commitment.radius_m`.
While no new point is sent the vehicle stays in that disc forever, whichever of the chain's points it
flies to and whenever they arrive (:mod:`uav_swarm.world.guard`, the lemma and the chain rule): so its
hold needs no command at all (it keeps flying to a point it can stop at), and the same disc is what
every other vehicle is kept away from.

- :meth:`Commitment.sent`: a new point; the disc moves onto it and grows by the step
  (``radius + |old - new|``, which contains the old disc);
- :meth:`Commitment.acknowledged`: the point is in effect: the older ones are dropped;
- :meth:`Commitment.measure`: a measurement (position, velocity, the time it was true) shrinks the
  radius to what the energy bound gives, and says whether the vehicle lies outside its disc (a bound
  broken: weaker braking, stronger wind, a larger error than stated).

Examples:
    >>> bounds = Bounds(accel_m_s2=2.5, command_delay_s=0.5)
    >>> hold = Commitment(np.array([0.0, 0.0]), bounds, now_s=0.0, radius_m=0.0)  # at rest there
    >>> hold.sent(np.array([30.0, 40.0]), now_s=0.0)  # 50 m away: the disc is centred there, radius 50
    1
    >>> float(hold.radius_m), hold.may_send(0.2), hold.may_send(0.5)
    (50.0, False, True)
    >>> hold.acknowledged(1, now_s=0.3)
    >>> hold.measure(np.array([30.0, 36.0]), np.array([0.0, 2.0]), stamp_s=0.4)  # 4 m short, at 2 m/s
    False
    >>> float(hold.radius_m)  # 4 m + 2^2 / (2 * 2.5)
    4.8
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from uav_swarm.world.guard.reach import axis_energy_radius_m, energy_radius_m

__all__ = ["Bounds", "Commitment"]

_KEPT = 64  # points (and earlier chains) kept for measurements older than the newest acknowledgement


@dataclass(frozen=True)
class Bounds:
    """The bounds under which one vehicle is kept apart (the proof's assumptions, checked at run time).

    Attributes:
        accel_m_s2: The acceleration its autopilot plans with, braking and turning included (the
            smallest of what it reports and what the guard is told).
        jerk_m_s3: Its jerk limit (``inf``: none); braking reaches ``accel_m_s2`` after ``a / j``.
        position_error_m: Largest error of a measured position.
        velocity_error_m_s: Largest error of a measured velocity.
        tracking_error_m: Largest distance between the true position and the autopilot's set point
            (wind, gusts).
        command_delay_s: A command takes effect, and its acknowledgement is back, within this.
        position_age_s: A measurement older than this is out of bounds.
        per_axis: Its autopilot limits the acceleration on each horizontal axis (PX4's ``MPC_ACC_HOR``):
            its energy is bounded on each axis ((B1x) of :mod:`uav_swarm.world.guard`).
    """

    accel_m_s2: float
    jerk_m_s3: float = math.inf
    position_error_m: float = 0.0
    velocity_error_m_s: float = 0.0
    tracking_error_m: float = 0.0
    command_delay_s: float = 0.5
    position_age_s: float = 1.0
    per_axis: bool = False

    def __post_init__(self) -> None:
        if not (math.isfinite(self.accel_m_s2) and self.accel_m_s2 > 0):
            raise ValueError(f"Bounds.accel_m_s2 must be > 0, got {self.accel_m_s2!r}")
        if not self.jerk_m_s3 > 0:
            raise ValueError(f"Bounds.jerk_m_s3 must be > 0 (inf: none), got {self.jerk_m_s3!r}")
        for name in ("position_error_m", "velocity_error_m_s", "tracking_error_m", "command_delay_s",
                     "position_age_s"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) >= 0):
                raise ValueError(f"Bounds.{name} must be >= 0, got {getattr(self, name)!r}")

    def radius_m(self, offset_m: np.ndarray, velocity_m_s: np.ndarray) -> np.ndarray:
        """Distance from its target it never exceeds again, from a measured offset (..., 2) and velocity (2,).

        :func:`~uav_swarm.world.guard.reach.energy_radius_m` under these bounds, or
        :func:`~uav_swarm.world.guard.reach.axis_energy_radius_m` for an autopilot limited per axis.
        """
        errors = {"position_error_m": self.position_error_m, "velocity_error_m_s": self.velocity_error_m_s,
                  "tracking_error_m": self.tracking_error_m, "jerk_m_s3": self.jerk_m_s3}
        velocity = np.asarray(velocity_m_s, dtype=np.float64)
        if self.per_axis:
            return axis_energy_radius_m(offset_m, velocity, self.accel_m_s2, **errors)
        speed = np.hypot(velocity[..., 0], velocity[..., 1])
        return energy_radius_m(offset_m, speed, self.accel_m_s2, **errors)


class Commitment:
    """The chain of points one vehicle may fly to and its certified disc (module docstring).

    Args:
        point_m: (2,) the point it is flying to when the guard takes it (it is there, or flying there).
        bounds: Its bounds.
        now_s: When that point is known to be in effect (the guard's clock, seconds).
        radius_m: Its certified radius around ``point_m`` now (``inf``: unknown until measured).
    """

    def __init__(self, point_m: np.ndarray, bounds: Bounds, now_s: float, radius_m: float = math.inf) -> None:
        self.bounds = bounds
        self.chain: list[np.ndarray] = [np.asarray(point_m, dtype=np.float64).copy()]
        self._seqs: list[int] = [0]
        self.radius_m = float(radius_m)
        self.known_s = float(now_s)
        """When the chain's first point was known to be in effect."""
        self.sent_s = -math.inf
        """When the newest point was sent."""
        self.awaiting = False
        """The newest point was sent and is neither acknowledged nor past the delay bound."""
        self.measured_s = -math.inf
        """The stamp of the newest measurement used."""
        self._next_seq = 1
        self._points: dict[int, np.ndarray] = {0: self.chain[0]}
        """The newest points sent, by sequence number (what an older measurement is judged against)."""
        self._known: list[tuple[float, int]] = []
        """``(known_s, first seq)`` of the chains that held before :attr:`known_s`, newest last."""

    @property
    def centre_m(self) -> np.ndarray:
        """(2,) the newest point: the centre of the certified disc."""
        return self.chain[-1]

    def may_send(self, now_s: float) -> bool:
        """Whether a new point may be sent now: the newest was acknowledged or sent the delay bound ago.

        Commands then take effect in the order sent (none older can still arrive after a newer one).
        """
        return not self.awaiting or now_s - self.sent_s >= self.bounds.command_delay_s

    def radius_after_m(self, point_m: np.ndarray) -> np.ndarray:
        """Certified radius around ``point_m`` (..., 2) if it were sent now: ``radius + |centre - point|``."""
        step = np.asarray(point_m, dtype=np.float64) - self.centre_m
        return self.radius_m + np.hypot(step[..., 0], step[..., 1])

    def sent(self, point_m: np.ndarray, now_s: float) -> int:
        """Record a point sent now (whether or not it will arrive); its sequence number."""
        point = np.asarray(point_m, dtype=np.float64).copy()
        self.radius_m = float(self.radius_after_m(point))
        self.chain.append(point)
        seq = self._next_seq
        self._next_seq += 1
        self._seqs.append(seq)
        self._points[seq] = point
        if len(self._points) > _KEPT:
            del self._points[min(self._points)]
        self.sent_s, self.awaiting = float(now_s), True
        return seq

    def acknowledged(self, seq: int, now_s: float) -> None:
        """The point ``seq`` is in effect (its acknowledgement arrived at ``now_s``): older points drop."""
        if seq not in self._seqs:
            return  # already superseded by a newer acknowledgement
        first = self._seqs.index(seq)
        self._known = [*self._known[1 - _KEPT:], (self.known_s, self._seqs[0])]
        self.chain, self._seqs = self.chain[first:], self._seqs[first:]
        self.known_s = float(now_s)
        if seq == self._seqs[-1]:
            self.awaiting = False

    def unacknowledged(self, seq: int) -> None:
        """No acknowledgement of ``seq`` within the bound: it may still be in effect; a new point may go."""
        if self._seqs and seq == self._seqs[-1]:
            self.awaiting = False
            self.sent_s = -math.inf

    def fresh_radius_m(self, position_m: np.ndarray, velocity_m_s: np.ndarray,
                       chain: list[np.ndarray] | None = None) -> float:
        """Certified radius around the newest point from a measurement taken while ``chain`` held.

        The vehicle flew to one of the chain's points when measured, then possibly to each later one:
        the worst over the chain of its energy bound to that point plus the chain's length from there.
        ``chain`` (default: today's) ends with the newest point sent.
        """
        points = np.asarray(self.chain if chain is None else chain)
        radii = self.bounds.radius_m(np.asarray(position_m) - points, np.asarray(velocity_m_s)[:2])
        steps = np.hypot(*np.diff(points, axis=0).T) if len(points) > 1 else np.zeros(0)
        onward = np.concatenate([np.cumsum(steps[::-1])[::-1], [0.0]])  # chain length from each point on
        return float(np.max(radii + onward))

    def measure(self, position_m: np.ndarray, velocity_m_s: np.ndarray, stamp_s: float) -> bool:
        """Use a measurement true at ``stamp_s``; True when it lies outside the certified disc.

        A measurement older than one already used changes nothing. One from before the chain's first
        point was known in effect is judged against the chain that held then and every point sent since
        (it flew to one of those when measured, then possibly to each later one); one older than every
        chain kept changes nothing.
        """
        if stamp_s <= self.measured_s:
            return False
        chain = self.chain
        if stamp_s < self.known_s:
            firsts = [first for known_s, first in self._known if known_s <= stamp_s]
            seqs = range(firsts[-1], self._seqs[-1] + 1) if firsts else range(0)
            if not firsts or any(s not in self._points for s in seqs):
                return False
            chain = [self._points[s] for s in seqs]
        self.measured_s = float(stamp_s)
        p = np.asarray(position_m, dtype=np.float64)
        outside = bool(np.hypot(*(p - self.centre_m)) > self.radius_m + self.bounds.position_error_m + 1e-9)
        fresh = self.fresh_radius_m(p, np.asarray(velocity_m_s, dtype=np.float64), chain)
        self.radius_m = min(self.radius_m, fresh)
        return outside

    def reset(self, point_m: np.ndarray, radius_m: float, now_s: float) -> None:
        """Start again from a point and radius the caller vouches for (a vehicle found outside its disc)."""
        self.chain, self._seqs = [np.asarray(point_m, dtype=np.float64).copy()], [self._next_seq]
        self._points, self._known = {self._next_seq: self.chain[0]}, []
        self._next_seq += 1
        self.radius_m, self.known_s, self.awaiting = float(radius_m), float(now_s), False
