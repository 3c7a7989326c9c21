"""The guard trials flown by the fuzz and the tests: named cases, the worst bounds, random draws.

Examples:
    >>> trial = random_trial(np.random.default_rng(0), seed=1, events=True)
    >>> 2 <= trial.n_uavs <= 10, event_of(trial) in ("none", *EVENTS)
    (True, True)
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from uav_swarm.runs.flight.guard_trial.trial import EVENTS, JOIN_AHEAD_M, Trial
from uav_swarm.world.separation import max_spread_m

__all__ = ["EVENT_TRIALS", "LIVENESS_TRIALS", "NAMED_TRIALS", "WORST_BOUNDS", "event_of", "random_trial"]

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
              area_m=(200.0, 200.0), starts_m=((20.0, 100.0), (JOIN_AHEAD_M, 100.0)),
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


def _line(n: int, spacing_m: float, y_m: float, x0_m: float = 20.0) -> tuple[tuple[float, float], ...]:
    return tuple((x0_m + i * spacing_m, y_m) for i in range(n))


_FLEET = Trial(n_uavs=2, speed_m_s=10.0, accel_m_s2=2.5, autopilot="arducopter", latency_s=0.4, age_s=0.2,
               area_m=(120.0, 120.0), duration_s=60.0)
_SPREAD = ((20.0, 60.0), (32.0, 85.0), (45.0, 60.0), (58.0, 85.0), (70.0, 60.0))  # no crossings
LIVENESS_TRIALS: dict[str, Trial] = {
    "launch-line": replace(_FLEET, n_uavs=5, starts_m=_line(5, 9.0, 20.0, 27.0),
                           script=tuple((0.5, i, p) for i, p in enumerate(_SPREAD))),
    "crossing": replace(_FLEET, starts_m=((10.0, 60.0), (75.0, 10.0)),
                        script=((0.5, 0, (110.0, 60.0)), (0.5, 1, (75.0, 110.0)))),
    "swap": replace(_FLEET, starts_m=((20.0, 55.0), (100.0, 65.0)),
                    script=((0.5, 0, (100.0, 55.0)), (0.5, 1, (20.0, 65.0)))),
    "held-by-a-parked-one": replace(_FLEET, starts_m=((10.0, 60.0), (60.0, 70.0)),
                                    script=((0.5, 0, (110.0, 60.0)),)),
    "the-return": replace(_FLEET, n_uavs=5, starts_m=_SPREAD,
                          script=tuple((0.5, i, p) for i, p in enumerate(_line(5, 9.0, 20.0, 27.0)))),
}
"""The packaged fleet's moves (five ArduCopter-like vehicles at 10 m/s, 2.5 m/s^2, 0.4 s latency) that a
guard must not slow beyond 1.5 times their unguarded time: a launch line 9 m apart spread to first
targets, two vehicles crossing (the first passes the crossing point 15 m before the other reaches it),
two swapping on lanes 10 m apart, one passing 10 m beside a parked one, and the return to the line."""
