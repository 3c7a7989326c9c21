"""Formation moves for the guard's liveness: a whole fleet sent to new places at once, and whether it can go.

:func:`formation_trial` draws one move of ``n`` vehicles (by the seed): a grid translated, a circle
expanded, or a line spread into a grid ahead of it (a launch line), each vehicle sent at once to the
goal a squared-distance assignment gives it (no two straight flights cross). :func:`unguarded_closest_m`
flies the same vehicles without the guard, each sent its goal straight; the move is *separable* when
that flight keeps the minimum, plus both vehicles' hover tolerances, plus 1 m at every instant
(:func:`separable`): a guard that keeps such a fleet waiting costs time it need not.

Examples:
    >>> trial = formation_trial(np.random.default_rng(0), seed=3, n_uavs=5, kind="grid-translated")
    >>> len(trial.starts_m), len(trial.script), trial.n_uavs
    (5, 5, 5)
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial.distance import pdist

from uav_swarm.runs.flight.guard_trial.trial import ALT_M, DT_S, Trial, copter_of, realism_of

__all__ = ["FORMATIONS", "formation_trial", "separable", "unguarded_closest_m"]

FORMATIONS = ("grid-translated", "circle-expanded", "line-spread")
"""The moves :func:`formation_trial` draws from."""
_MARGIN_M = 20.0
_SENT_S = 0.5  # when the goals are sent (the vehicles have hovered and been measured)


def _grid(n: int, spacing_m: float) -> np.ndarray:
    cols = math.ceil(math.sqrt(n))
    return np.array([[(i % cols) * spacing_m, (i // cols) * spacing_m] for i in range(n)])


def _move(rng: np.random.Generator, n: int, kind: str) -> tuple[np.ndarray, np.ndarray]:
    """(starts, goals) of one move, each (n, 2), metres, before it is placed in its area."""
    spacing = float(rng.uniform(9.0, 14.0))
    if kind == "grid-translated":
        starts = _grid(n, spacing)
        angle, length = float(rng.uniform(0.0, 2 * math.pi)), float(rng.uniform(20.0, 80.0))
        return starts, starts + length * np.array([math.cos(angle), math.sin(angle)])
    if kind == "circle-expanded":
        radius = spacing / (2.0 * math.sin(math.pi / n))
        angles = 2 * math.pi * np.arange(n) / n + float(rng.uniform(0.0, 2 * math.pi))
        ring = np.stack([np.cos(angles), np.sin(angles)], axis=1)
        return radius * ring, float(rng.uniform(1.5, 3.0)) * radius * ring
    if kind == "line-spread":
        starts = np.stack([np.arange(n) * spacing, np.zeros(n)], axis=1)
        goals = _grid(n, float(rng.uniform(1.5, 3.0)) * spacing)
        goals = goals - goals.mean(axis=0) + starts.mean(axis=0) + [0.0, float(rng.uniform(20.0, 60.0))]
        return starts, goals
    raise ValueError(f"kind must be one of {', '.join(FORMATIONS)}, got {kind!r}")


def formation_trial(rng: np.random.Generator, seed: int, n_uavs: int, kind: str, autopilot: str = "pointmass",
                    duration_s: float = 60.0) -> Trial:
    """One formation move of ``n_uavs`` vehicles, its settings drawn as the fuzz draws them.

    5-20 m/s, acceleration 2-5 m/s^2, jerk 2-10 m/s^3 (the jerk-limited autopilots), command latency up
    to 1.5 s, positions up to 1 s old at 5 or 10 Hz, noise 0 or 0.2 m; no events, no loss.
    """
    starts, goals = _move(rng, n_uavs, kind)
    rows, cols = linear_sum_assignment(((starts[:, None] - goals[None]) ** 2).sum(axis=-1))
    goals = goals[cols[np.argsort(rows)]]
    low = np.minimum(starts.min(axis=0), goals.min(axis=0)) - _MARGIN_M
    starts, goals = starts - low, goals - low
    side = float(np.maximum(starts.max(axis=0), goals.max(axis=0)).max() + _MARGIN_M)
    trial = Trial(n_uavs=n_uavs, area_m=(side, side), speed_m_s=float(rng.uniform(5.0, 20.0)),
                  accel_m_s2=float(rng.uniform(2.0, 5.0)), latency_s=float(rng.uniform(0.0, 1.5)),
                  age_s=float(rng.uniform(0.0, 1.0)), rate_hz=float(rng.choice([5.0, 10.0])),
                  noise_m=float(rng.choice([0.0, 0.2])), duration_s=duration_s, seed=seed,
                  autopilot=autopilot, starts_m=tuple((float(x), float(y)) for x, y in starts),
                  script=tuple((_SENT_S, i, (float(x), float(y))) for i, (x, y) in enumerate(goals)))
    if autopilot != "pointmass":
        trial = replace(trial, jerk_m_s3=float(rng.uniform(2.0, 10.0)))
    return trial


def unguarded_closest_m(trial: Trial) -> float:
    """The closest two of ``trial``'s vehicles come, true positions, when each is sent its goal straight.

    Only scripted trials with starts (:func:`formation_trial`); flown until every vehicle is within
    ``reach_m`` of its last goal or the trial's duration is over.
    """
    if not trial.starts_m or not trial.script:
        raise ValueError("unguarded_closest_m needs a trial with starts_m and a script")
    rng = np.random.default_rng(trial.seed)
    copters = [copter_of(trial, np.asarray(start), rng.spawn(1)[0]) for start in trial.starts_m]
    script = sorted(trial.script)
    finals = {i: np.asarray(point) for _, i, point in script}
    closest, now_s = math.inf, 0.0
    while now_s <= trial.duration_s:
        while script and script[0][0] <= now_s + 1e-9:
            _, i, point = script.pop(0)
            while not copters[i].send(now_s, np.array([*point, ALT_M])):  # lost: sent again
                pass
        truth = np.array([c.position_m[:2] for c in copters])
        closest = min(closest, float(pdist(truth).min()))
        if not script and all(float(np.hypot(*(truth[i] - g))) <= trial.reach_m for i, g in finals.items()):
            break
        for copter in copters:
            copter.advance(DT_S)
        now_s += DT_S
    return closest


def separable(trial: Trial) -> bool:
    """Whether the unguarded flight keeps the minimum, both hover tolerances and 1 m (module docstring)."""
    hover_m = trial.reach_m + realism_of(trial).tracking_error_bound_m
    return unguarded_closest_m(trial) >= trial.min_separation_m + 2.0 * hover_m + 1.0
