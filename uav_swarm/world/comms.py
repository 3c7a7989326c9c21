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

**Propagation** (``RadioConfig.propagation``): ``"paper"`` is the model above; ``"802.11"`` is the 802.11
model of :mod:`uav_swarm.world.wifi.coverage` (path loss, SINR, MCS rates, airtime shared by co-channel APs
that hear each other, admission on rate; docs/radio.md), which the same functions and :class:`Association`
run, with each UAV's own altitude and a channel plan.

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

from collections.abc import Sequence

import numpy as np

from uav_swarm.world.admission import admit_stations
from uav_swarm.world.coverage import Coverage, coverage_of_links
from uav_swarm.world.radio_config import RadioConfig
from uav_swarm.world.wifi.coverage import wifi_links

__all__ = ["RadioConfig", "Coverage", "Association", "rescaled_signal", "evaluate_coverage",
           "coverage_of", "coverage_of_links"]


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


def _wifi_snapshot(users_m: np.ndarray, uavs_m: np.ndarray, config: RadioConfig,
                   altitudes_m: np.ndarray | None, channels: np.ndarray | None, previous: np.ndarray | None
                   ) -> Coverage:
    users_m, uavs_m = _check_points("users_m", users_m), _check_points("uavs_m", uavs_m)
    links = wifi_links(users_m, np.zeros(len(users_m), np.int64), uavs_m[None], config, altitudes_m, channels,
                       previous)
    return coverage_of_links(links, 0, config)


def evaluate_coverage(users_m: np.ndarray, uavs_m: np.ndarray, config: RadioConfig,
                      altitudes_m: np.ndarray | None = None, channels: np.ndarray | None = None) -> Coverage:
    """Associate the users (the config's association, snapshot) and share each UAV's capacity.

    Args:
        users_m: (N, 2) user positions in metres.
        uavs_m: (K, 2) UAV positions in metres.
        config: The radio model; ``config.station_limit`` chooses the association (module docstring).
        altitudes_m: (K,) each UAV's height above the users (metres); None: ``config.altitude_m`` for all.
        channels: 802.11 only: (K,) each UAV's channel number; None: all on the first usable channel.

    Returns:
        The :class:`Coverage` of the users.

    Raises:
        ValueError: An input is not of shape (n, 2), ``altitudes_m`` or ``channels`` not of shape (K,), or
            ``channels`` given to the paper's model.
    """
    if config.propagation == "802.11":
        return _wifi_snapshot(users_m, uavs_m, config, altitudes_m, channels, None)
    if channels is not None:
        raise ValueError("channels apply only with RadioConfig.propagation = '802.11'")
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

    With propagation ``"802.11"`` incumbents are always kept while in range (MCS 0 or better at their AP) and
    newcomers are admitted as :mod:`uav_swarm.world.wifi.coverage` says.
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

    def incumbents(self, uav_ids: np.ndarray, n_users: int) -> np.ndarray:
        """(N,) each user's UAV at the last update in ``uav_ids``' rows (-1: none); keeps the ids."""
        previous = self._previous_rows(uav_ids)
        self._ids = uav_ids
        if previous is None or previous.shape[0] != n_users:
            return np.full(n_users, -1, np.int64)
        return previous

    def remember(self, association: np.ndarray) -> None:
        """Keep ``association`` (this update's, in the rows of the ids given to :meth:`incumbents`)."""
        self._association = association

    def update(self, users_m: np.ndarray, uavs_m: np.ndarray, uav_ids: Sequence[int] | None = None,
               altitudes_m: np.ndarray | None = None, channels: np.ndarray | None = None) -> Coverage:
        """Associate the users of this snapshot, keeping incumbents in range, and return the coverage.

        Args:
            users_m: (N, 2) user positions, the same users in the same rows at every update.
            uavs_m: (K, 2) UAV positions.
            uav_ids: (K,) a stable id per UAV row, for fleets whose rows change (a vehicle lost or back);
                default: the row index.
            altitudes_m: (K,) each UAV's height above the users; None: ``config.altitude_m`` for all.
            channels: 802.11 only: (K,) each UAV's channel number; None: all on the first usable channel.

        Raises:
            ValueError: An input is not of shape (n, 2), ``uav_ids``, ``altitudes_m`` or ``channels`` not of
                length K, or ``channels`` given to the paper's model.
        """
        config, limit = self.config, self.config.max_stations
        ids = np.arange(len(uavs_m)) if uav_ids is None else np.asarray(uav_ids, np.int64).reshape(-1)
        if len(ids) != len(uavs_m):
            raise ValueError(f"uav_ids has {len(ids)} ids for {len(uavs_m)} UAVs")
        if config.propagation == "802.11":
            kept = self.incumbents(ids, len(np.asarray(users_m).reshape(-1, 2)))
            coverage = _wifi_snapshot(users_m, uavs_m, config, altitudes_m, channels, kept)
            self.remember(coverage.association)
            return coverage
        if channels is not None:
            raise ValueError("channels apply only with RadioConfig.propagation = '802.11'")
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
