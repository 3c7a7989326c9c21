"""The Wi-Fi expert under the 802.11 radio: positions and channels judged by the model itself.

Under the 802.11 model (:mod:`uav_swarm.world.wifi.coverage`) no coverage radius or per-UAV load bound
describes a good placement: what a UAV delivers depends on its distance to each user (path loss, MCS), on
the airtime its access point shares with co-channel neighbours that hear it, and on the interference of
those that do not. So this expert optimises the mission's QoS itself, computed by the model for every
candidate at once (one batch of worlds per move):

- the **score** of a placement is ``(users served, total throughput)``, compared in that order; a user is
  served when it has a usable rate (strategy 1: MCS 0 or better) or at least ``min_user_rate_mbps``
  (strategy 2);
- every placement is judged with its **channel plan**, the greedy colouring of the carrier-sense graph
  (:func:`uav_swarm.world.wifi.channels.plan_channels`), so the expert places positions *and* channels;
- **greedy**: UAVs are added one at a time at the grid candidate that raises the score most (ties: the
  lowest candidate index), while the new UAV serves at least ``min_gain_users`` more users;
- **polish**: each UAV may move to a point of a finer grid around it (``polish_radius_m``, ``polish_step_m``);
  the best improving move of all UAVs is applied, until none improves or ``max_moves`` is reached;
- **prune**: a UAV whose removal loses fewer than ``min_gain_users`` served users is removed (the last
  such first), so that every UAV kept earns its place.

:func:`refine_80211` runs the same three steps from proposed positions (a learned planner's peaks): the
greedy then only adds what the proposals miss, which makes it several times cheaper than the expert.

Every candidate keeps ``min_separation_m`` to the other UAVs, and every step is deterministic (ties by
index): the same crowd gives the same placement, and a crowd moved by a few centimetres gives the same
choices wherever no score is tied within the moved users.

Examples:
    >>> import numpy as np
    >>> from uav_swarm.world.radio_config import RadioConfig
    >>> radio = RadioConfig(propagation="802.11", altitude_m=10.0, min_user_rate_mbps=5.0)
    >>> rng = np.random.default_rng(0)
    >>> users = np.vstack([rng.normal((50.0, 50.0), 3.0, (30, 2)), rng.normal((150.0, 150.0), 3.0, (30, 2))])
    >>> placement = place_uavs_80211(users, radio, 200.0, 200.0, strategy=2, max_uavs=4,
    ...                              min_separation_m=5.0, config=Ieee80211ExpertConfig())
    >>> len(placement) >= 2, bool(np.all(np.abs(placement - 100.0) <= 100.0))
    (True, True)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from typed_config import Config, param
from uav_swarm.world.radio_config import RadioConfig
from uav_swarm.world.wifi.channels import plan_channels
from uav_swarm.world.wifi.coverage import wifi_links

__all__ = ["Ieee80211ExpertConfig", "placement_scores", "place_uavs_80211", "refine_80211"]


@dataclass(frozen=True)
class Ieee80211ExpertConfig(Config):
    """Settings of the 802.11 expert (``[task.expert.ieee80211]``)."""

    grid_step_m: float = param(10.0, gt=0.0, le=50.0, doc="spacing of the greedy's candidate grid, metres")
    min_gain_users: int = param(
        5, ge=1, le=10_000, doc="a UAV is added (and kept) only while it serves at least this many more "
        "users")
    polish_radius_m: float = param(5.0, ge=0.0, le=50.0, doc="how far the polish moves a UAV, metres")
    polish_step_m: float = param(2.5, gt=0.0, le=50.0, doc="spacing of the polish's grid, metres")
    max_moves: int = param(20, ge=0, le=1000, doc="improving polish moves allowed (0: no polish)")


def placement_scores(users_m: np.ndarray, placements_m: np.ndarray, radio: RadioConfig,
                     altitudes_m: np.ndarray, strategy: int) -> tuple[np.ndarray, np.ndarray]:
    """Users served and total throughput (Mbps) of B placements of K UAVs, each with its channel plan.

    Args:
        users_m: (N, 2) user positions, metres.
        placements_m: (B, K, 2) UAV positions of each placement, metres.
        radio: The 802.11 radio (``propagation = "802.11"``).
        altitudes_m: (K,) each UAV's height above the users, metres.
        strategy: 1 (a usable rate) or 2 (at least ``radio.min_user_rate_mbps``).

    Returns:
        ``(served (B,) int, throughput_mbps (B,) float)``.
    """
    placements = np.asarray(placements_m, dtype=np.float64)
    n_worlds, n_users = placements.shape[0], len(users_m)
    if n_worlds == 0 or placements.shape[1] == 0:
        return np.zeros(n_worlds, np.int64), np.zeros(n_worlds)
    plans = plan_channels(placements, radio, altitudes_m)
    links = wifi_links(np.tile(users_m, (n_worlds, 1)), np.repeat(np.arange(n_worlds), n_users), placements,
                       radio, altitudes_m, plans)
    share = links.qos_s1 if strategy == 1 else links.qos_s2
    served = np.rint(share * n_users).astype(np.int64)
    return served, links.mean_throughput_mbps * n_users


def _best(served: np.ndarray, throughput_mbps: np.ndarray) -> int:
    """Index of the best score: most served, then most throughput, then the lowest index."""
    return int(np.lexsort((np.arange(len(served)), -throughput_mbps, -served))[0])


def _separated(points_m: np.ndarray, others_m: np.ndarray, min_separation_m: float) -> np.ndarray:
    """(M,) True where a point stands at least ``min_separation_m`` from every one of ``others_m``."""
    if len(others_m) == 0 or min_separation_m <= 0.0:
        return np.ones(len(points_m), bool)
    gaps = np.linalg.norm(points_m[:, None, :] - others_m[None, :, :], axis=2)
    return np.asarray(gaps.min(axis=1) >= min_separation_m)


class _Search:
    """One crowd's placement search: the greedy, the polish and the prune (module docstring)."""

    def __init__(self, users_m: np.ndarray, radio: RadioConfig, width_m: float, height_m: float,
                 strategy: int, max_uavs: int, min_separation_m: float, altitude_m: float,
                 config: Ieee80211ExpertConfig) -> None:
        self.users_m, self.radio, self.strategy = users_m, radio, strategy
        self.width_m, self.height_m = width_m, height_m
        self.max_uavs, self.min_separation_m, self.config = max_uavs, min_separation_m, config
        self.altitude_m = altitude_m
        step = config.grid_step_m
        xs = np.arange(step / 2.0, width_m, step)
        ys = np.arange(step / 2.0, height_m, step)
        grid = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
        # Only candidates some user can hear at MCS 0 matter; the others serve nobody.
        self.candidates_m = grid[self._heard(grid)]
        self.uavs_m = np.zeros((0, 2))
        self.served, self.throughput_mbps = 0, 0.0

    def _heard(self, points_m: np.ndarray) -> np.ndarray:
        if len(self.users_m) == 0 or len(points_m) == 0:
            return np.zeros(len(points_m), bool)
        served, _ = placement_scores(self.users_m, points_m[:, None, :], self.radio.replace(
            ieee80211=self.radio.ieee80211.replace(rate_admission=False), station_limit=None),
            np.array([self.altitude_m]), 1)
        return np.asarray(served > 0)

    def scores(self, placements_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:func:`placement_scores` of (B, K, 2) placements of this crowd, at the search's height."""
        heights = np.full(placements_m.shape[1], self.altitude_m)
        return placement_scores(self.users_m, placements_m, self.radio, heights, self.strategy)

    def adopt(self, uavs_m: np.ndarray) -> None:
        """Go on from these ``(k, 2)`` UAV positions (separated, inside the area)."""
        served, throughput = self.scores(uavs_m[None])
        self.uavs_m, self.served, self.throughput_mbps = uavs_m, int(served[0]), float(throughput[0])

    def greedy(self) -> None:
        """Add UAVs while one serves at least ``min_gain_users`` more users."""
        while len(self.uavs_m) < self.max_uavs:
            options = self.candidates_m[_separated(self.candidates_m, self.uavs_m, self.min_separation_m)]
            if len(options) == 0:
                return
            worlds = np.concatenate([np.broadcast_to(self.uavs_m, (len(options), *self.uavs_m.shape)),
                                     options[:, None, :]], axis=1)
            served, throughput = self.scores(worlds)
            best = _best(served, throughput)
            if served[best] - self.served < self.config.min_gain_users:
                return
            self.uavs_m = worlds[best]
            self.served, self.throughput_mbps = int(served[best]), float(throughput[best])

    def polish(self) -> None:
        """Apply the best improving move of one UAV on the fine grid around it, until none improves."""
        radius, step = self.config.polish_radius_m, self.config.polish_step_m
        offsets_1d = np.arange(-radius, radius + 1e-9, step)
        offsets = np.stack(np.meshgrid(offsets_1d, offsets_1d), axis=-1).reshape(-1, 2)
        offsets = offsets[np.any(offsets != 0.0, axis=1)]
        for _ in range(self.config.max_moves):
            worlds, n_uavs = [], len(self.uavs_m)
            for j in range(n_uavs):
                moved = self.uavs_m[j] + offsets
                inside = np.all((moved >= 0.0) & (moved <= (self.width_m, self.height_m)), axis=1)
                others = np.delete(self.uavs_m, j, axis=0)
                moved = moved[inside & _separated(moved, others, self.min_separation_m)]
                trial = np.broadcast_to(self.uavs_m, (len(moved), n_uavs, 2)).copy()
                trial[:, j] = moved
                worlds.append(trial)
            if not worlds or sum(len(w) for w in worlds) == 0:
                return
            stacked = np.concatenate(worlds)
            served, throughput = self.scores(stacked)
            best = _best(served, throughput)
            better = served[best] > self.served or (
                served[best] == self.served and throughput[best] > self.throughput_mbps + 1e-6)
            if not better:
                return
            self.uavs_m = stacked[best]
            self.served, self.throughput_mbps = int(served[best]), float(throughput[best])

    def prune(self) -> None:
        """Remove the UAVs that serve fewer than ``min_gain_users`` users the others would not."""
        while len(self.uavs_m) > 1:
            n_uavs = len(self.uavs_m)
            worlds = np.stack([np.delete(self.uavs_m, j, axis=0) for j in range(n_uavs)])
            served, throughput = self.scores(worlds)
            loss = self.served - served
            # The last UAV whose removal costs least, if that costs fewer than min_gain_users.
            j = int(np.lexsort((-np.arange(n_uavs), loss))[0])
            if loss[j] >= self.config.min_gain_users:
                return
            self.uavs_m = worlds[j]
            self.served, self.throughput_mbps = int(served[j]), float(throughput[j])


def _checked(users_m: np.ndarray, radio: RadioConfig, altitude_m: float | None) -> tuple[np.ndarray, float]:
    users_m = np.asarray(users_m, dtype=np.float64)
    if users_m.ndim != 2 or users_m.shape[1] != 2 or not np.all(np.isfinite(users_m)):
        raise ValueError(f"users_m must be a finite (N, 2) array, got shape {users_m.shape}")
    if radio.propagation != "802.11":
        raise ValueError("the 802.11 expert needs RadioConfig.propagation = '802.11', "
                         f"got {radio.propagation!r}")
    height = radio.altitude_m if altitude_m is None else altitude_m
    if not height > 0.0:
        raise ValueError("the 802.11 expert needs the UAVs' altitude: set RadioConfig.altitude_m (> 0)")
    return users_m, height


def _sorted(uavs_m: np.ndarray) -> np.ndarray:
    return uavs_m[np.lexsort((uavs_m[:, 0], uavs_m[:, 1]))] if len(uavs_m) else np.zeros((0, 2))


def refine_80211(users_m: np.ndarray, proposals_m: np.ndarray, radio: RadioConfig, width_m: float,
                 height_m: float, *, strategy: int, max_uavs: int, min_separation_m: float,
                 config: Ieee80211ExpertConfig, altitude_m: float | None = None) -> np.ndarray:
    """Proposed positions refined on the crowd: the expert's greedy, polish and prune from them.

    Proposals outside the area are clipped into it; a proposal closer than ``min_separation_m`` to one kept
    before it is dropped; at most ``max_uavs`` are kept. Arguments and result as :func:`place_uavs_80211`.

    Raises:
        ValueError: As :func:`place_uavs_80211`, or ``proposals_m`` not a finite ``(k, 2)`` array.
    """
    users_m, height = _checked(users_m, radio, altitude_m)
    proposals = np.asarray(proposals_m, dtype=np.float64).reshape(-1, 2)
    if not np.all(np.isfinite(proposals)):
        raise ValueError("proposals_m must be finite")
    proposals = np.clip(proposals, 0.0, (width_m, height_m))
    kept = np.zeros((0, 2))
    for point in proposals[:max_uavs]:
        if _separated(point[None], kept, min_separation_m)[0]:
            kept = np.vstack([kept, point])
    search = _Search(users_m, radio, width_m, height_m, strategy, max_uavs, min_separation_m, height, config)
    if len(kept):
        search.adopt(kept)
    search.greedy()
    search.polish()
    search.prune()
    return _sorted(search.uavs_m)


def place_uavs_80211(users_m: np.ndarray, radio: RadioConfig, width_m: float, height_m: float, *,
                     strategy: int, max_uavs: int, min_separation_m: float, config: Ieee80211ExpertConfig,
                     altitude_m: float | None = None) -> np.ndarray:
    """The 802.11 expert's placement for one crowd (module docstring).

    Args:
        users_m: ``(N, 2)`` user positions, metres.
        radio: The 802.11 radio (``propagation = "802.11"``).
        width_m: Area width (x extent), metres.
        height_m: Area height (y extent), metres.
        strategy: 1 (share with a usable rate) or 2 (share with at least ``radio.min_user_rate_mbps``).
        max_uavs: Largest number of UAVs.
        min_separation_m: No two UAVs closer than this (horizontal), metres.
        config: The expert's settings.
        altitude_m: The UAVs' height above the users; None: ``radio.altitude_m``.

    Returns:
        ``(k, 2)`` float64 UAV positions in metres, ``0 <= k <= max_uavs``, sorted by ``(y, x)``.

    Raises:
        ValueError: ``users_m`` is not a finite ``(N, 2)`` array, the radio is not the 802.11 model, or no
            altitude is known.
    """
    users_m, height = _checked(users_m, radio, altitude_m)
    search = _Search(users_m, radio, width_m, height_m, strategy, max_uavs, min_separation_m, height, config)
    search.greedy()
    search.polish()
    search.prune()
    return _sorted(search.uavs_m)
