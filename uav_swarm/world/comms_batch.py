"""The radio model of :mod:`uav_swarm.world.comms` over B worlds at once: :func:`coverage_batch`.

The users of all worlds are stacked world by world in one ``(N, 2)`` array with the world of each user
(``copy_index``), as :class:`~uav_swarm.world.crowd_batch.BatchedCrowd` keeps them; the UAVs are a
``(B, K, 2)`` array. Each world is associated exactly as :func:`~uav_swarm.world.comms.evaluate_coverage`
associates it alone (the paper's model: every user in range joins its nearest UAV, ties to the lowest
index, the squared distances computed operation for operation as there), or, under admission control,
by one :class:`~uav_swarm.world.comms.Association` per world, whose incumbents are kept step to step.
With ``RadioConfig.propagation = "802.11"`` all worlds go through the 802.11 model at once
(:func:`~uav_swarm.world.wifi.coverage.wifi_links`), the associations holding each world's incumbents:
one :class:`~uav_swarm.world.comms.Association` per world, or, for worlds whose UAV rows never change (the
environment's), one :class:`StackedIncumbents` for all of them.

Examples:
    >>> import numpy as np
    >>> from uav_swarm.world.comms import RadioConfig
    >>> users = np.array([[0.0, 0.0], [29.0, 0.0], [5.0, 5.0]])
    >>> cov = coverage_batch(users, np.array([0, 0, 1]), np.array([[[0.0, 0.0]], [[100.0, 0.0]]]),
    ...                      RadioConfig())
    >>> cov.users_per_uav.tolist(), cov.qos_s1.tolist(), cov.copy(0).covered.tolist()
    ([[2], [0]], [1.0, 0.0], [True, True])
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numba
import numpy as np

from uav_swarm.world.comms import Association, Coverage, RadioConfig, coverage_of, coverage_of_links
from uav_swarm.world.wifi.coverage import WifiLinks, wifi_links

__all__ = ["CoverageBatch", "StackedIncumbents", "coverage_batch", "nearest_uav"]


@dataclass(frozen=True)
class CoverageBatch:
    """The coverage of B worlds: per-user arrays stacked world by world, per-world and per-UAV arrays.

    Attributes:
        association: (N,) int, each user's UAV within its world, -1 without network.
        in_range: (N,) bool, the user's strongest signal reaches ``signal_at_range``.
        offsets: (B + 1,) world ``c``'s users are ``offsets[c]:offsets[c + 1]``.
        users_per_uav: (B, K) int, users associated with each UAV.
        throughput_per_user_mbps: (B, K) the rate each user of the UAV gets (0 for a UAV without users).
        covered_users: (B,) int, users with network in each world.
        n_users: (B,) int, users of each world.
        qos_s1: (B,) share of each world's users with network (0.0 without users).
        qos_s2: (B,) share with network and at least ``min_user_rate_mbps``.
        mean_throughput_mbps: (B,) mean throughput over each world's users.
        config: The radio model.
        links: 802.11 only (None in the paper's model): everything the 802.11 model computed (per-user SINR,
            MCS, rate, throughput; each AP's airtime and channel).
    """

    association: np.ndarray
    in_range: np.ndarray
    offsets: np.ndarray
    users_per_uav: np.ndarray
    throughput_per_user_mbps: np.ndarray
    covered_users: np.ndarray
    n_users: np.ndarray
    qos_s1: np.ndarray
    qos_s2: np.ndarray
    mean_throughput_mbps: np.ndarray
    config: RadioConfig
    links: WifiLinks | None = None

    def copy(self, c: int) -> Coverage:
        """World ``c``'s :class:`~uav_swarm.world.comms.Coverage`, as ``evaluate_coverage`` returns it."""
        if self.links is not None:
            return coverage_of_links(self.links, c, self.config)
        rows = slice(self.offsets[c], self.offsets[c + 1])
        return coverage_of(self.association[rows], self.in_range[rows], self.users_per_uav.shape[1],
                           self.config)


class StackedIncumbents:
    """The 802.11 incumbents of B worlds whose UAV rows never change, stacked as their users are.

    What one :class:`~uav_swarm.world.comms.Association` per world keeps when its UAV ids are the rows,
    without a Python call per world: each user's UAV at the last update; none (-1) for the users of a world
    reset since, or whose number of users changed.

    Args:
        n_worlds: B.
    """

    def __init__(self, n_worlds: int) -> None:
        self._association: np.ndarray | None = None
        self._offsets = np.zeros(n_worlds + 1, np.int64)
        self._fresh = np.ones(n_worlds, bool)

    def reset(self, worlds: np.ndarray | Sequence[int]) -> None:
        """Forget the incumbents of ``worlds`` (indices; a new episode)."""
        self._fresh[np.asarray(worlds, np.int64)] = True

    def previous(self, offsets: np.ndarray) -> np.ndarray:
        """(N,) each user's UAV at the last update, -1 for none; ``offsets``: (B + 1,) as the users'."""
        last, before = self._association, self._offsets
        if last is None or self._fresh.all():
            return np.full(int(offsets[-1]), -1, np.int64)
        if not self._fresh.any() and np.array_equal(offsets, before):
            return last
        sizes, sizes_before = np.diff(offsets), np.diff(before)
        return np.concatenate([
            last[before[c]:before[c + 1]] if not self._fresh[c] and sizes[c] == sizes_before[c]
            else np.full(sizes[c], -1, np.int64) for c in range(len(sizes))])

    def remember(self, association: np.ndarray, offsets: np.ndarray) -> None:
        """Keep this update's ``association`` (N,) of the worlds' users ``offsets`` (B + 1,)."""
        self._association, self._offsets = association, np.asarray(offsets, np.int64)
        self._fresh[:] = False


@numba.njit(cache=True, nogil=True)
def nearest_uav(users_m: np.ndarray, copy_index: np.ndarray, uavs_m: np.ndarray, altitudes_sq_m2: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """``(N,)`` nearest UAV of each user within its world (the lowest index among equals) and its ``d**2``.

    The squared distance is ``evaluate_coverage``'s, operation for operation: ``dx * dx``, plus
    ``dy * dy``, plus the UAV's squared altitude (no fused multiply-add: numba keeps IEEE semantics).

    Args:
        users_m: (N, 2) user positions, metres.
        copy_index: (N,) world of each user.
        uavs_m: (B, K, 2) UAV positions of each world, metres.
        altitudes_sq_m2: (K,) squared height of each UAV above the users (zeros: horizontal distance).
    """
    n_users, n_uavs = users_m.shape[0], uavs_m.shape[1]
    nearest = np.zeros(n_users, np.int64)
    best = np.full(n_users, np.inf)
    for n in range(n_users):
        c = copy_index[n]
        for k in range(n_uavs):
            dx = uavs_m[c, k, 0] - users_m[n, 0]
            dy = uavs_m[c, k, 1] - users_m[n, 1]
            d2 = dx * dx
            d2 += dy * dy
            d2 += altitudes_sq_m2[k]
            if d2 < best[n]:
                nearest[n], best[n] = k, d2
    return nearest, best


def coverage_batch(users_m: np.ndarray, copy_index: np.ndarray, uavs_m: np.ndarray, config: RadioConfig,
                   associations: Sequence[Association] | StackedIncumbents | None = None,
                   altitudes_m: np.ndarray | None = None, channels: np.ndarray | None = None,
                   enabled: np.ndarray | None = None) -> CoverageBatch:
    """Associate the users of B worlds with their own world's UAVs and share each UAV's capacity.

    Args:
        users_m: (N, 2) user positions of all worlds, stacked world by world, metres.
        copy_index: (N,) int, the world of each user (non-decreasing).
        uavs_m: (B, K, 2) UAV positions, metres.
        config: The radio model; with a station limit, ``associations`` must be given.
        associations: One :class:`~uav_swarm.world.comms.Association` per world (admission control keeps
            its incumbents between calls), or under the 802.11 model one :class:`StackedIncumbents` for all
            worlds; None computes the model afresh.
        altitudes_m: (K,) height of each UAV above the users (802.11: or (B, K)); None: ``config.altitude_m``.
        channels: 802.11 only: (K,) or (B, K) channel number of each UAV; None: all on the first usable one.
        enabled: 802.11 only: (K,) or (B, K) bool, the UAVs whose access point is on; None: all.

    Returns:
        The :class:`CoverageBatch`.

    Raises:
        ValueError: A station limit without one association per world, ``channels`` with the paper's model.
    """
    if config.propagation == "802.11":
        return _wifi_batch(users_m, copy_index, uavs_m, config, associations, altitudes_m, channels, enabled)
    if channels is not None or enabled is not None:
        raise ValueError("channels and access points apply only with RadioConfig.propagation = '802.11'")
    n_copies, n_uavs = uavs_m.shape[0], uavs_m.shape[1]
    if n_copies == 1:
        offsets = np.array([0, len(users_m)])
    else:
        offsets = np.searchsorted(copy_index, np.arange(n_copies + 1))
    n_users = np.diff(offsets)
    if config.max_stations is not None:
        if not isinstance(associations, Sequence) or len(associations) != n_copies:
            raise ValueError(f"admission control needs one Association per world ({n_copies})")
        parts = [link.update(users_m[offsets[c]:offsets[c + 1]], uavs_m[c], altitudes_m=altitudes_m)
                 for c, link in enumerate(associations)]
        return _stacked(parts, offsets, n_users, n_uavs, config)
    heights = np.full(n_uavs, config.altitude_m) if altitudes_m is None else np.asarray(altitudes_m, float)
    nearest, best = nearest_uav(np.ascontiguousarray(users_m, dtype=np.float64),
                                np.ascontiguousarray(copy_index, dtype=np.int64),
                                np.ascontiguousarray(uavs_m, dtype=np.float64), heights * heights)
    # numpy's exp, as evaluate_coverage's, so that a user on the range's edge is judged the same.
    in_range = np.exp(best * (-0.5 / config.effective_sigma_sq_m2)) >= config.signal_at_range
    association = np.where(in_range, nearest, -1)
    slot = nearest[in_range] if n_copies == 1 else (copy_index * n_uavs + nearest)[in_range]
    served = np.bincount(slot, minlength=n_copies * n_uavs).reshape(n_copies, n_uavs)
    return _from_loads(association, in_range, offsets, served, n_users, config)


def _from_loads(association: np.ndarray, in_range: np.ndarray, offsets: np.ndarray, served: np.ndarray,
                n_users: np.ndarray, config: RadioConfig) -> CoverageBatch:
    """The rates and QoS of each world from its UAVs' loads (``coverage_of``'s arithmetic, per world)."""
    active = served > 0
    rate_mbps = config.capacity_mbps / np.maximum(served, 1)
    n_fast = (served * (rate_mbps >= config.min_user_rate_mbps)).sum(axis=1)
    covered = served.sum(axis=1)
    users = np.maximum(n_users, 1)  # a world without users has none covered: its shares are 0.0
    return CoverageBatch(
        association=association, in_range=in_range, offsets=offsets, users_per_uav=served,
        throughput_per_user_mbps=rate_mbps * active, covered_users=covered, n_users=n_users,
        qos_s1=covered / users, qos_s2=n_fast / users,
        mean_throughput_mbps=config.capacity_mbps * active.sum(axis=1) / users, config=config)


def _stacked(parts: list[Coverage], offsets: np.ndarray, n_users: np.ndarray, n_uavs: int,
             config: RadioConfig) -> CoverageBatch:
    """One :class:`CoverageBatch` from each world's :class:`~uav_swarm.world.comms.Coverage`."""
    served = np.array([cov.users_per_uav for cov in parts], np.int64).reshape(len(parts), n_uavs)
    return _from_loads(np.concatenate([cov.association for cov in parts]),
                       np.concatenate([cov.in_range for cov in parts]), offsets, served, n_users, config)


def _wifi_batch(users_m: np.ndarray, copy_index: np.ndarray, uavs_m: np.ndarray, config: RadioConfig,
                associations: Sequence[Association] | StackedIncumbents | None,
                altitudes_m: np.ndarray | None, channels: np.ndarray | None,
                enabled: np.ndarray | None = None) -> CoverageBatch:
    """The 802.11 model of all worlds at once; ``associations`` hold the incumbents."""
    n_copies, n_uavs = uavs_m.shape[0], uavs_m.shape[1]
    offsets = np.searchsorted(copy_index, np.arange(n_copies + 1)) if n_copies > 1 \
        else np.array([0, len(users_m)])
    previous = None
    if isinstance(associations, StackedIncumbents):
        links = wifi_links(users_m, copy_index, uavs_m, config, altitudes_m, channels,
                           associations.previous(offsets), enabled)
        associations.remember(links.association, offsets)
        return _of_links(links, config)
    if associations is not None:
        if len(associations) != n_copies:
            raise ValueError(f"the 802.11 model needs one Association per world ({n_copies}) or none")
        rows = np.arange(n_uavs)
        previous = np.concatenate([link.incumbents(rows, int(offsets[c + 1] - offsets[c]))
                                   for c, link in enumerate(associations)])
    links = wifi_links(users_m, copy_index, uavs_m, config, altitudes_m, channels, previous, enabled)
    if associations is not None:
        for c, link in enumerate(associations):
            link.remember(links.association[offsets[c]:offsets[c + 1]])
    return _of_links(links, config)


def _of_links(links: WifiLinks, config: RadioConfig) -> CoverageBatch:
    """The :class:`CoverageBatch` of what the 802.11 model computed."""
    return CoverageBatch(
        association=links.association, in_range=links.in_range, offsets=links.offsets,
        users_per_uav=links.users_per_uav, throughput_per_user_mbps=links.throughput_per_user_mbps,
        covered_users=links.covered_users,
        n_users=links.n_users, qos_s1=links.qos_s1, qos_s2=links.qos_s2,
        mean_throughput_mbps=links.mean_throughput_mbps, config=config, links=links)
