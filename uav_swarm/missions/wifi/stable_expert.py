"""A strategy-2 expert that is a function of its crowd: the consensus of seeded jittered solves.

The strategy-2 experts (the search, and the capacitated expert under admission control) answer a
discrete question (which groups get a UAV, and how many) by a discrete search: a user a few
centimetres across a coverage radius changes a count, the count changes a ranking, and the ranking
sends the search to another, nearly as good placement. Two crowds a network's raster cannot tell
apart then get different demonstrations, which no network can both learn
(:mod:`learning.expert_stability` measures how often).

The stable expert (:func:`place_uavs_stable`) solves the crowd itself and ``copies - 1`` copies of it,
each pedestrian moved by a normal draw of ``jitter_m`` metres from generator ``(seed, copy)`` (fixed
draws: the same crowd always gets the same copies, and a crowd moved by a few centimetres gets copies
moved by as much). It keeps the **medoid**: the solve that agrees most with the others, two solves
agreeing on each pair of UAVs that a least-distance assignment pairs within ``agreement_m`` (pairs
over the larger of the two counts; ties go to the lower copy, the crowd itself first). A choice that
flips with a few centimetres in one solve rarely flips the majority of ``copies`` solves. The medoid,
solved on a copy whose users stand about ``jitter_m`` from the crowd's, is then made valid on the
crowd itself by the base method's repair, which also centres its UAVs on their users.

Everything is deterministic; ``copies = 1`` is the base method, repaired.

Example:
    >>> a = np.array([[0.0, 0.0], [50.0, 0.0]])
    >>> medoid([a, a + 1.0, np.array([[0.0, 90.0]])], agreement_m=20.0)
    0
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from typed_config import Config, param

__all__ = ["StableExpertConfig", "agreement", "medoid", "place_uavs_stable"]


@dataclass(frozen=True)
class StableExpertConfig(Config):
    """Settings of the stable strategy-2 expert ([task.expert.stable])."""

    copies: int = param(7, ge=1, le=64, doc="solves of the base method: the crowd, then jittered copies")
    jitter_m: float = param(0.2, gt=0.0, le=10.0, doc="standard deviation of the copies' jitter, metres")
    agreement_m: float = param(
        20.0, gt=0.0, le=1000.0, doc="two solves agree on a pair of UAVs this close, metres (the paper's "
        "matching radius: a tenth of the 200 m area)")
    seed: int = param(0, ge=0, doc="seed of the copies' jitter")


def agreement(a: np.ndarray, b: np.ndarray, agreement_m: float) -> float:
    """The share of UAVs two placements agree on: pairs within ``agreement_m``, over the larger count.

    >>> agreement(np.array([[0.0, 0.0], [30.0, 0.0]]), np.array([[1.0, 0.0]]), 5.0)
    0.5
    """
    if len(a) == 0 or len(b) == 0:
        return 1.0 if len(a) == len(b) else 0.0
    distance = np.sqrt(((a[:, None, :] - b[None, :, :]) ** 2).sum(-1))
    rows, cols = linear_sum_assignment(distance)
    return float(np.count_nonzero(distance[rows, cols] <= agreement_m)) / max(len(a), len(b))


def medoid(placements: Sequence[np.ndarray], agreement_m: float) -> int:
    """Index of the placement with the most agreement with the others (ties: the lowest index)."""
    n = len(placements)
    totals = np.zeros(n)
    for i in range(n):
        for j in range(i + 1, n):
            score = agreement(placements[i], placements[j], agreement_m)
            totals[i] += score
            totals[j] += score
    return int(np.flatnonzero(totals >= totals.max() - 1e-12)[0])


def place_uavs_stable(users_m: np.ndarray, config: StableExpertConfig,
                      solve: Callable[[np.ndarray], np.ndarray],
                      repair: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> np.ndarray:
    """The stable expert's placement of one crowd (module docstring).

    Args:
        users_m: ``(N, 2)`` user positions, metres.
        config: Copies, jitter, agreement radius, seed.
        solve: The base method on a crowd: ``(N, 2)`` users to ``(k, 2)`` UAVs, metres.
        repair: The base method's repair: ``(users_m, uavs_m)`` to a valid placement over ``users_m``.

    Returns:
        ``(k, 2)`` UAV positions, metres, as ``repair`` returns them.
    """
    users_m = np.asarray(users_m, dtype=np.float64)
    crowds = [users_m] + [users_m + np.random.default_rng((config.seed, copy)).normal(0.0, config.jitter_m,
                                                                                        users_m.shape)
                          for copy in range(1, config.copies)]
    placements = [np.asarray(solve(crowd), np.float64).reshape(-1, 2) for crowd in crowds]
    return repair(users_m, placements[medoid(placements, config.agreement_m)])
