"""One guard trial flown: the guard decides on reports, simulated autopilots fly, a judge watches the truth.

:func:`fly_trial` (:mod:`uav_swarm.runs.flight.guard_trial` says what is flown and judged).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial.distance import pdist

from bridge.simulated.dynamics import PointMassCopter, PositionReport
from uav_swarm.runs.flight.guard_trial.trial import (
    ALT_M,
    DT_S,
    GUARD_EVERY,
    Trial,
    TrialResult,
    Window,
    bounds_of,
    copter_of,
    realism_of,
)
from uav_swarm.world.guard import Bounds, FleetGuard
from uav_swarm.world.separation import draw_apart_m

__all__ = ["fly_trial"]


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
    return trial.reach_m + realism_of(trial).tracking_error_bound_m


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
    target = np.array([*goal_m, ALT_M])
    while not clone.send(clone.now_s, target):
        pass
    while clone.now_s - start_s <= limit_s:
        if float(np.hypot(*(clone.position_m[:2] - goal_m))) <= reach_m:
            return clone.now_s - start_s
        clone.advance(DT_S)
    return math.inf


@dataclass
class _Goal:
    """One goal of one vehicle while it is held."""

    point_m: np.ndarray
    since_s: float
    copter: PointMassCopter | None  # a copy of the vehicle when it was set (None: not a goal to judge)
    gap_m: float = math.inf  # the nearest other goal while this one was held
    until_s: float = math.inf  # when it was replaced
    reached_s: float = math.inf  # when the vehicle first came within reach of it

    @property
    def reached(self) -> bool:
        return self.reached_s < math.inf


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
    k, bounds = trial.n_uavs, bounds_of(trial)
    need = trial.min_separation_m
    if trial.starts_m:
        starts = np.asarray(trial.starts_m, dtype=np.float64)
    else:
        gap_m = need + 2.0 * bounds.position_error_m + 4.0 * bounds.tracking_error_m + 1.0
        starts, scale = _starts(rng, trial, gap_m)
        trial = replace(trial, area_m=(trial.area_m[0] * scale, trial.area_m[1] * scale))
    copters = [copter_of(trial, starts[i], rng.spawn(1)[0]) for i in range(k)]
    guard = FleetGuard(np.full((k, k), need))
    joining = {i: (join_s, np.asarray(point, dtype=np.float64)) for i, join_s, point in trial.joins}
    for i, (_, point) in joining.items():
        copters[i].send(0.0, np.array([*point, ALT_M]))  # outside the guard
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
    steps = int(round(trial.duration_s / DT_S))

    def set_goal(i: int, point: np.ndarray, now_s: float, gaps: bool = True) -> None:
        goals[i].until_s = now_s
        judged.append(goals[i])
        goals[i] = _Goal(np.asarray(point, dtype=np.float64), now_s, copy.deepcopy(copters[i]))
        if gaps:
            note_gaps(i)

    def note_gaps(i: int) -> None:
        for j in range(k):
            if j != i:
                gap = float(np.hypot(*(goals[j].point_m - goals[i].point_m)))
                goals[i].gap_m = min(goals[i].gap_m, gap)
                goals[j].gap_m = min(goals[j].gap_m, gap)

    for step in range(steps + 1):
        now_s = step * DT_S
        fresh = []  # goals scripted for the same instant are set together, then compared
        while script and script[0][0] <= now_s + 1e-9:
            _, i, scripted = script.pop(0)
            set_goal(i, np.asarray(scripted), now_s, gaps=False)
            fresh.append(i)
        for i in fresh:
            note_gaps(i)
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
        if step % GUARD_EVERY == 0:
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
                               and copters[i].send(now_s, np.array([*decision.point_m, ALT_M])))
                    due_s = now_s + (trial.latency_s + DT_S if arrived else bounds.command_delay_s)
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
            if not goals[i].reached and float(np.hypot(*(truth[i] - goals[i].point_m))) <= trial.reach_m:
                goals[i].reached_s = now_s
        if step < steps:
            for copter in copters:
                copter.advance(DT_S)
    for goal in goals:  # the goals held at the end
        goal.until_s = trial.duration_s
        judged.append(goal)
    reachable = reached = timely = 0
    for goal in judged:
        held_s = goal.until_s - goal.since_s
        if goal.copter is None or goal.gap_m < separable or held_s < 2.0:
            continue
        unguarded_s = _unguarded_s(goal.copter, goal.point_m, trial.reach_m, (held_s - 2.0) / 2.0)
        if unguarded_s < math.inf:
            reachable += 1
            reached += int(goal.reached)
            timely += int(goal.reached_s - goal.since_s <= trial.within_factor * unguarded_s + 1e-9)
    kinds: dict[str, int] = {}
    for _, _, kind in guard.events:
        kinds[kind] = kinds.get(kind, 0) + 1
    return TrialResult(closest, trial.area_m, reachable, reached, kinds.get("outside_bounds", 0), holds,
                       pairs_under=len(under), outside=len(outside), outside_steps=outside_steps,
                       outside_m=max(outside.values(), default=0.0), events=kinds, timely=timely)


