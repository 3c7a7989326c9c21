"""The guard of a fleet of real (or simulated) vehicles: measurements in, next points out, bounds checked.

:class:`FleetGuard` keeps each vehicle's :class:`~uav_swarm.world.guard.holds.Commitment` and, at each
decision, chooses the next points (:func:`~uav_swarm.world.guard.decide.choose_points`). The caller
sends the points it is given, says when each was acknowledged (or not, within the bound), and feeds
every measurement with the time it was true. What lies outside the bounds is detected and answered:

- **a position older than** ``position_age_s``: the vehicle is sent nothing new (it keeps flying to a
  point inside its disc, which needs no measurement to stay valid), event ``position_stale``;
- **a point not acknowledged** within ``command_delay_s``: it may still be in effect, so it stays in the
  chain (the disc covers it) and a new point may follow; event ``command_unacknowledged``;
- **a vehicle outside its certified disc** (braking weaker, wind stronger, errors larger than stated):
  its disc is widened to what its measured state needs at half the stated acceleration and it is sent
  the point where it was measured (it stops there), event ``outside_bounds``; the others are held
  off that wider disc. No distance is promised then: it is reported.

Each decision is a :class:`Decision` per vehicle; a vehicle not steered by the guard (climbing, landing)
is an :meth:`FleetGuard.obstacle`, a disc the others keep away from, with the column over its home where
its autopilot will land (:meth:`FleetGuard.obstacle`'s ``home_m``).

**Every state of a flight.** A vehicle that goes **silent** (no link, no position fix) keeps its disc,
which needs no measurement (:meth:`FleetGuard.silent`), and the column over its home is added: its
link-loss failsafe may take it home. Only a vehicle known to be on the ground leaves
(:meth:`FleetGuard.leave`). A vehicle joins with the points it may still be flying to
(:meth:`FleetGuard.join`'s ``earlier_m``) and an unknown radius until measured; an unknown disc
refuses every offer near it. A pair closer than required (homes a few metres apart, a vehicle
taken back) may only **part** or **yield**: a vehicle at rest at its point (or already flying straight
away) steps at most ``parting_step_m`` along a segment whose every point is at least as far from the
other's centre as it is (:func:`~uav_swarm.world.guard.decide.choose_points`). Decisions go to the
vehicle held longest first (priority rotates to who waits); vehicles each held by the next (a cycle of
holds, :mod:`~uav_swarm.world.guard.deadlock`) are recorded in :attr:`FleetGuard.deadlocks`; held,
each goes round the one it waits for after ``detour_after_s``. No point is committed more than
``max_step_m`` ahead. One lock serialises every call (the flight's loop and its sending threads).

Examples:
    >>> import numpy as np
    >>> guard = FleetGuard(np.full((2, 2), 5.0))
    >>> bounds = Bounds(accel_m_s2=2.5, command_delay_s=0.5)
    >>> for i, x in enumerate((0.0, 40.0)):
    ...     guard.join(i, np.array([x, 0.0]), bounds, now_s=0.0, radius_m=0.0)
    >>> goals = np.array([[40.0, 0.0], [0.0, 0.0]])  # a head-on swap
    >>> [(d.state, d.point_m) for d in guard.decide(goals, now_s=0.0)]  # first, the points they hover at
    [('on', (0.0, 0.0)), ('on', (40.0, 0.0))]
    >>> [(d.state, d.point_m) for d in guard.decide(goals, now_s=0.5)]
    [('free', (16.0, 0.0)), ('free', (39.0, 0.0))]
    >>> guard.radius_m(0), guard.radius_m(1)  # 16 + 1 + 5 <= 39 - 16: the discs keep 5 m
    (16.0, 1.0)
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import numpy as np

from uav_swarm.world.guard.deadlock import hold_cycles
from uav_swarm.world.guard.decide import STEPS_M, choose_points, finite_point
from uav_swarm.world.guard.holds import Bounds, Commitment

__all__ = ["Bounds", "Decision", "FleetGuard"]

_AT_POINT_M = 1.0  # a vehicle measured this close to its newest point may part from a pair inside


@dataclass(frozen=True)
class Decision:
    """What one vehicle is told at a decision.

    Attributes:
        state: ``"free"`` (sent its next point), ``"on"`` (flying to the point it has: its goal, or a new
            one may not go yet), ``"held"`` (its next point refused: it stops at the one it has),
            ``"stale"`` (no fresh position: held), ``"silent"`` (unheard: kept on its disc),
            ``"outside"`` (found outside its disc: stopped),
            ``"idle"`` (no goal, or not steered).
        point_m: The point to send now (None: send nothing).
        blocker: The vehicle that refused its next point (-1: none).
        seq: The point's sequence number, for :meth:`FleetGuard.acknowledged` (0: none).
    """

    state: str
    point_m: tuple[float, float] | None = None
    blocker: int = -1
    seq: int = 0


class FleetGuard:
    """Certified discs of up to K vehicles and the decisions that keep them apart (module docstring).

    Args:
        required_m: (K, K) the distance each pair must keep (the minimum, or less across altitude
            layers; :func:`uav_swarm.world.separation.required_distances_m`), the margin included.
        detour_after_s: A vehicle held this long may also step round what blocks it, seconds.
        detour_m: The longest such step, metres (default: the largest required distance).
        area_m: (width, height) the steps round stay in, from the origin (None: anywhere).
        max_step_m: The farthest a new point is committed ahead of a disc's centre, metres.
    """

    def __init__(self, required_m: np.ndarray, detour_after_s: float = 2.0, detour_m: float | None = None,
                 area_m: tuple[float, float] | None = None, max_step_m: float = STEPS_M[0]) -> None:
        self.required_m = np.array(required_m, dtype=np.float64)
        k = self.required_m.shape[0]
        self.max_step_m = float(max_step_m)
        self._lock = threading.RLock()
        self._homes: dict[int, np.ndarray] = {}  # the home columns of silent and landing vehicles
        self._silent: set[int] = set()
        self._velocity = np.zeros((k, 2))  # each vehicle's newest measured velocity
        self._position = np.full((k, 2), np.nan)  # and position
        self.parting_step_m = 4.0
        """The longest step a pair inside may part by, metres."""
        self.parting_speed_m_s = 1.5
        """A vehicle parts from a pair inside only this slow (it flies along its step), m/s."""
        self.detour_after_s = float(detour_after_s)
        self.area_m = None if area_m is None else np.asarray(area_m, dtype=np.float64)
        self.detour_m = float(detour_m if detour_m is not None else max(float(self.required_m.max()), 1.0))
        self._hold: list[Commitment | None] = [None] * k
        self._obstacle: dict[int, tuple[np.ndarray, float]] = {}
        self._held_since: dict[int, float] = {}
        self._via: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # a point round a blocker, then the goal
        self._joining: set[int] = set()  # joined, its join point not sent yet
        self._stale: set[int] = set()
        self._outside: dict[int, np.ndarray] = {}
        self._cycles: set[tuple[int, ...]] = set()  # the cycles of holds at the last decision
        self.deadlocks: list[tuple[float, tuple[int, ...]]] = []
        """``(now_s, cycle)`` of every cycle of holds found (:mod:`~uav_swarm.world.guard.deadlock`): the
        vehicles each held by the next, recorded once while it lasts."""
        self.events: list[tuple[float, int, str]] = []
        """``(now_s, vehicle, kind)`` of every bound found broken (position_stale, command_unacknowledged,
        outside_bounds)."""

    # -- vehicles ------------------------------------------------------------------------------
    def join(self, i: int, point_m: np.ndarray, bounds: Bounds, now_s: float,
             radius_m: float = math.inf, earlier_m: tuple[np.ndarray, ...] = ()) -> None:
        """Take vehicle ``i`` under the guard at ``point_m``, with its bounds.

        ``earlier_m`` are the points it may still be flying to (oldest first: where its take-off left it,
        the point it had before it went silent): its disc covers them until one sent is acknowledged.
        Its first decision sends it ``point_m`` (state ``"on"``), so that every point it flies to was sent.
        """
        with self._lock:
            chain = [np.asarray(p, dtype=np.float64) for p in (*earlier_m, point_m)]
            hold = Commitment(chain[0], bounds, now_s, radius_m)
            for later in chain[1:]:
                hold.sent(later, now_s)
                hold.awaiting = False  # no answer is due for it: the next point may follow at once
            hold.radius_m = float(radius_m)
            self._hold[i] = hold
            self._joining.add(i)
            self._obstacle.pop(i, None)
            self._homes.pop(i, None)
            self._silent.discard(i)
            self._held_since.pop(i, None)

    def leave(self, i: int) -> None:
        """Forget vehicle ``i``: only once it is known to be on the ground (disarmed)."""
        with self._lock:
            self._hold[i] = None
            self._obstacle.pop(i, None)
            self._homes.pop(i, None)
            self._silent.discard(i)
            self._held_since.pop(i, None)
            self._via.pop(i, None)
            self._joining.discard(i)
            self._stale.discard(i)
            self._outside.pop(i, None)

    def silent(self, i: int, home_m: np.ndarray | None = None) -> None:
        """Vehicle ``i`` is heard no more, or has no position: it keeps its disc and is sent nothing.

        Its disc holds without a measurement (it flies to one of its chain's points); ``home_m``, where
        its link-loss failsafe would land it, is kept clear as well. A vehicle never steered keeps its
        last obstacle disc. It is steered again at its next measurement.
        """
        with self._lock:
            if self._hold[i] is None and i not in self._obstacle:
                return
            self._silent.add(i)
            if home_m is not None:
                self._homes[i] = np.asarray(home_m, dtype=np.float64)

    def obstacle(self, i: int, centre_m: np.ndarray, radius_m: float,
                 home_m: np.ndarray | None = None) -> None:
        """Vehicle ``i`` is not steered by the guard: a disc the others keep away from, until it joins.

        ``home_m``: the column over its home is kept clear as well (it will land there: RTL).
        """
        with self._lock:
            self._hold[i] = None
            self._silent.discard(i)
            self._obstacle[i] = (np.asarray(centre_m, dtype=np.float64), float(radius_m))
            if home_m is None:
                self._homes.pop(i, None)
            else:
                self._homes[i] = np.asarray(home_m, dtype=np.float64)

    def joined(self, i: int) -> bool:
        """Whether vehicle ``i`` is steered by the guard (silent ones included)."""
        return self._hold[i] is not None

    def is_obstacle(self, i: int) -> bool:
        """Whether vehicle ``i`` is a disc the others keep off, not steered (climbing, returning)."""
        return i in self._obstacle

    def is_silent(self, i: int) -> bool:
        """Whether vehicle ``i`` is kept on its last disc, unheard."""
        return i in self._silent

    def centre_m(self, i: int) -> np.ndarray:
        """(2,) the centre of vehicle ``i``'s disc."""
        hold = self._hold[i]
        return hold.centre_m if hold is not None else self._obstacle[i][0]

    def radius_m(self, i: int) -> float:
        """The radius of vehicle ``i``'s disc (``inf`` before its first measurement)."""
        hold = self._hold[i]
        return hold.radius_m if hold is not None else self._obstacle[i][1]

    def bounds(self, i: int) -> Bounds | None:
        """Vehicle ``i``'s bounds (None: not steered)."""
        hold = self._hold[i]
        return None if hold is None else hold.bounds

    # -- what comes back -----------------------------------------------------------------------
    def measure(self, i: int, position_m: np.ndarray, velocity_m_s: np.ndarray, stamp_s: float,
                now_s: float, received_s: float | None = None) -> str | None:
        """A measurement of vehicle ``i``, true at ``stamp_s``; the kind of bound it breaks, if any.

        ``received_s`` is when it arrived, where only that is known (``stamp_s`` then its lower bound:
        received less the largest age); its age is judged from it.
        """
        with self._lock:
            return self._measure(i, position_m, velocity_m_s, stamp_s, now_s, received_s)

    def _measure(self, i: int, position_m: np.ndarray, velocity_m_s: np.ndarray, stamp_s: float,
                 now_s: float, received_s: float | None) -> str | None:
        hold = self._hold[i]
        if hold is None:
            return None
        self._silent.discard(i)
        self._homes.pop(i, None)
        self._velocity[i] = np.asarray(velocity_m_s, dtype=np.float64)[:2]
        self._position[i] = np.asarray(position_m, dtype=np.float64)[:2]
        if now_s - (stamp_s if received_s is None else received_s) > hold.bounds.position_age_s:
            if i not in self._stale:
                self._stale.add(i)
                self.events.append((now_s, i, "position_stale"))
            return "position_stale"
        self._stale.discard(i)
        if hold.measure(position_m, velocity_m_s, stamp_s):
            slow = Bounds(**{**hold.bounds.__dict__, "accel_m_s2": hold.bounds.accel_m_s2 / 2})
            p = np.asarray(position_m, dtype=np.float64)
            velocity = np.asarray(velocity_m_s, dtype=np.float64)[:2]
            needed = float(slow.radius_m(p[:2] - hold.centre_m, velocity))
            hold.radius_m = max(hold.radius_m, needed)
            self._outside[i] = p
            self.events.append((now_s, i, "outside_bounds"))
            return "outside_bounds"
        return None

    def sent(self, i: int, point_m: tuple[float, float] | np.ndarray, now_s: float) -> int:
        """Record that vehicle ``i`` was sent ``point_m`` now; its sequence number."""
        with self._lock:
            hold = self._hold[i]
            assert hold is not None, f"vehicle {i} is not steered by the guard"
            return hold.sent(np.asarray(point_m, dtype=np.float64), now_s)

    def acknowledged(self, i: int, seq: int, now_s: float) -> None:
        """Vehicle ``i`` acknowledged point ``seq`` (received at ``now_s``)."""
        with self._lock:
            hold = self._hold[i]
            if hold is not None:
                hold.acknowledged(seq, now_s)

    def unacknowledged(self, i: int, seq: int, now_s: float) -> None:
        """Point ``seq`` of vehicle ``i`` got no acknowledgement within the bound."""
        with self._lock:
            hold = self._hold[i]
            if hold is not None:
                hold.unacknowledged(seq)
                self.events.append((now_s, i, "command_unacknowledged"))

    # -- decisions -----------------------------------------------------------------------------
    def decide(self, goals_m: np.ndarray, now_s: float) -> list[Decision]:
        """Each vehicle's decision (by index = priority); the points are sent by the caller.

        Args:
            goals_m: (K, 2) where each vehicle should go (NaN: nowhere new).
            now_s: The guard's clock, seconds.
        """
        with self._lock:
            return self._decide(goals_m, now_s)

    def _decide(self, goals_m: np.ndarray, now_s: float) -> list[Decision]:
        k = len(self._hold)
        homes = sorted(self._homes)
        n = k + len(homes)  # each home column kept clear is one more disc, owned by its vehicle
        owner = np.concatenate([np.arange(k), np.asarray(homes, dtype=np.int64)])
        centres, radii = np.zeros((n, 2)), np.full(n, -np.inf)  # -inf: no vehicle (never in the way)
        for i in range(k):
            if self._hold[i] is not None or i in self._obstacle:
                centres[i], radii[i] = self.centre_m(i), self.radius_m(i)
        for m, i in enumerate(homes):
            hold = self._hold[i]
            bounds = hold.bounds if hold is not None else None
            centres[k + m] = self._homes[i]
            radii[k + m] = 0.0 if bounds is None else float(bounds.radius_m(np.zeros(2), np.zeros(2)))
        present = np.isfinite(radii) | (radii == np.inf)
        goals = np.full((n, 2), np.nan)
        goals[:k] = np.array(goals_m, dtype=np.float64).reshape(k, 2)
        steered = np.array([h is not None for h in self._hold] + [False] * len(homes))
        may = np.array([h is not None and h.may_send(now_s) for h in self._hold] + [False] * len(homes))
        for i in list(self._stale) + list(self._outside) + list(self._silent):
            may[i] = False
        goals[~steered] = np.nan
        finals = goals.copy()
        for i, (via, final) in list(self._via.items()):
            if (not steered[i] or not finite_point(goals[i])
                    or not np.all(np.abs(final - goals[i]) <= 1e-8 + 1e-5 * np.abs(goals[i]))  # allclose
                    or float(np.hypot(*(self.centre_m(i) - via))) <= 0.5):
                del self._via[i]  # reached, or its goal changed
            else:
                goals[i] = via
        waited = np.array([now_s - self._held_since.get(i, now_s) for i in range(k)] + [0.0] * len(homes))
        detour = waited >= self.detour_after_s
        apart = present[:, None] & present[None] & (owner[:, None] != owner[None])  # not one's own home
        required = np.where(apart, self.required_m[owner[:, None], owner[None]], -np.inf)
        gaps = _gaps_m(centres, radii)
        parting = apart & np.isfinite(gaps) & (gaps < required)
        parting[k:] = False
        if parting.any():  # parts a vehicle at rest at its point, or already flying straight away
            towards = centres[None] - self._position[:, None]  # (k, n, 2)
            with np.errstate(invalid="ignore", divide="ignore"):  # each one's speed towards each disc
                closing = (np.einsum("knc,kc->kn", towards, self._velocity)
                           / np.hypot(towards[..., 0], towards[..., 1]))
            speed = np.hypot(*self._velocity.T)
            at_rest = ((np.hypot(*(self._position - centres[:k]).T) <= _AT_POINT_M)
                       & (speed <= self.parting_speed_m_s))
            fleeing = -closing >= 0.9 * speed[:, None]  # its velocity points away from that one
            parting[:k] &= ((at_rest[:, None] & ~(closing > 0.5))
                            | (fleeing & (speed > self.parting_speed_m_s)[:, None]))
        order = np.argsort(-waited, kind="stable")  # the longest held first, then by index
        points, _, blockers = choose_points(centres, np.where(present, radii, 0.0), goals, may, required,
                                            detour, self.detour_m, self.area_m, order=order,
                                            max_step_m=self.max_step_m, parting=parting,
                                            parting_step_m=self.parting_step_m,
                                            positions_m=np.vstack([self._position, np.full((n - k, 2),
                                                                                           np.nan)]))
        blockers = np.where(blockers >= k, owner[np.maximum(blockers, 0)], blockers)
        decisions = [self._decision(i, points[i], int(blockers[i]), goals[i], may[i], now_s)
                     for i in range(k)]
        self._note_cycles(decisions, now_s)
        for i, decision in enumerate(decisions):
            if (decision.state == "held" and blockers[i] >= 0 and i not in self._via
                    and now_s - self._held_since.get(i, now_s) >= self.detour_after_s):
                self._go_round(i, int(blockers[i]), finals[i], now_s)
        return decisions

    def _note_cycles(self, decisions: list[Decision], now_s: float) -> None:
        """Record each cycle of holds once while it lasts (its members go round as any held vehicle)."""
        cycles = hold_cycles(np.array([d.blocker if d.state == "held" else -1 for d in decisions]))
        self.deadlocks += [(now_s, cycle) for cycle in cycles if cycle not in self._cycles]
        self._cycles = set(cycles)

    def _go_round(self, i: int, blocker: int, goal: np.ndarray, now_s: float) -> None:
        """Send a vehicle held long by ``blocker`` by a point beside it, with room to pass at each step."""
        here, there = self.centre_m(i), self.centre_m(blocker)
        way = goal - here
        length = float(np.hypot(*way))
        if length < 1e-9 or not math.isfinite(self.radius_m(blocker)):
            return
        across = np.array([-way[1], way[0]]) / length
        reach = self.required_m[i, blocker] + self.radius_m(blocker) + self.detour_m
        points = [there + side * reach * across for side in (1.0, -1.0)]
        if self.area_m is not None:
            points = [q for q in points if bool(np.all((q >= 0.0) & (q <= self.area_m)))]
        if points:
            best = min(points, key=lambda q: float(np.hypot(*(q - here)) + np.hypot(*(goal - q))))
            self._via[i] = (best, goal.copy())
            self._held_since[i] = now_s

    def _decision(self, i: int, point: np.ndarray, blocker: int, goal: np.ndarray, may: bool,
                  now_s: float) -> Decision:
        hold = self._hold[i]
        if hold is None:
            return Decision("idle")
        if i in self._outside:
            stop = self._outside.pop(i)
            return Decision("outside", (float(stop[0]), float(stop[1])), seq=self.sent(i, stop, now_s))
        if i in self._silent:
            return Decision("silent")
        if i in self._stale:
            return Decision("stale")
        if i in self._joining and math.isfinite(hold.radius_m):
            self._joining.discard(i)
            here = hold.centre_m  # its first command: the point it joined at, so its chain starts sent
            return Decision("on", (float(here[0]), float(here[1])), seq=self.sent(i, here, now_s))
        if finite_point(point):
            self._held_since.pop(i, None)
            seq = self.sent(i, point, now_s)
            return Decision("free", (float(point[0]), float(point[1])), blocker, seq)
        arrived = not finite_point(goal) or float(np.hypot(*(goal - hold.centre_m))) <= 1e-3
        if arrived and may and len(hold.chain) > 1:  # its newest point was never acknowledged: again
            here = hold.centre_m
            return Decision("on", (float(here[0]), float(here[1])), seq=self.sent(i, here, now_s))
        if arrived or not may or not math.isfinite(hold.radius_m):
            return Decision("on" if not arrived else "idle")
        self._held_since.setdefault(i, now_s)
        return Decision("held", None, blocker)


def _gaps_m(centres: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """(N, N) the distance between each pair of discs (NaN or -inf with an unknown one)."""
    with np.errstate(invalid="ignore"):
        return np.hypot(*(centres[:, None] - centres[None]).transpose(2, 0, 1)) - radii[:, None] - radii[None]
