"""The paper's placement metrics: correspondence ratio and precision.

Expert positions ζ and predicted positions ζ̂ are paired by an optimal assignment
(Hungarian algorithm, ``scipy.optimize.linear_sum_assignment``); a pair *matches*
when its distance is at most ε = 10 % of the mission dimension. Two assignment rules
(``rule``):

- ``"paper"`` (the default, the paper's rule, used for every headline figure): the
  assignment of least total distance over all pairs, then the pairs within ε are counted.
  A far pair can take a prediction that a nearer expert needed.
- ``"max-matches"``: the assignment that maximises the number of pairs within ε and,
  among those, minimises their total distance (pairs farther than ε cost a constant
  larger than any sum of matched distances). It never scores below the paper's rule.

    corr      = |match| / |ζ|
    precision = |match| / (|match| + |ζ̂*|)    ζ̂* = predictions matching no expert
              = |match| / |ζ̂|

Conventions for the 0/0 cases: an empty expert placement has corr = 1 (nothing
to find); an empty prediction has precision = 1 when the expert is empty too
and 0 otherwise (predicting nothing where something was needed is not precise).
Every other case follows the formulas (e.g. empty expert with predictions:
precision 0).

Aggregation over a test set (:func:`aggregate`) gives both the mean of the
per-sample values (``corr``, ``precision``: what the paper's table reports and
what our tables show) and the pooled ratios of summed counts (``pooled_corr``,
``pooled_precision``).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import asdict, dataclass
from typing import Literal

import numpy as np
from scipy.optimize import linear_sum_assignment

__all__ = ["MATCH_FRACTION", "MATCH_RULES", "MatchRule", "SampleScore", "match_positions", "score_sample",
           "aggregate"]

MATCH_FRACTION = 0.1
"""ε as a fraction of the mission dimension."""

MatchRule = Literal["paper", "max-matches"]
MATCH_RULES: tuple[str, ...] = ("paper", "max-matches")
"""The assignment rules of :func:`match_positions` (see the module docstring)."""


@dataclass(frozen=True)
class SampleScore:
    """Counts and ratios of one sample."""

    n_expert: int
    n_predicted: int
    n_matched: int
    corr: float
    precision: float

    def to_dict(self) -> dict[str, float | int]:
        """Plain dict for JSON."""
        return asdict(self)


def match_positions(expert: np.ndarray, predicted: np.ndarray, eps: float, rule: MatchRule = "paper"
                    ) -> np.ndarray:
    """Matched pairs of the optimal assignment between expert and predicted positions.

    Args:
        expert: ``(n, 2)`` positions.
        predicted: ``(m, 2)`` positions (same units as ``expert``).
        eps: Match radius (inclusive), same units.
        rule: ``"paper"`` (least total distance, then pairs within ``eps``) or
            ``"max-matches"`` (most pairs within ``eps``); see the module docstring.

    Returns:
        ``(p, 2)`` int array of ``(expert index, predicted index)`` with distance <= eps.

    Raises:
        ValueError: ``eps`` is negative, ``rule`` is unknown or an input is not ``(k, 2)``.
    """
    if not eps >= 0.0:
        raise ValueError(f"eps = {eps} must be >= 0")
    if rule not in MATCH_RULES:
        raise ValueError(f"rule = {rule!r} is not allowed: choose one of {list(MATCH_RULES)}")
    expert = np.asarray(expert, dtype=np.float64).reshape(-1, 2)
    predicted = np.asarray(predicted, dtype=np.float64).reshape(-1, 2)
    if len(expert) == 0 or len(predicted) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    distance = np.linalg.norm(expert[:, None, :] - predicted[None, :, :], axis=-1)  # (n, m)
    within = distance <= eps
    if rule == "paper":
        cost = distance
    else:
        far_cost = (min(distance.shape) + 1) * max(eps, 1.0)  # > any sum of matched distances
        cost = np.where(within, distance, far_cost)
    rows, cols = linear_sum_assignment(cost)
    keep = within[rows, cols]
    return np.stack([rows[keep], cols[keep]], axis=1).astype(np.int64)


def _ratios(n_expert: int, n_predicted: int, n_matched: int) -> tuple[float, float]:
    corr = 1.0 if n_expert == 0 else n_matched / n_expert
    if n_predicted == 0:
        precision = 1.0 if n_expert == 0 else 0.0
    else:
        precision = n_matched / n_predicted
    return corr, precision


def score_sample(expert: np.ndarray, predicted: np.ndarray, eps: float, rule: MatchRule = "paper"
                 ) -> SampleScore:
    """Correspondence ratio and precision of one prediction.

    Args:
        expert: ``(n, 2)`` expert positions.
        predicted: ``(m, 2)`` predicted positions.
        eps: Match radius, same units (``MATCH_FRACTION`` × mission dimension).
        rule: The assignment rule of :func:`match_positions`.

    Examples:
        >>> s = score_sample(np.array([[0.0, 0.0], [10.0, 0.0]]), np.array([[1.0, 0.0]]), eps=2.0)
        >>> (s.n_matched, s.corr, s.precision)
        (1, 0.5, 1.0)
    """
    n_expert = len(np.asarray(expert).reshape(-1, 2))
    n_predicted = len(np.asarray(predicted).reshape(-1, 2))
    n_matched = len(match_positions(expert, predicted, eps, rule))
    corr, precision = _ratios(n_expert, n_predicted, n_matched)
    return SampleScore(n_expert, n_predicted, n_matched, corr, precision)


def aggregate(scores: Iterable[SampleScore]) -> dict[str, float]:
    """Test-set summary: means of per-sample ratios and pooled ratios of counts.

    Returns:
        ``n_samples``, ``corr`` and ``precision`` (means of per-sample values, as in
        the paper), ``pooled_corr`` and ``pooled_precision`` (ratios of summed
        counts, same 0/0 conventions), and the summed counts.

    Raises:
        ValueError: ``scores`` is empty.
    """
    scores = list(scores)
    if not scores:
        raise ValueError("cannot aggregate an empty list of scores")
    n_expert = sum(s.n_expert for s in scores)
    n_predicted = sum(s.n_predicted for s in scores)
    n_matched = sum(s.n_matched for s in scores)
    pooled_corr, pooled_precision = _ratios(n_expert, n_predicted, n_matched)
    return {
        "n_samples": len(scores),
        "corr": float(np.mean([s.corr for s in scores])),
        "precision": float(np.mean([s.precision for s in scores])),
        "pooled_corr": pooled_corr,
        "pooled_precision": pooled_precision,
        "n_expert": n_expert,
        "n_predicted": n_predicted,
        "n_matched": n_matched,
    }
