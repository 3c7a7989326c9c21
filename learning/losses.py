"""Losses beside the paper's MSE: the penalty-reduced focal loss of keypoint detectors.

The paper regresses the two-Gaussian utility map with an MSE. A network with a peak head
(:class:`learning.model.ModelConfig` ``peak_head``) also predicts the expert positions as a
heatmap (:func:`learning.targets.render_peak_heatmap`), scored as CenterNet scores its object
centres (Zhou et al., "Objects as Points", 2019, eq. 1): a focal loss whose negatives near a
position are down-weighted by ``(1 - Y)^β``, normalised by the number of positions. Its
gradient concentrates on pixels that are wrongly confident, which sharpens the peaks that the
MSE leaves flat.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

__all__ = ["focal_loss"]


def focal_loss(logits: torch.Tensor, heatmap: torch.Tensor, alpha: float = 2.0, beta: float = 4.0
               ) -> torch.Tensor:
    """Penalty-reduced focal loss of ``logits`` against the target ``heatmap`` (both ``(B, 1, h, w)``).

    Positives are the pixels where ``heatmap == 1``; the sum is divided by their number (at least 1).

    Examples:
        >>> target = torch.zeros(1, 1, 3, 3); target[0, 0, 1, 1] = 1.0
        >>> good, bad = torch.full((1, 1, 3, 3), -6.0), torch.zeros(1, 1, 3, 3)
        >>> good[0, 0, 1, 1] = 6.0
        >>> bool(focal_loss(good, target) < focal_loss(bad, target))
        True
    """
    logits, heatmap = logits.float(), heatmap.float()
    log_p, log_not_p = F.logsigmoid(logits), F.logsigmoid(-logits)
    p = log_p.exp()
    positive = heatmap >= 1.0
    positive_loss = ((1.0 - p) ** alpha * log_p)[positive].sum()
    negative_loss = ((1.0 - heatmap) ** beta * p**alpha * log_not_p)[~positive].sum()
    return -(positive_loss + negative_loss) / positive.sum().clamp(min=1)
