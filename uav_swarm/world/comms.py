"""The paper's Wi-Fi model: rescaled signal, user association, shared throughput and QoS.

A UAV transmits with a fixed power; the received power, rescaled from the user's
sensitivity to the transmit power onto ``[signal_at_range, 1]``, is approximated by an
unnormalised Gaussian of the UAV-user distance ``d``::

    signal(d) = exp(-d**2 / (2 * sigma_sq_m2))

By default ``sigma_sq_m2 = range_m**2 / (2 ln(1 / signal_at_range))`` (about 195.4 m^2),
so the signal is exactly ``signal_at_range`` (0.1) at the 30 m range; the paper's
``sigma_sq_m2 = 450`` can be set explicitly. Each user associates with its strongest
UAV (the nearest one; ties go to the lowest UAV index) and is covered when that
signal is at least ``signal_at_range``. A UAV's capacity is shared equally among its
covered users.

Examples:
    >>> import numpy as np
    >>> users = np.array([[0.0, 0.0], [29.0, 0.0], [31.0, 0.0]])
    >>> cov = evaluate_coverage(users, np.zeros((1, 2)), RadioConfig())
    >>> cov.covered.tolist(), cov.throughput_mbps.tolist()
    ([True, True, False], [100.0, 100.0, 0.0])
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from typed_config import Config, ConfigError, param

__all__ = ["RadioConfig", "Coverage", "rescaled_signal", "evaluate_coverage"]


@dataclass(frozen=True)
class RadioConfig(Config):
    """Parameters of the UAV Wi-Fi model (defaults: the paper's radio with 0.1 at 30 m)."""

    range_m: float = param(30.0, gt=0.0, le=10_000.0,
                           doc="distance (m) at which the rescaled signal equals signal_at_range")
    signal_at_range: float = param(0.1, gt=0.0, lt=1.0,
                                   doc="coverage threshold on the rescaled signal (0..1)")
    sigma_sq_m2: float | None = param(
        None, gt=0.0, doc="Gaussian variance (m^2); None derives it from range_m and signal_at_range; "
        "450 is the paper's value")
    capacity_mbps: float = param(200.0, gt=0.0, doc="UAV capacity (Mbps) shared equally by its users")
    min_user_rate_mbps: float = param(5.0, ge=0.0, doc="per-user rate (Mbps) that strategy 2 requires")
    altitude_m: float = param(0.0, ge=0.0, le=10_000.0,
                              doc="UAV height above the users (m); > 0 uses the 3D distance")

    def check(self) -> None:
        """Reject a ``min_user_rate_mbps`` above the capacity (strategy 2 could never be met)."""
        if self.min_user_rate_mbps > self.capacity_mbps:
            raise ConfigError(
                f"RadioConfig.min_user_rate_mbps = {self.min_user_rate_mbps} is out of range: "
                f"allowed 0 <= min_user_rate_mbps <= capacity_mbps ({self.capacity_mbps})")

    @property
    def effective_sigma_sq_m2(self) -> float:
        """The Gaussian variance in use (m^2): ``sigma_sq_m2`` or the one giving the threshold at range."""
        if self.sigma_sq_m2 is not None:
            return self.sigma_sq_m2
        return self.range_m**2 / (2.0 * math.log(1.0 / self.signal_at_range))

    @property
    def coverage_radius_m(self) -> float:
        """Horizontal distance (m) within which the signal reaches ``signal_at_range`` (0 if never)."""
        reach_sq = 2.0 * self.effective_sigma_sq_m2 * math.log(1.0 / self.signal_at_range)
        return math.sqrt(max(0.0, reach_sq - self.altitude_m**2))


@dataclass(frozen=True)
class Coverage:
    """Association, coverage and throughput of N users served by K UAVs.

    Attributes:
        association: (N,) int, index of each user's strongest UAV, -1 when uncovered.
        covered: (N,) bool, strongest signal >= ``signal_at_range``.
        users_per_uav: (K,) int, covered users associated with each UAV.
        throughput_mbps: (N,) float, ``capacity / users_per_uav[association]``, 0 when uncovered.
        qos_s1: Share of users covered (strategy 1), 0.0 without users.
        qos_s2: Share of users covered with at least ``min_user_rate_mbps`` (strategy 2).
        mean_throughput_mbps: Mean throughput over all users (uncovered users count as 0).
    """

    association: np.ndarray
    covered: np.ndarray
    users_per_uav: np.ndarray
    throughput_mbps: np.ndarray
    qos_s1: float
    qos_s2: float
    mean_throughput_mbps: float


def _check_points(name: str, points: np.ndarray) -> np.ndarray:
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 2:
        raise ValueError(f"{name} must have shape (n, 2), got {points.shape}")
    return points


def _squared_distances(users_m: np.ndarray, uavs_m: np.ndarray, config: RadioConfig) -> np.ndarray:
    """(K, N) squared UAV-user distances (m^2); UAV-major, which makes reductions over K fast."""
    users_m = _check_points("users_m", users_m)
    uavs_m = _check_points("uavs_m", uavs_m)
    dx = uavs_m[:, 0:1] - users_m[:, 0]  # (K, N)
    dy = uavs_m[:, 1:2] - users_m[:, 1]
    d2 = dx * dx
    d2 += dy * dy
    if config.altitude_m:
        d2 += config.altitude_m**2
    return d2


def rescaled_signal(users_m: np.ndarray, uavs_m: np.ndarray, config: RadioConfig) -> np.ndarray:
    """The rescaled signal of every UAV at every user.

    Args:
        users_m: (N, 2) user positions in metres.
        uavs_m: (K, 2) UAV positions in metres (horizontal; ``config.altitude_m`` adds height).
        config: The radio model.

    Returns:
        (N, K) float64 signal in (0, 1].

    Raises:
        ValueError: An input is not of shape (n, 2).
    """
    d2 = _squared_distances(users_m, uavs_m, config)  # (K, N)
    return np.exp(-d2 / (2.0 * config.effective_sigma_sq_m2)).T


def evaluate_coverage(users_m: np.ndarray, uavs_m: np.ndarray, config: RadioConfig) -> Coverage:
    """Associate users with their strongest UAV and share each UAV's capacity among its users.

    Args:
        users_m: (N, 2) user positions in metres.
        uavs_m: (K, 2) UAV positions in metres.
        config: The radio model.

    Returns:
        The :class:`Coverage` of the users.

    Raises:
        ValueError: An input is not of shape (n, 2).
    """
    d2 = _squared_distances(users_m, uavs_m, config)  # (K, N)
    n_uavs, n_users = d2.shape
    if n_users == 0 or n_uavs == 0:
        return Coverage(
            association=np.full(n_users, -1, dtype=np.int64),
            covered=np.zeros(n_users, dtype=bool),
            users_per_uav=np.zeros(n_uavs, dtype=np.int64),
            throughput_mbps=np.zeros(n_users),
            qos_s1=0.0, qos_s2=0.0, mean_throughput_mbps=0.0,
        )
    # The signal decreases with distance: the strongest UAV is the nearest (argmin keeps the lowest index).
    nearest = d2.argmin(axis=0)
    best_signal = np.exp(d2.min(axis=0) * (-0.5 / config.effective_sigma_sq_m2))
    covered = best_signal >= config.signal_at_range
    served_by = nearest[covered]
    users_per_uav = np.bincount(served_by, minlength=n_uavs)
    rate_mbps = config.capacity_mbps / np.maximum(users_per_uav, 1)  # (K,) per-user rate of each UAV
    n_fast = int(users_per_uav[rate_mbps >= config.min_user_rate_mbps].sum())
    # Each UAV with users hands out its whole capacity: the throughput sums to capacity * active UAVs.
    total_mbps = config.capacity_mbps * np.count_nonzero(users_per_uav)
    return Coverage(
        association=np.where(covered, nearest, -1),
        covered=covered,
        users_per_uav=users_per_uav,
        throughput_mbps=np.where(covered, rate_mbps[nearest], 0.0),
        qos_s1=served_by.size / n_users,
        qos_s2=n_fast / n_users,
        mean_throughput_mbps=float(total_mbps / n_users),
    )
