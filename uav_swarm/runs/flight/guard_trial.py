"""The separation guard flown against simulated autopilots in simulated time, judged on true positions.

:func:`fly_trial` flies one :class:`Trial`: K simulated vehicles (``autopilot``: the point mass
:class:`bridge.simulated.dynamics.PointMassCopter`, or the jerk-limited
:class:`~bridge.simulated.jerk_limited.ArduCopterLikeCopter` and
:class:`~bridge.simulated.jerk_limited.PX4LikeCopter`;
their own speed, acceleration and jerk, command latency and loss, late and noisy positions, wind),
started at rest and apart, each given a new goal every 1-10 s (kept apart from the others' goals); a
:class:`uav_swarm.world.guard.FleetGuard` decides 10 times a second on the vehicles' *reports* and its
points reach them ``command_latency_s`` later (an acknowledgement comes back with the command's effect;
a lost one is never acknowledged). The guard is told the limits the vehicles report: the acceleration
(PX4 applies it on each axis) and the jerk (``PSC_JERK_XY``, ``MPC_JERK_AUTO``; none for the point mass).

**Events** a trial may add (the named cases and random flights with ``events=True``):

- *silent*: a vehicle's link is down both ways for a while (no reports, its commands and their
  acknowledgements lost) while it flies on to the last point it got;
- *no fix*: its reports carry no position for a while (the guard is given nothing); commands still arrive;
- *join in flight*: a vehicle flies to a point sent outside the guard and is taken under the guard
  (``join`` at its measured position, with the point it flies to) while still flying there;
- *stale first rows*: a vehicle's reports are older than the guard's ``position_age_s`` for its first seconds;
- *reversal*: when a vehicle first reaches a speed, its goal moves behind it (it is still accelerating away).

**The judge** is independent of the guard: every 0.05 s, the **true** positions of the vehicles under
the guard, their pair distances by ``scipy.spatial.distance.pdist`` (the closest pair, and the pairs
that came under the minimum, once both are under the guard and have been seen the minimum apart: a
vehicle joined in flight closer than that is the guard's to separate, not its failure), and each
vehicle's true position against the set the guard certifies for it (``centre_m``, ``radius_m``): a
vehicle found outside it is counted, whatever the guard reported.

**Liveness**: the share of *separable* goals reached (the vehicle's true position within ``reach_m`` of
it while it was its goal). A goal is separable when it stays at least the minimum, plus both vehicles'
hover tolerances (``reach_m`` and the wind's tracking error), plus 1 m from every other vehicle's goal
while it is held, and it is held at least twice as long as the same vehicle, unguarded, needs to
reach it (a copy of it, at that moment, sent the goal straight), plus 2 s. A guard that holds everyone
fails it.

The guard is used through four calls only (``join``, ``measure``, ``decide``; ``sent`` points come back
by ``acknowledged`` / ``unacknowledged``) and judged through ``centre_m`` / ``radius_m``; the few
lines that touch it are :func:`_join`, :func:`_measure` and :func:`_outside_m`.

Examples:
    >>> result = fly_trial(Trial(n_uavs=2, area_m=(60.0, 60.0), seed=0, duration_s=20.0))
    >>> result.closest_m >= 5.0, result.breaches, result.outside
    (True, 0, 0)
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial.distance import pdist

from bridge.simulated.dynamics import AutopilotLimits, PointMassCopter, PositionReport, Realism
from bridge.simulated.jerk_limited import (
    ARDUCOPTER_JERK,
    PX4_JERK,
    ArduCopterLikeCopter,
    JerkLimits,
    PX4LikeCopter,
)
from uav_swarm.world.guard import Bounds, FleetGuard
from uav_swarm.world.separation import draw_apart_m, max_spread_m

__all__ = ["AUTOPILOTS", "EVENTS", "EVENT_TRIALS", "NAMED_TRIALS", "Trial", "TrialResult", "WORST_BOUNDS",
           "event_of", "fly_trial", "random_trial"]

_DT_S = 0.05  # the judge's step (20 Hz) and the integration step
_GUARD_EVERY = 2  # a guard decision every 2 steps (10 Hz)
_ALT_M = 10.0
AUTOPILOTS = ("pointmass", "arducopter", "px4")
"""The simulated autopilots a trial may fly."""
EVENTS = ("silent", "no-fix", "join-in-flight", "stale-first-rows", "reversal")
"""The events a random trial may add (module docstring)."""
_JOIN_AHEAD_M = 50.0
_DEFAULT_JERK = {"pointmass": math.inf, "arducopter": ARDUCOPTER_JERK.jerk_m_s3, "px4": PX4_JERK.jerk_m_s3}

Window = tuple[int, float, float]


@dataclass(frozen=True)
class Trial:
    """One simulated flight: the fleet, the autopilots, the link, the guard's stated bounds, its events.

    ``stated_accel_m_s2`` is what the guard is told (0: the autopilots' own ``accel_m_s2``); a larger
    value than the real one puts the flight outside the bounds. ``jerk_m_s3`` is the autopilots' jerk
    limit (0: the autopilot's default; the point mass has none). ``script`` replaces random goals by
    ``(time_s, vehicle, (x, y))`` goals; ``starts_m`` replaces random starts.

    Events (module docstring): ``silent`` and ``no_fix`` are ``(vehicle, from_s, to_s)``; ``joins`` are
    ``(vehicle, join_s, (x, y))``, the point it flies to from the start, outside the guard, until it
    joins; ``stale_first_s`` are ``(vehicle, seconds)``; ``reversals`` are ``(vehicle, speed_m_s, metres)``:
    when its true speed first reaches ``speed_m_s``, its goal becomes the point that far behind it.
    """

    n_uavs: int = 4
    area_m: tuple[float, float] = (60.0, 60.0)
    min_separation_m: float = 5.0
    speed_m_s: float = 10.0
    accel_m_s2: float = 2.5
    stated_accel_m_s2: float = 0.0
    autopilot: str = "pointmass"
    jerk_m_s3: float = 0.0
    latency_s: float = 0.4
    loss: float = 0.0
    age_s: float = 0.2
    rate_hz: float = 10.0
    noise_m: float = 0.0
    wind_m_s: float = 0.0
    gust_m_s: float = 0.0
    goal_every_s: tuple[float, float] = (1.0, 10.0)
    duration_s: float = 60.0
    seed: int = 0
    reach_m: float = 1.0
    script: tuple[tuple[float, int, tuple[float, float]], ...] = ()
    starts_m: tuple[tuple[float, float], ...] = ()
    silent: tuple[Window, ...] = ()
    no_fix: tuple[Window, ...] = ()
    joins: tuple[tuple[int, float, tuple[float, float]], ...] = ()
    stale_first_s: tuple[tuple[int, float], ...] = ()
    reversals: tuple[tuple[int, float, float], ...] = ()

    def __post_init__(self) -> None:
        if self.autopilot not in AUTOPILOTS:
            raise ValueError(f"autopilot must be one of {', '.join(AUTOPILOTS)}, got {self.autopilot!r}")

    @property
    def jerk(self) -> float:
        """The autopilots' jerk limit, m/s^3 (``inf``: none)."""
        return self.jerk_m_s3 or _DEFAULT_JERK[self.autopilot]


@dataclass
class TrialResult:
    """What the judge saw.

    Attributes:
        closest_m: The closest pair of vehicles under the guard (once seen the minimum apart), true positions.
        area_m: The area flown (grown where the starts did not fit).
        goals: Separable goals (module docstring).
        reached: Of those, the goals reached.
        breaches: ``outside_bounds`` events the guard reported.
        holds: Decisions that turned a vehicle to ``"held"``.
        pairs_under: Pairs of vehicles that came closer than the minimum.
        outside: Vehicles the judge found outside the set the guard certified for them.
        outside_steps: Judge steps (0.05 s) a vehicle was found outside it, summed over the vehicles.
        outside_m: The furthest a vehicle was found outside it, metres.
        events: Every kind of event the guard reported, with its count.
    """

    closest_m: float
    area_m: tuple[float, float]
    goals: int
    reached: int
    breaches: int
    holds: int
    pairs_under: int = 0
    outside: int = 0
    outside_steps: int = 0
    outside_m: float = 0.0
    events: dict[str, int] = field(default_factory=dict)

    @property
    def liveness(self) -> float:
        """Share of the separable goals that were reached (1 with none)."""
        return self.reached / self.goals if self.goals else 1.0


def _bounds(trial: Trial) -> Bounds:
    realism = _realism(trial)
    noise = 6.0 * trial.noise_m * math.sqrt(2.0)  # 6 sigma on each axis: a bound in practice
    tracking = realism.tracking_error_bound_m
    return Bounds(accel_m_s2=trial.stated_accel_m_s2 or trial.accel_m_s2, jerk_m_s3=trial.jerk,
                  position_error_m=noise,
                  velocity_error_m_s=2.0 * tracking / realism.wind_response_s if tracking else 0.0,
                  tracking_error_m=tracking, command_delay_s=trial.latency_s + 2 * _DT_S,
                  position_age_s=trial.age_s + 1.0 / trial.rate_hz + 2 * _DT_S)


def _realism(trial: Trial) -> Realism:
    return Realism(command_latency_s=trial.latency_s, command_loss=trial.loss, position_age_s=trial.age_s,
                   position_rate_hz=trial.rate_hz, position_noise_m=trial.noise_m, wind_m_s=trial.wind_m_s,
                   gust_m_s=trial.gust_m_s)


def _copter(trial: Trial, start_m: np.ndarray, rng: np.random.Generator) -> PointMassCopter:
    limits = AutopilotLimits(trial.speed_m_s, trial.accel_m_s2, climb_m_s=3.0, descent_m_s=1.5)
    position = np.array([*start_m, _ALT_M])
    if trial.autopilot == "pointmass":
        return PointMassCopter(position, limits, _realism(trial), rng)
    jerk = JerkLimits(jerk_m_s3=trial.jerk, vertical_jerk_m_s3=trial.jerk)
    kind = ArduCopterLikeCopter if trial.autopilot == "arducopter" else PX4LikeCopter
    return kind(position, limits, _realism(trial), rng, jerk)


# -- the guard's interface, in one place --------------------------------------------------------
def _join(guard: FleetGuard, i: int, report: PositionReport, bounds: Bounds, now_s: float,
          flying_to_m: np.ndarray | None = None) -> None:
    """Take vehicle ``i`` under the guard where its report puts it, with the point it may still fly to.

    As ``fly`` does: where its take-off left it, or the point it was last sent.
    """
    earlier = () if flying_to_m is None else (np.asarray(flying_to_m, dtype=np.float64),)
    guard.join(i, np.asarray(report.position_m[:2]), bounds, now_s=now_s, earlier_m=earlier)


def _measure(guard: FleetGuard, i: int, report: PositionReport | None, now_s: float) -> None:
    """Give the guard a report (None: the vehicle reported no position, or nothing reached us)."""
    if report is not None:
        guard.measure(i, report.position_m[:2], report.velocity_m_s[:2], report.stamp_s, now_s)


def _outside_m(guard: FleetGuard, i: int, truth_m: np.ndarray) -> float:
    """How far vehicle ``i``'s true position lies outside its certified set (<= 0: inside)."""
    radius = guard.radius_m(i)
    if not math.isfinite(radius):
        return -math.inf
    return float(np.hypot(*(truth_m - guard.centre_m(i)))) - radius


# -- goals ----------------------------------------------------------------------------------------
def _hover_m(trial: Trial) -> float:
    """A hovering vehicle's tolerance: ``reach_m`` and the wind's tracking error."""
    return trial.reach_m + _realism(trial).tracking_error_bound_m


def _separable_m(trial: Trial) -> float:
    """How far a goal keeps from every other goal to be separable (module docstring)."""
    return trial.min_separation_m + 2.0 * _hover_m(trial) + 1.0


def _draw_goal(rng: np.random.Generator, trial: Trial, others: np.ndarray) -> np.ndarray | None:
    area = np.asarray(trial.area_m)
    for _ in range(50):
        goal = rng.uniform(0.0, area)
        if others.size == 0 or np.hypot(*(others - goal).T).min() >= _separable_m(trial):
            return goal
    return None


def _unguarded_s(copter: PointMassCopter, goal_m: np.ndarray, reach_m: float, limit_s: float) -> float:
    """Seconds the vehicle, as it is now, needs to come within ``reach_m`` of its goal flown straight.

    A copy of it is sent the goal (again while lost) and flown; ``inf`` beyond ``limit_s``.
    """
    clone = copy.deepcopy(copter)
    start_s = clone.now_s
    target = np.array([*goal_m, _ALT_M])
    while not clone.send(clone.now_s, target):
        pass
    while clone.now_s - start_s <= limit_s:
        if float(np.hypot(*(clone.position_m[:2] - goal_m))) <= reach_m:
            return clone.now_s - start_s
        clone.advance(_DT_S)
    return math.inf


@dataclass
class _Goal:
    """One goal of one vehicle while it is held."""

    point_m: np.ndarray
    since_s: float
    copter: PointMassCopter | None  # a copy of the vehicle when it was set (None: not a goal to judge)
    gap_m: float = math.inf  # the nearest other goal while this one was held
    until_s: float = math.inf  # when it was replaced
    reached: bool = False


def _starts(rng: np.random.Generator, trial: Trial, gap_m: float) -> tuple[np.ndarray, float]:
    """Random starts ``gap_m`` apart, and the scale of the area they needed (1: the trial's own area).

    Where random draws do not fit them, the area grows by 5 % at a time (the scale says how much).
    """
    k, scale = trial.n_uavs, 1.0
    while True:
        try:
            area = np.asarray(trial.area_m) * scale
            return draw_apart_m(rng, k, area, np.full((k, k), gap_m), max_tries=2000), scale
        except ValueError:
            scale *= 1.05


def _in(windows: tuple[Window, ...], i: int, now_s: float) -> bool:
    return any(v == i and start <= now_s < end for v, start, end in windows)


def fly_trial(trial: Trial) -> TrialResult:
    """Fly one trial (module docstring)."""
    rng = np.random.default_rng(trial.seed)
    k, bounds = trial.n_uavs, _bounds(trial)
    need = trial.min_separation_m
    if trial.starts_m:
        starts = np.asarray(trial.starts_m, dtype=np.float64)
    else:
        gap_m = need + 2.0 * bounds.position_error_m + 4.0 * bounds.tracking_error_m + 1.0
        starts, scale = _starts(rng, trial, gap_m)
        trial = replace(trial, area_m=(trial.area_m[0] * scale, trial.area_m[1] * scale))
    copters = [_copter(trial, starts[i], rng.spawn(1)[0]) for i in range(k)]
    guard = FleetGuard(np.full((k, k), need))
    joining = {i: (join_s, np.asarray(point, dtype=np.float64)) for i, join_s, point in trial.joins}
    for i, (_, point) in joining.items():
        copters[i].send(0.0, np.array([*point, _ALT_M]))  # outside the guard
    stale_until = dict(trial.stale_first_s)
    for i in range(k):
        if i not in joining:
            _join(guard, i, copters[i].report(), bounds, 0.0)
    goals = [_Goal(starts[i].copy(), 0.0, None) for i in range(k)]
    next_goal_s = rng.uniform(*trial.goal_every_s, size=k) if not trial.script else np.full(k, np.inf)
    script = sorted(trial.script)
    reversals = {i: (speed, back) for i, speed, back in trial.reversals}
    acks: list[tuple[float, int, int, bool]] = []  # (due_s, vehicle, seq, acknowledged)
    judged: list[_Goal] = []
    holds, closest = 0, math.inf
    under: set[tuple[int, int]] = set()
    apart: set[tuple[int, int]] = set()  # pairs under the guard seen at least the minimum apart
    outside: dict[int, float] = {}
    outside_steps = 0
    states = ["idle"] * k
    separable = _separable_m(trial)
    steps = int(round(trial.duration_s / _DT_S))

    def set_goal(i: int, point: np.ndarray, now_s: float) -> None:
        goals[i].until_s = now_s
        judged.append(goals[i])
        goals[i] = _Goal(np.asarray(point, dtype=np.float64), now_s, copy.deepcopy(copters[i]))
        for j in range(k):
            if j != i:
                gap = float(np.hypot(*(goals[j].point_m - goals[i].point_m)))
                goals[i].gap_m = min(goals[i].gap_m, gap)
                goals[j].gap_m = min(goals[j].gap_m, gap)

    for step in range(steps + 1):
        now_s = step * _DT_S
        while script and script[0][0] <= now_s + 1e-9:
            _, i, scripted = script.pop(0)
            set_goal(i, np.asarray(scripted), now_s)
        for due_uav in np.flatnonzero(next_goal_s <= now_s + 1e-9):
            i = int(due_uav)
            drawn = _draw_goal(rng, trial, np.array([g.point_m for j, g in enumerate(goals) if j != i]))
            if drawn is not None:
                set_goal(i, drawn, now_s)
            next_goal_s[i] = now_s + rng.uniform(*trial.goal_every_s)
        for i, (speed, back) in list(reversals.items()):
            velocity = copters[i].velocity_m_s[:2]
            if float(np.hypot(*velocity)) >= speed:
                del reversals[i]
                behind = copters[i].position_m[:2] - velocity / float(np.hypot(*velocity)) * back
                set_goal(i, np.clip(behind, 0.0, np.asarray(trial.area_m)), now_s)
        for i, (join_s, point) in list(joining.items()):
            if now_s >= join_s - 1e-9:
                del joining[i]
                _join(guard, i, copters[i].report(), bounds, now_s, point)
        for due in [a for a in acks if a[0] <= now_s + 1e-9]:
            acks.remove(due)
            if due[3] and not _in(trial.silent, due[1], now_s):
                guard.acknowledged(due[1], due[2], due[0])
            else:
                guard.unacknowledged(due[1], due[2], due[0])
        if step % _GUARD_EVERY == 0:
            for i, copter in enumerate(copters):
                report: PositionReport | None = copter.report()
                if _in(trial.silent, i, now_s) or _in(trial.no_fix, i, now_s):
                    report = None
                elif report is not None and now_s < stale_until.get(i, 0.0):
                    report = report._replace(stamp_s=report.stamp_s - bounds.position_age_s - 1.0)
                if guard.joined(i):
                    _measure(guard, i, report, now_s)
            targets = np.array([g.point_m for g in goals])
            for i, decision in enumerate(guard.decide(targets, now_s)):
                holds += int(decision.state == "held" and states[i] != "held")
                states[i] = decision.state
                if decision.point_m is not None:
                    arrived = (not _in(trial.silent, i, now_s)
                               and copters[i].send(now_s, np.array([*decision.point_m, _ALT_M])))
                    due_s = now_s + (trial.latency_s + _DT_S if arrived else bounds.command_delay_s)
                    acks.append((due_s, i, decision.seq, arrived))
        truth = np.array([c.position_m[:2] for c in copters])
        under_guard = [i for i in range(k) if guard.joined(i)]
        if len(under_guard) >= 2:
            distances = pdist(truth[under_guard])
            pairs = [(a, b) for n, a in enumerate(under_guard) for b in under_guard[n + 1:]]
            for pair, d in zip(pairs, distances, strict=True):
                if d >= need:
                    apart.add(pair)
                elif pair in apart:
                    under.add(pair)
            judged_d = [d for pair, d in zip(pairs, distances, strict=True) if pair in apart]
            closest = min(closest, float(min(judged_d, default=math.inf)))
        for i in under_guard:
            excess = _outside_m(guard, i, truth[i])
            if excess > 1e-6:
                outside[i] = max(outside.get(i, 0.0), excess)
                outside_steps += 1
        for i in range(k):
            goals[i].reached |= float(np.hypot(*(truth[i] - goals[i].point_m))) <= trial.reach_m
        if step < steps:
            for copter in copters:
                copter.advance(_DT_S)
    for goal in goals:  # the goals held at the end
        goal.until_s = trial.duration_s
        judged.append(goal)
    reachable = reached = 0
    for goal in judged:
        held_s = goal.until_s - goal.since_s
        if goal.copter is None or goal.gap_m < separable or held_s < 2.0:
            continue
        if _unguarded_s(goal.copter, goal.point_m, trial.reach_m, (held_s - 2.0) / 2.0) < math.inf:
            reachable += 1
            reached += int(goal.reached)
    kinds: dict[str, int] = {}
    for _, _, kind in guard.events:
        kinds[kind] = kinds.get(kind, 0) + 1
    return TrialResult(closest, trial.area_m, reachable, reached, kinds.get("outside_bounds", 0), holds,
                       pairs_under=len(under), outside=len(outside), outside_steps=outside_steps,
                       outside_m=max(outside.values(), default=0.0), events=kinds)



_TURN = Trial(n_uavs=2, speed_m_s=12.0, accel_m_s2=2.5, latency_s=0.4, age_s=0.2, duration_s=60.0,
              area_m=(200.0, 200.0), starts_m=((0.0, 100.0), (70.0, 112.0)),
              script=((0.0, 0, (190.0, 100.0)), (6.0, 0, (20.0, 170.0))))
_CROSS = Trial(n_uavs=2, speed_m_s=15.0, accel_m_s2=2.5, latency_s=0.4, age_s=0.2, duration_s=60.0,
               area_m=(200.0, 200.0), starts_m=((0.0, 100.0), (100.0, 0.0)),
               script=((0.0, 0, (200.0, 100.0)), (0.0, 1, (100.0, 200.0))))
_OVERSHOOT = Trial(n_uavs=3, speed_m_s=15.0, accel_m_s2=2.5, latency_s=0.4, age_s=0.2, duration_s=60.0,
                   area_m=(200.0, 200.0), starts_m=((0.0, 100.0), (100.0, 100.0), (100.0, 50.0)),
                   script=((0.0, 0, (93.0, 100.0)), (3.0, 2, (100.0, 160.0)), (5.0, 0, (180.0, 100.0))))
_REVERSAL = Trial(n_uavs=2, speed_m_s=15.0, accel_m_s2=2.5, latency_s=0.4, age_s=0.2, duration_s=60.0,
                  area_m=(300.0, 200.0), starts_m=((20.0, 100.0), (250.0, 190.0)),
                  script=((0.0, 0, (120.0, 100.0)),), reversals=((0, 12.0, 40.0),))
_PASSING = dict(n_uavs=3, speed_m_s=12.0, accel_m_s2=2.5, latency_s=0.4, age_s=0.2, duration_s=45.0,
                area_m=(200.0, 200.0), starts_m=((20.0, 100.0), (100.0, 20.0), (170.0, 60.0)),
                script=((0.0, 0, (180.0, 100.0)), (4.0, 1, (100.0, 180.0)), (6.0, 2, (20.0, 140.0))))
_JOIN = Trial(n_uavs=2, speed_m_s=12.0, accel_m_s2=2.5, latency_s=0.4, age_s=0.2, duration_s=30.0,
              area_m=(200.0, 200.0), starts_m=((20.0, 100.0), (_JOIN_AHEAD_M, 100.0)),
              joins=((0, 3.0, (180.0, 100.0)),))
_STALE = Trial(n_uavs=2, speed_m_s=12.0, accel_m_s2=2.5, latency_s=0.4, age_s=0.2, duration_s=40.0,
               area_m=(200.0, 200.0), starts_m=((20.0, 100.0), (100.0, 100.0)),
               script=((0.0, 0, (180.0, 100.0)),), stale_first_s=((1, 4.0),))
NAMED_TRIALS: dict[str, Trial] = {
    "turn-at-12-m-s-beside-a-hover": _TURN,
    "crossing-at-15-m-s": _CROSS,
    "held-with-overshoot": _OVERSHOOT,
}
"""Scripted flights (goals by time) that brought an earlier guard under the minimum: a turn at 12 m/s
beside a hovering vehicle, a crossing at 15 m/s, a vehicle held on its way with overshoot."""
EVENT_TRIALS: dict[str, Trial] = {
    "reversal-at-12-m-s": _REVERSAL,
    "silent-for-12-s": Trial(**_PASSING, silent=((0, 3.0, 15.0),)),  # type: ignore[arg-type]
    "no-fix-for-12-s": Trial(**_PASSING, no_fix=((0, 3.0, 15.0),)),  # type: ignore[arg-type]
    "join-in-flight": _JOIN,
    "stale-first-rows": _STALE,
}
"""Scripted flights with an event each: a point behind a vehicle still accelerating away at 12 m/s (its
goal 100 m ahead: the guard's point ahead is close enough for a point behind it to follow in one step);
a vehicle silent, or without a fix, for 12 s while the others cross its way; a vehicle taken under the
guard while it flies at a vehicle hovering ahead; a hovering vehicle whose first 4 s of reports are too
old, another sent through it."""
WORST_BOUNDS: dict[str, dict[str, float]] = {
    "braking-2.5": {"accel_m_s2": 2.5},
    "braking-2": {"accel_m_s2": 2.0},
    "positions-1-s-old": {"age_s": 1.0},
    "round-trip-1.5-s": {"latency_s": 1.5},
    "all-at-once": {"accel_m_s2": 2.0, "age_s": 1.0, "latency_s": 1.5, "loss": 0.2, "rate_hz": 5.0},
}
"""The worst bounds each named case (and event case) is flown with."""


def random_trial(rng: np.random.Generator, seed: int, duration_s: float = 60.0, autopilot: str = "pointmass",
                 events: bool = False) -> Trial:
    """A trial drawn within the guard's tested bounds.

    2-10 vehicles, 5-20 m/s, acceleration 2-5 m/s^2, jerk 2-10 m/s^3 (the jerk-limited autopilots),
    command latency up to 1.5 s (5 % of commands lost), positions up to 1 s old, square areas from the
    tightest the fleet check accepts for 6 m between starts (the minimum and a metre) up to 200 m; with
    ``events``, one of :data:`EVENTS` for one vehicle (or none, one flight in six): silent or without a
    fix for 5-20 s from 2 s to half the flight, joined after 1-4 s, stale first rows for 1-5 s, or a
    reversal at 50-90 % of its speed to 10-40 m behind it.
    """
    n = int(rng.integers(2, 11))
    tightest = 6.0 / max_spread_m(n, 1.0, 1.0)  # the fleet check's limit for 6 m between starts
    side = float(np.exp(rng.uniform(np.log(tightest), np.log(200.0))))
    trial = Trial(n_uavs=n, area_m=(side, side), speed_m_s=float(rng.uniform(5.0, 20.0)),
                  accel_m_s2=float(rng.uniform(2.0, 5.0)), latency_s=float(rng.uniform(0.0, 1.5)),
                  loss=float(rng.choice([0.0, 0.05])), age_s=float(rng.uniform(0.0, 1.0)),
                  rate_hz=float(rng.choice([5.0, 10.0])), noise_m=float(rng.choice([0.0, 0.2])),
                  duration_s=duration_s, seed=seed, autopilot=autopilot)
    if autopilot != "pointmass":
        trial = replace(trial, jerk_m_s3=float(rng.uniform(2.0, 10.0)))
    if not events:
        return trial
    kind = int(rng.integers(0, len(EVENTS) + 1))
    i = int(rng.integers(0, n))
    start = float(rng.uniform(2.0, max(2.0, duration_s / 2.0)))
    window = ((i, start, start + float(rng.uniform(5.0, 20.0))),)
    point = (float(rng.uniform(0.0, side)), float(rng.uniform(0.0, side)))
    return [replace(trial, silent=window), replace(trial, no_fix=window),
            replace(trial, joins=((i, float(rng.uniform(1.0, 4.0)), point),)),
            replace(trial, stale_first_s=((i, float(rng.uniform(1.0, 5.0))),)),
            replace(trial, reversals=((i, float(rng.uniform(0.5, 0.9)) * trial.speed_m_s,
                                       float(rng.uniform(10.0, 40.0))),)),
            trial][kind]


def event_of(trial: Trial) -> str:
    """The kind of event a trial has (``"none"``: none)."""
    fields = {"silent": trial.silent, "no-fix": trial.no_fix, "join-in-flight": trial.joins,
              "stale-first-rows": trial.stale_first_s, "reversal": trial.reversals}
    return next((name for name, value in fields.items() if value), "none")
