"""The Wi-Fi deployment rule checked on learned placements, from the observation alone.

The network proposes a UAV wherever its utility map peaks, but it does not count users: it also
peaks over groups that the mission's rule would not serve ("a UAV is deployed only for a group
of more than 30 users"), and those peaks are its false positives. The rule check counts them on
the same density raster the network sees, with no other knowledge of the crowd:

1. Every pixel's pedestrians stand at the pixel's centre (:func:`raster_users`).
2. Users associate as the experts' rules say (nearest UAV within the coverage radius,
   :func:`uav_swarm.missions.wifi.rules.assign_users`).
3. While some UAV is justified by fewer than ``min_users - slack_users`` users (strategy 1: users
   only it covers; strategy 2: users it serves), the least justified one is dropped
   (:func:`drop_unjustified`). The slack allows for the half pixel between a pedestrian and the
   centre of its pixel, which moves users across the coverage radius.

Peaks are extracted at ``threshold_abs`` before the check: a check that removes unjustified
peaks can afford a lower threshold than the network's calibrated one, so it keeps more of the
justified ones. Both settings are chosen on the validation split (README, "rule check").

Examples:
    >>> from uav_swarm.missions.wifi.rules import CoverageRules
    >>> rules = CoverageRules(radius_m=30.0, min_users=31, max_users=None, max_uavs=10, exclusive=True)
    >>> users = np.vstack([np.full((40, 2), 50.0), np.full((10, 2), 150.0)])
    >>> drop_unjustified(users, np.array([[50.0, 50.0], [150.0, 150.0]]), rules, 0).tolist()
    [[50.0, 50.0]]
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from typed_config import Config, param
from uav_swarm.missions.wifi.rules import CoverageRules, assign_users

__all__ = ["RasterFrame", "RuleCheckConfig", "WifiRuleCheck", "raster_users", "drop_unjustified"]


class _DensityConfig(Protocol):
    @property
    def density_scale(self) -> float:
        """Pedestrians per unit of the raster's density channel."""


class RasterFrame(Protocol):
    """What the check needs of a Wi-Fi task (:class:`uav_swarm.missions.wifi.task.WifiTask` is one)."""

    @property
    def config(self) -> _DensityConfig:
        """The task's config (its density scale)."""

    @property
    def rules(self) -> CoverageRules:
        """The coverage rules the check applies."""

    def to_metres(self, xy_px: np.ndarray) -> np.ndarray:
        """Pixel coordinates to metres."""

    def to_pixels(self, xy_m: np.ndarray) -> np.ndarray:
        """Metres to pixel coordinates."""


@dataclass(frozen=True)
class RuleCheckConfig(Config):
    """Settings of the rule check (the ``[rule_check]`` table of a Wi-Fi task settings file).

    The defaults are those ``uav-swarm calibrate-check`` chose for the shipped S1 network
    (``configs/tasks/wifi-s1.toml``), so the planner's ``[planning.rule_checking]`` starts from them.
    """

    threshold_abs: float = param(
        0.2, ge=0.0, le=100.0, doc="peaks are extracted at this threshold (utility-map units), then checked")
    slack_users: int = param(
        8, ge=0, le=1000, doc="the rule's minimum of users is lowered by this many (users at pixel centres)")


def raster_users(observation: np.ndarray, density_scale: float) -> tuple[np.ndarray, np.ndarray]:
    """The users a density raster shows: ``(pixels (m, 2) as (x, y), counts (m,))`` of its non-empty pixels.

    Args:
        observation: ``(C, h, w)`` (channel 0 is the density) or ``(h, w)`` density divided by
            ``density_scale``.
        density_scale: Pedestrians per pixel that read as 1.0.
    """
    observation = np.asarray(observation, dtype=np.float64)
    density = observation[0] if observation.ndim == 3 else observation
    counts = np.rint(density * density_scale).astype(np.int64)
    rows, cols = np.nonzero(counts > 0)
    return np.stack([cols, rows], axis=1).astype(np.float64), counts[rows, cols]


def drop_unjustified(users_m: np.ndarray, uavs_m: np.ndarray, rules: CoverageRules, slack_users: int
                     ) -> np.ndarray:
    """``uavs_m`` without the UAVs the rule does not justify, the least justified dropped first.

    Args:
        users_m: ``(N, 2)`` user positions, metres.
        uavs_m: ``(k, 2)`` UAV positions, metres, in order of preference (kept in that order).
        rules: The strategy's rules (radius, ``min_users``, exclusive or served counting).
        slack_users: ``min_users`` is lowered by this many users.

    Returns:
        The ``(k', 2)`` kept positions, ``k' <= k``, each justified by at least
        ``rules.min_users - slack_users`` users.
    """
    uavs_m = np.asarray(uavs_m, dtype=np.float64).reshape(-1, 2)
    needed = rules.min_users - slack_users
    while len(uavs_m):
        state = assign_users(users_m, uavs_m, rules.radius_m)
        justified = state.exclusive_counts if rules.exclusive else state.counts
        weakest = int(np.argmin(justified))
        if justified[weakest] >= needed:
            break
        uavs_m = np.delete(uavs_m, weakest, axis=0)
    return uavs_m


class WifiRuleCheck:
    """The rule check of one Wi-Fi task: ``check(observation, positions_px) -> positions_px``.

    Args:
        task: The Wi-Fi task (its raster geometry, density scale and rules).
        config: The check's settings; default ``RuleCheckConfig()``.
    """

    config_class = RuleCheckConfig

    def __init__(self, task: RasterFrame, config: RuleCheckConfig | None = None) -> None:
        self.task = task
        self.config = config or RuleCheckConfig()

    @property
    def threshold_abs(self) -> float:
        """The peak threshold to extract the proposals at."""
        return self.config.threshold_abs

    def settings(self) -> dict[str, Any]:
        """The check's settings, for results files."""
        return self.config.to_dict()

    def __call__(self, observation: np.ndarray, positions_px: np.ndarray) -> np.ndarray:
        """The ``(k', 2)`` pixel positions among ``positions_px`` the rule justifies on ``observation``."""
        task = self.task
        pixels, counts = raster_users(observation, task.config.density_scale)
        users_m = np.repeat(task.to_metres(pixels), counts, axis=0)
        kept = drop_unjustified(users_m, task.to_metres(positions_px), task.rules, self.config.slack_users)
        return task.to_pixels(kept)
