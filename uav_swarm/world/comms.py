"""The paper's Wi-Fi model, and the same radio with admission control: signal, association, throughput, QoS.

A UAV transmits with a fixed power; the received power, rescaled from the user's
sensitivity to the transmit power onto ``[signal_at_range, 1]``, is approximated by an
unnormalised Gaussian of the UAV-user distance ``d``::

    signal(d) = exp(-d**2 / (2 * sigma_sq_m2))

By default ``sigma_sq_m2 = range_m**2 / (2 ln(1 / signal_at_range))`` (about 195.4 m^2),
so the signal is exactly ``signal_at_range`` (0.1) at the 30 m range; the paper's
``sigma_sq_m2 = 450`` can be set explicitly. A user is *in range* of a UAV when that signal is
at least ``signal_at_range``. A UAV's capacity is shared equally among its associated users.

**Association** (``RadioConfig.station_limit``):

- ``None``, the paper's model: every user in range joins its strongest UAV (the nearest one;
  ties go to the lowest UAV index), however many are already there.
- an integer ``L`` or ``"auto"`` (``floor(capacity / min_user_rate)``, 40 by default), admission control
  as a deployed access point does it (hostapd's ``max_num_sta``): a UAV admits at most ``L``
  stations and refuses the next one (802.11 status 17), which then tries its next-strongest UAV in
  range. A snapshot (:func:`evaluate_coverage`) takes the (user, UAV) pairs in range strongest signal
  first (ties: lower UAV index, then lower user index) and admits a pair while the user has no UAV and the
  UAV has room. A sequence (:class:`Association`, for the environment, ``simulate`` and ``fly``) keeps
  every incumbent on its UAV while it stays in range, even when a newcomer is nearer; newcomers fill
  the free places strongest first. The admission itself is :mod:`uav_swarm.world.admission`.

A user *has network* (``covered``) when it is associated; strategy 1's QoS is the share of users
with network, strategy 2's the share with network and at least ``min_user_rate_mbps``. Under
admission control with ``L <= capacity / min_user_rate`` the two are equal.

Examples:
    >>> import numpy as np
    >>> users = np.array([[0.0, 0.0], [29.0, 0.0], [31.0, 0.0]])
    >>> cov = evaluate_coverage(users, np.zeros((1, 2)), RadioConfig())
    >>> cov.covered.tolist(), cov.throughput_mbps.tolist()
    ([True, True, False], [100.0, 100.0, 0.0])
    >>> full = evaluate_coverage(users, np.zeros((1, 2)), RadioConfig(station_limit=1))
    >>> full.association.tolist(), full.in_range.tolist(), full.model
    ([0, -1, -1], [True, True, False], 'admission control (1 stations per UAV)')
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from typed_config import Config, ConfigError, param
from uav_swarm.world.admission import admit_stations

__all__ = ["RadioConfig", "Coverage", "Association", "rescaled_signal", "evaluate_coverage",
           "coverage_of"]


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
    station_limit: int | Literal["auto", "off"] | None = param(
        None, ge=1, doc="stations a UAV admits (admission control, as an access point's max_num_sta): "
        "an integer 1..floor(capacity_mbps / min_user_rate_mbps), 'auto' for that floor (40 by default), "
        "or 'off' for the paper's model (every user in range joins its strongest UAV); None (not given) is "
        "the paper's model too, except in simulate and fly with strategy 2, which take 'auto'")

    def check(self) -> None:
        """Reject a minimum rate above the capacity and a station limit the capacity cannot serve."""
        if self.min_user_rate_mbps > self.capacity_mbps:
            raise ConfigError(
                f"RadioConfig.min_user_rate_mbps = {self.min_user_rate_mbps} is out of range: "
                f"allowed 0 <= min_user_rate_mbps <= capacity_mbps ({self.capacity_mbps})")
        if self.station_limit is None or self.station_limit == "off":
            return
        most = self.rate_bound_stations
        if self.station_limit == "auto":
            if most is None:
                raise ConfigError("RadioConfig.station_limit = 'auto' needs min_user_rate_mbps > 0 "
                                  "(the limit is floor(capacity_mbps / min_user_rate_mbps)); give an integer")
        elif most is not None and self.station_limit > most:
            raise ConfigError(
                f"RadioConfig.station_limit = {self.station_limit} is out of range: allowed "
                f"1 <= station_limit <= {most} (capacity_mbps / min_user_rate_mbps = {self.capacity_mbps} / "
                f"{self.min_user_rate_mbps}: more stations could not all get the minimum rate)")

    @property
    def rate_bound_stations(self) -> int | None:
        """``floor(capacity / min_user_rate)``: the most users that all get the minimum rate (None at 0)."""
        if self.min_user_rate_mbps <= 0.0:
            return None
        return int(math.floor(self.capacity_mbps / self.min_user_rate_mbps + 1e-9))

    @property
    def max_stations(self) -> int | None:
        """The station limit in force per UAV, ``None`` for the paper's model (no admission control)."""
        if self.station_limit == "auto":
            return self.rate_bound_stations
        if self.station_limit == "off":
            return None
        return self.station_limit

    @property
    def association_name(self) -> str:
        """Which association runs, in words (outputs and tables say it)."""
        limit = self.max_stations
        return "paper (no admission control)" if limit is None else \
            f"admission control ({limit} stations per UAV)"

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
        association: (N,) int, index of each user's UAV, -1 without network.
        covered: (N,) bool, the user has network (is associated).
        users_per_uav: (K,) int, users associated with each UAV.
        throughput_mbps: (N,) float, ``capacity / users_per_uav[association]``, 0 without network.
        qos_s1: Share of users with network (strategy 1), 0.0 without users.
        qos_s2: Share of users with network and at least ``min_user_rate_mbps`` (strategy 2).
        mean_throughput_mbps: Mean throughput over all users (users without network count as 0).
        in_range: (N,) bool, strongest signal >= ``signal_at_range`` (equals ``covered`` in the paper's model;
            under admission control a user in range of full UAVs only is refused).
        model: Which association ran (:attr:`RadioConfig.association_name`).
    """

    association: np.ndarray
    covered: np.ndarray
    users_per_uav: np.ndarray
    throughput_mbps: np.ndarray
    qos_s1: float
    qos_s2: float
    mean_throughput_mbps: float
    in_range: np.ndarray
    model: str


def _check_points(name: str, points: np.ndarray) -> np.ndarray:
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 2:
        raise ValueError(f"{name} must have shape (n, 2), got {points.shape}")
    return points


def _squared_distances(users_m: np.ndarray, uavs_m: np.ndarray, config: RadioConfig,
                       altitudes_m: np.ndarray | None = None) -> np.ndarray:
    """(K, N) squared UAV-user distances (m^2); UAV-major, which makes reductions over K fast.

    The height of a UAV above the users is its entry of ``altitudes_m`` ((K,), metres) when given, else
    ``config.altitude_m``; a height adds its square.
    """
    users_m = _check_points("users_m", users_m)
    uavs_m = _check_points("uavs_m", uavs_m)
    dx = uavs_m[:, 0:1] - users_m[:, 0]  # (K, N)
    dy = uavs_m[:, 1:2] - users_m[:, 1]
    d2 = dx * dx
    d2 += dy * dy
    if altitudes_m is not None:
        heights = np.asarray(altitudes_m, dtype=np.float64).reshape(-1)
        if heights.shape != (len(uavs_m),):
            raise ValueError(f"altitudes_m must have shape ({len(uavs_m)},), got {heights.shape}")
        d2 += (heights * heights)[:, None]
    elif config.altitude_m:
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


def coverage_of(association: np.ndarray, in_range_any: np.ndarray, n_uavs: int, config: RadioConfig
              ) -> Coverage:
    """The :class:`Coverage` of an association: per-UAV loads, per-user throughput and the QoS.

    Args:
        association: (N,) int, each user's UAV, -1 without network.
        in_range_any: (N,) bool, the user's strongest signal reaches ``signal_at_range``.
        n_uavs: Number of UAVs K.
        config: The radio model.
    """
    n_users = association.shape[0]
    covered = association >= 0
    served_by = association[covered]
    users_per_uav = np.bincount(served_by, minlength=n_uavs)
    rate_mbps = config.capacity_mbps / np.maximum(users_per_uav, 1)  # (K,) per-user rate of each UAV
    n_fast = int(users_per_uav[rate_mbps >= config.min_user_rate_mbps].sum())
    # Each UAV with users hands out its whole capacity: the throughput sums to capacity * active UAVs.
    total_mbps = config.capacity_mbps * np.count_nonzero(users_per_uav)
    return Coverage(
        association=np.where(covered, association, -1),
        covered=covered,
        users_per_uav=users_per_uav,
        throughput_mbps=np.where(covered, rate_mbps[np.maximum(association, 0)], 0.0) if n_uavs else
        np.zeros(n_users),
        qos_s1=served_by.size / n_users if n_users else 0.0,
        qos_s2=n_fast / n_users if n_users else 0.0,
        mean_throughput_mbps=float(total_mbps / n_users) if n_users else 0.0,
        in_range=in_range_any,
        model=config.association_name,
    )


def evaluate_coverage(users_m: np.ndarray, uavs_m: np.ndarray, config: RadioConfig,
                      altitudes_m: np.ndarray | None = None) -> Coverage:
    """Associate the users (the config's association, snapshot) and share each UAV's capacity.

    Args:
        users_m: (N, 2) user positions in metres.
        uavs_m: (K, 2) UAV positions in metres.
        config: The radio model; ``config.station_limit`` chooses the association (module docstring).
        altitudes_m: (K,) each UAV's height above the users (metres); None: ``config.altitude_m`` for all.

    Returns:
        The :class:`Coverage` of the users.

    Raises:
        ValueError: An input is not of shape (n, 2), or ``altitudes_m`` not of shape (K,).
    """
    d2 = _squared_distances(users_m, uavs_m, config, altitudes_m)  # (K, N)
    n_uavs, n_users = d2.shape
    if n_users == 0 or n_uavs == 0:
        return coverage_of(np.full(n_users, -1, np.int64), np.zeros(n_users, bool), n_uavs, config)
    # The signal decreases with distance: the strongest UAV is the nearest (argmin keeps the lowest index).
    nearest = d2.argmin(axis=0)
    best_signal = np.exp(d2.min(axis=0) * (-0.5 / config.effective_sigma_sq_m2))
    in_range_any = best_signal >= config.signal_at_range
    association = np.where(in_range_any, nearest, -1)
    limit = config.max_stations
    # Admission control changes nothing while no UAV's nearest users exceed its limit.
    if limit is not None and np.bincount(nearest[in_range_any], minlength=n_uavs).max() > limit:
        association = admit_stations(d2, _signal_in_range(d2, config), np.full(n_uavs, limit, np.int64))
    return coverage_of(association, in_range_any, n_uavs, config)


def _signal_in_range(d2: np.ndarray, config: RadioConfig) -> np.ndarray:
    """(K, N) bool: the signal of the UAV at the user reaches ``signal_at_range`` (the same test as above)."""
    return np.exp(d2 * (-0.5 / config.effective_sigma_sq_m2)) >= config.signal_at_range


class Association:
    """The association of a sequence of snapshots (the environment, ``simulate``, ``fly``).

    In the paper's model (no station limit) every snapshot is associated afresh, exactly as
    :func:`evaluate_coverage`. Under admission control a user keeps its UAV while it stays in range
    (no eviction by newcomers, no roaming while its signal holds); users that left their UAV's range,
    and users new in range, fill the free places strongest first (:func:`admit_stations`).
    Users are identified by their row: the crowd keeps its pedestrians in order.

    Args:
        config: The radio model.

    Examples:
        >>> link = Association(RadioConfig(station_limit=1))
        >>> link.update(np.array([[10.0, 0.0]]), np.array([[0.0, 0.0], [25.0, 0.0]])).association.tolist()
        [0]
        >>> link.update(np.array([[14.0, 0.0]]), np.array([[0.0, 0.0], [25.0, 0.0]])).association.tolist()
        [0]
    """

    def __init__(self, config: RadioConfig) -> None:
        self.config = config
        self._association: np.ndarray | None = None
        self._ids = np.zeros(0, np.int64)

    def reset(self) -> None:
        """Forget every association (a new episode)."""
        self._association = None
        self._ids = np.zeros(0, np.int64)

    def _previous_rows(self, ids: np.ndarray) -> np.ndarray | None:
        """The last association in this update's UAV rows (-1 where the UAV is gone)."""
        if self._association is None:
            return None
        if np.array_equal(ids, self._ids):
            return self._association
        row_of = {int(uav_id): row for row, uav_id in enumerate(ids)}
        rows = np.array([row_of.get(int(uav_id), -1) for uav_id in self._ids] + [-1], np.int64)
        return rows[self._association]  # -1 (no UAV) indexes the appended -1

    def update(self, users_m: np.ndarray, uavs_m: np.ndarray, uav_ids: Sequence[int] | None = None,
               altitudes_m: np.ndarray | None = None) -> Coverage:
        """Associate the users of this snapshot, keeping incumbents in range, and return the coverage.

        Args:
            users_m: (N, 2) user positions, the same users in the same rows at every update.
            uavs_m: (K, 2) UAV positions.
            uav_ids: (K,) a stable id per UAV row, for fleets whose rows change (a vehicle lost or back);
                default: the row index.
            altitudes_m: (K,) each UAV's height above the users; None: ``config.altitude_m`` for all.

        Raises:
            ValueError: An input is not of shape (n, 2), ``uav_ids`` or ``altitudes_m`` not of length K.
        """
        config, limit = self.config, self.config.max_stations
        ids = np.arange(len(uavs_m)) if uav_ids is None else np.asarray(uav_ids, np.int64).reshape(-1)
        if len(ids) != len(uavs_m):
            raise ValueError(f"uav_ids has {len(ids)} ids for {len(uavs_m)} UAVs")
        previous = self._previous_rows(ids)
        self._ids = ids
        if limit is None:
            coverage = evaluate_coverage(users_m, uavs_m, config, altitudes_m)
            self._association = coverage.association
            return coverage
        d2 = _squared_distances(users_m, uavs_m, config, altitudes_m)  # (K, N)
        n_uavs, n_users = d2.shape
        in_range = _signal_in_range(d2, config)
        in_range_any = np.asarray(in_range.any(axis=0)) if n_uavs else np.zeros(n_users, bool)
        kept = np.full(n_users, -1, np.int64)
        if previous is not None and previous.shape[0] == n_users and n_uavs:
            stays = (previous >= 0) & (previous < n_uavs)
            rows = np.flatnonzero(stays)
            stays[rows] = in_range[previous[rows], rows]
            kept[stays] = previous[stays]
        free = limit - np.bincount(kept[kept >= 0], minlength=n_uavs)
        association = admit_stations(d2, in_range, np.maximum(free, 0), kept) if n_uavs else kept
        self._association = association
        return coverage_of(association, in_range_any, n_uavs, config)
