"""The guard's liveness on the packaged fleet's moves: kept apart, not slowed past 1.5x the unguarded flight.

Each case (:data:`uav_swarm.runs.flight.guard_trial.cases.LIVENESS_TRIALS`) is flown in simulated time by
five ArduCopter-like autopilots and judged on true positions every 0.05 s; the unguarded flight of the same
vehicles is the reference (a case must be separable: flown straight, its vehicles keep the minimum, both
hover tolerances and 1 m).
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

from uav_swarm.runs.flight.guard_trial import Trial, TrialResult, fly_trial, formation_trial, separable
from uav_swarm.runs.flight.guard_trial.cases import LIVENESS_TRIALS as CASES
from uav_swarm.runs.flight.guard_trial.formation import unguarded_closest_m

_SLOW = {
    "launch-line": "1 of 5 in time: the certified discs (braking distance in every direction) of neighbours "
                   "9 m apart overlap as soon as they move, so they leave one after another",
    "crossing": "1 of 2 in time: the second waits until the first's disc has passed the crossing",
    "swap": "0 of 2 in time: lanes 10 m apart are far closer than two moving discs",
    "held-by-a-parked-one": "0 of 1 in time: a moving disc does not pass 10 m beside a hovering vehicle",
    "the-return": "1 of 5 in time: as the launch line, in reverse",
}
"""Cases today's guard does not fly in time, with what was measured (strict xfail)."""


@functools.cache
def _flown(case: str) -> TrialResult:
    return fly_trial(CASES[case])


@pytest.mark.parametrize("case", list(CASES))
def test_case_is_separable_and_kept_apart(case: str) -> None:
    assert unguarded_closest_m(CASES[case]) >= 8.0  # the minimum 5 m, two hover tolerances of 1 m, 1 m
    result = _flown(case)
    assert result.goals == len(CASES[case].script)  # every goal judged separable by the fuzz's rule too
    assert result.closest_m >= CASES[case].min_separation_m
    assert result.pairs_under == 0 and result.outside == 0 and result.breaches == 0
    assert result.reached == result.goals  # within the flight (60 s), if not in time


@pytest.mark.parametrize("case", [pytest.param(c, marks=pytest.mark.xfail(strict=True, reason=_SLOW[c]))
                                  if c in _SLOW else c for c in CASES])
def test_case_in_time(case: str) -> None:
    result = _flown(case)
    assert result.timely == result.goals, (result.timely, result.goals)


def test_a_formation_move_crossing_itself_is_not_separable() -> None:
    move = formation_trial(np.random.default_rng(0), seed=1, n_uavs=2, kind="grid-translated")
    starts = move.starts_m
    swap = ((0.5, 0, starts[1]), (0.5, 1, starts[0]))  # head on, through each other
    through = Trial(**{**move.__dict__, "script": swap})
    assert not separable(through)
    assert separable(move) == (unguarded_closest_m(move) >= 8.0)
