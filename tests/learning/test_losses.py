"""The penalty-reduced focal loss: positives rewarded, negatives near a position forgiven."""

import torch

from learning.losses import focal_loss


def _target() -> torch.Tensor:
    heatmap = torch.zeros(2, 1, 5, 5)
    heatmap[0, 0, 2, 2] = 1.0
    heatmap[0, 0, 2, 3] = 0.6  # near the position
    heatmap[1, 0, 0, 0] = 1.0
    return heatmap


def test_a_confident_correct_map_scores_lower_than_an_unsure_or_wrong_one() -> None:
    target = _target()
    right = torch.where(target >= 1.0, 8.0, -8.0)
    unsure = torch.zeros_like(target)
    wrong = -right
    assert focal_loss(right, target) < 1e-3 < focal_loss(unsure, target) < focal_loss(wrong, target)


def test_a_false_peak_beside_a_position_costs_less_than_one_far_from_it() -> None:
    target = _target()
    base = torch.where(target >= 1.0, 8.0, -8.0)
    near, far = base.clone(), base.clone()
    near[0, 0, 2, 3] = 4.0
    far[0, 0, 4, 0] = 4.0
    assert focal_loss(base, target) < focal_loss(near, target) < focal_loss(far, target)


def test_the_loss_is_normalised_by_the_number_of_positions_and_pushes_positives_up() -> None:
    target = _target()
    logits = torch.zeros_like(target, requires_grad=True)
    loss = focal_loss(logits, target)
    loss.backward()
    assert logits.grad[0, 0, 2, 2] < 0 < logits.grad[1, 0, 4, 4]  # descent: positive up, negative down
    doubled = torch.cat([target, target])
    assert torch.isclose(focal_loss(torch.zeros_like(doubled), doubled), loss.detach())  # mean per position
    assert torch.isfinite(focal_loss(torch.zeros(1, 1, 3, 3), torch.zeros(1, 1, 3, 3)))  # no position
