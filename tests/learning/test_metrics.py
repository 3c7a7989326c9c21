import numpy as np
import pytest

from learning.metrics import aggregate, match_positions, score_sample


def test_all_predictions_match_but_one_expert_is_missed():
    expert = np.array([[0.0, 0.0], [10.0, 0.0], [20.0, 0.0]])
    predicted = np.array([[0.5, 0.0], [19.0, 1.0]])
    s = score_sample(expert, predicted, eps=2.0)
    assert (s.n_expert, s.n_predicted, s.n_matched) == (3, 2, 2)
    assert s.corr == pytest.approx(2 / 3) and s.precision == 1.0


def test_precision_counts_unmatched_predictions():
    expert = np.array([[0.0, 0.0], [10.0, 10.0]])
    predicted = np.array([[0.0, 1.0], [5.0, 5.0], [30.0, 30.0], [0.0, 1.5]])
    s = score_sample(expert, predicted, eps=2.0)
    # one expert matched; the second prediction near it is unmatched (one-to-one assignment)
    assert s.n_matched == 1
    assert s.corr == 0.5
    assert s.precision == pytest.approx(1 / (1 + 3))


def test_match_radius_is_inclusive():
    s = score_sample(np.array([[0.0, 0.0]]), np.array([[3.0, 4.0]]), eps=5.0)
    assert s.n_matched == 1
    assert score_sample(np.array([[0.0, 0.0]]), np.array([[3.0, 4.0]]), eps=4.99).n_matched == 0


def _crossed_pairs() -> tuple[np.ndarray, np.ndarray]:
    # Minimising raw distance pairs e1-p1 (0) and e2-p2 (1.1 > eps): one match.
    # The maximum matching pairs e1-p2 and e2-p1 (both 1.0 <= eps): two matches.
    c, s = np.sqrt(1 - 0.55**2), 0.55
    return np.array([[0.0, 0.0], [c, s]]), np.array([[0.0, 0.0], [c, -s]])


def test_max_matches_rule_maximises_matches_not_raw_distance():
    expert, predicted = _crossed_pairs()
    pairs = match_positions(expert, predicted, eps=1.01, rule="max-matches")
    assert sorted(map(tuple, pairs.tolist())) == [(0, 1), (1, 0)]


def test_paper_rule_takes_the_least_total_distance_then_counts_pairs_within_eps():
    expert, predicted = _crossed_pairs()
    assert match_positions(expert, predicted, eps=1.01).tolist() == [[0, 0]]
    paper = score_sample(expert, predicted, eps=1.01)
    ours = score_sample(expert, predicted, eps=1.01, rule="max-matches")
    assert (paper.n_matched, ours.n_matched) == (1, 2)
    assert (paper.corr, paper.precision) == (0.5, 0.5)


def test_paper_rule_never_scores_above_max_matches():
    rng = np.random.default_rng(0)
    for _ in range(200):
        expert = rng.uniform(0, 20, size=(rng.integers(0, 6), 2))
        predicted = rng.uniform(0, 20, size=(rng.integers(0, 6), 2))
        paper = score_sample(expert, predicted, eps=4.0).n_matched
        assert paper <= score_sample(expert, predicted, eps=4.0, rule="max-matches").n_matched


def test_unknown_match_rule_is_refused():
    with pytest.raises(ValueError, match="rule = 'nearest'"):
        match_positions(np.zeros((1, 2)), np.zeros((1, 2)), eps=1.0, rule="nearest")


@pytest.mark.parametrize(
    "n_expert,n_pred,corr,precision",
    [(0, 0, 1.0, 1.0), (0, 2, 1.0, 0.0), (2, 0, 0.0, 0.0)],
    ids=["both-empty", "expert-empty", "prediction-empty"],
)
def test_empty_set_conventions(n_expert, n_pred, corr, precision):
    expert = np.arange(2 * n_expert, dtype=float).reshape(-1, 2) * 10
    predicted = np.arange(2 * n_pred, dtype=float).reshape(-1, 2) * 10 + 100
    s = score_sample(expert, predicted, eps=1.0)
    assert (s.corr, s.precision) == (corr, precision)


def test_aggregate_reports_means_and_pooled_ratios():
    a = score_sample(np.array([[0.0, 0.0]]), np.array([[0.0, 0.0]]), eps=1.0)  # 1/1, 1/1
    b = score_sample(np.array([[0.0, 0.0], [5.0, 0], [9.0, 0]]), np.array([[0.0, 0.0], [50.0, 0]]), eps=1.0)
    summary = aggregate([a, b])  # b: corr 1/3, precision 1/2
    assert summary["corr"] == pytest.approx((1 + 1 / 3) / 2)
    assert summary["precision"] == pytest.approx((1 + 0.5) / 2)
    assert summary["pooled_corr"] == pytest.approx(2 / 4)
    assert summary["pooled_precision"] == pytest.approx(2 / 3)
    assert (summary["n_samples"], summary["n_matched"]) == (2, 2)


def test_aggregate_of_nothing_is_an_error():
    with pytest.raises(ValueError, match="empty"):
        aggregate([])
