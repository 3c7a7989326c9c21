"""Planning in motion: a replan starts from where the UAVs are and what they serve.

A snapshot planner solves every instant from scratch, so its targets jump from one combination to
another and the UAVs chase placements they never reach. :class:`MotionPlanning` instead keeps what
works and changes only what a change pays for:

1. **Follow.** Each UAV remembers the users it served at the last replan. Its followed target is
   their centroid now, plus the offset it had from them, plus their mean velocity times
   ``lead_s`` (aimed where they will be when the UAV gets there): a UAV walks with its group.
2. **Keep or release.** A followed UAV is kept while, on the crowd predicted ``lead_s`` ahead, its
   users still satisfy the strategy's rule (more than ``min_users``; at most ``max_users`` for
   strategy 2). Under admission control (``rules.admission_control``) a UAV's users are those the radio
   admits (:func:`uav_swarm.missions.wifi.capacitated.admitted_users`): it keeps and follows them, and
   the cap needs no margin since a full UAV refuses newcomers. Released UAVs, and UAVs without users,
   are free.
3. **Options.** *Hybrid*: the kept UAVs follow; the base planner's proposals that no kept UAV
   already covers (none within the coverage radius) go to the free UAVs. *Fresh*: every UAV goes to
   a proposal. Proposals are aimed at where their users will be when the UAV arrives. Both are
   assigned by **time to reach** under the UAVs' speed and acceleration limits (Hungarian on the
   squared times, so no UAV gets a far target another could reach sooner).
4. **Judge over the horizon.** Each option is flown forward in a simple model: the UAVs travel
   along straight lines with a trapezoidal speed profile, targets move with their users, and the
   crowd with its velocities; the strategy's QoS (the radio model of
   :func:`uav_swarm.world.comms.evaluate_coverage`) is averaged over ``samples`` instants of the
   next ``horizon_s`` seconds. The fresh option replaces the hybrid only when it gains more than
   ``switch_margin`` (a share of the crowd), so the swarm re-solves when a re-solve pays after the
   time to fly there, and otherwise keeps its service.

Examples:
    >>> time_to_reach(np.array([0.0, 2.5, 100.0]), 10.0, 5.0).round(2).tolist()
    [0.0, 1.41, 12.0]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from typed_config import Config, param
from uav_swarm.missions.wifi.capacitated import admitted_users
from uav_swarm.missions.wifi.rules import CoverageRules, assign_users
from uav_swarm.planning.horizon import horizon_qos, travelled_m
from uav_swarm.planning.parking import parking_spot
from uav_swarm.planning.spacing import separate_targets
from uav_swarm.world.comms import RadioConfig
from uav_swarm.world.uav import UAVConfig

__all__ = ["MotionConfig", "MotionPlan", "MotionPlanning", "time_to_reach", "travelled_m"]


@dataclass(frozen=True)
class MotionConfig(Config):
    """Settings of planning in motion (:mod:`uav_swarm.planning.motion`)."""

    horizon_s: float = param(6.0, gt=0.0, le=120.0, doc="an option's QoS is judged over the next this many s")
    samples: int = param(4, ge=1, le=100, doc="instants of the horizon the QoS is averaged over")
    lead_s: float = param(1.0, ge=0.0, le=30.0, doc="targets aim where their users will be this far ahead, s")
    range_margin_m: float = param(
        1.0, ge=0.0, le=20.0, doc="strategy 2: a UAV's load counts the users within radius + this (they "
        "walk in), so a kept or added UAV is not at the cap's edge, m")
    park_margin_m: float = param(
        5.0, ge=0.0, le=100.0, doc="strategy 2: a spare UAV parks at least radius + this from every user, m")
    stick_m: float = param(
        5.0, ge=0.0, le=100.0, doc="a free UAV keeps the proposal within this distance of its last target, m")
    switch_margin: float = param(
        0.01, ge=0.0, le=1.0, doc="a fresh solve replaces keeping the service only when it gains this "
        "much QoS (share of the crowd, averaged over the horizon)")


@dataclass(frozen=True)
class MotionPlan:
    """One replan in motion.

    Attributes:
        targets_m: ``(n, 2)`` target of each UAV, metres.
        kept: ``(n,)`` True where the UAV kept following its users.
        candidate_index: ``(n,)`` index of the proposal each UAV flies to, -1 where it follows or holds.
        option: ``"hybrid"`` or ``"fresh"``: the option chosen.
        horizon_qos: The chosen option's QoS averaged over the horizon (the model of the module docstring).
        separation_shift_m: ``(n, 2)`` how far the last projection moved each target to keep the minimum
            separation (zeros where it kept the target it was given).
    """

    targets_m: np.ndarray
    kept: np.ndarray
    candidate_index: np.ndarray
    option: str
    horizon_qos: float
    separation_shift_m: np.ndarray


def time_to_reach(distance_m: np.ndarray, max_speed_m_s: float, max_accel_m_s2: float) -> np.ndarray:
    """Seconds to fly ``distance_m`` from rest to rest (trapezoidal speed profile)."""
    d = np.asarray(distance_m, dtype=np.float64)
    ramp_m = max_speed_m_s ** 2 / max_accel_m_s2  # accelerating and braking at full speed
    cruising = d / max_speed_m_s + max_speed_m_s / max_accel_m_s2
    return np.where(d <= ramp_m, 2.0 * np.sqrt(d / max_accel_m_s2), cruising)


class MotionPlanning:
    """The state of planning in motion over one sequence (see the module docstring).

    Args:
        n_uavs: Number of UAVs.
        rules: The strategy's rules (coverage radius, users per UAV).
        radio: The radio model the QoS is judged with.
        strategy: 1 (QoS = covered share) or 2 (covered with the minimum rate).
        area_m: ``(width, height)`` of the area; targets stay inside.
        uav: The UAVs' speed and acceleration limits.
        config: Horizon, lead and switching margin.
        min_gap_m: Smallest distance between two targets (the UAVs' minimum separation).
    """

    def __init__(self, n_uavs: int, rules: CoverageRules, radio: RadioConfig, strategy: int,
                 area_m: tuple[float, float], uav: UAVConfig | None = None,
                 config: MotionConfig | None = None, min_gap_m: float = 1.0) -> None:
        self.n_uavs = n_uavs
        self.area_m = np.asarray(area_m, dtype=np.float64)
        self.min_gap_m = min_gap_m
        self.rules = rules
        self.radio = radio
        self.strategy = strategy
        self.uav = uav or UAVConfig()
        self.config = config or MotionConfig()
        self.reset()

    def reset(self) -> None:
        """Forget every UAV's users (a new sequence starts)."""
        self._users: list[np.ndarray] = [np.zeros(0, np.int64) for _ in range(self.n_uavs)]
        self._offsets = np.zeros((self.n_uavs, 2))
        self._previous: np.ndarray | None = None  # the last targets
        self._n_pedestrians = -1

    # --- the steps of one replan ------------------------------------------------------------

    def _followed(self, peds: np.ndarray, vels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(targets (n, 2), following (n,) bool)`` of every UAV that remembers its users."""
        targets = np.zeros((self.n_uavs, 2))
        following = np.zeros(self.n_uavs, dtype=bool)
        if self._n_pedestrians != len(peds):
            return targets, following
        for j, users in enumerate(self._users):
            if len(users):
                targets[j] = peds[users].mean(axis=0) + vels[users].mean(axis=0) * self.config.lead_s
                targets[j] += self._offsets[j]
                following[j] = True
        return targets, following

    def _healthy(self, predicted: np.ndarray, targets: np.ndarray, following: np.ndarray) -> np.ndarray:
        """``(n,)`` True where a following UAV's users satisfy the rule on the predicted crowd."""
        healthy = np.zeros(self.n_uavs, dtype=bool)
        index = np.flatnonzero(following)
        if len(index) == 0:
            return healthy
        _, justified = self._association(predicted, targets[index])
        healthy[index] = (justified >= self.rules.min_users) & (self._loads(predicted, targets[index])
                                                                 <= self.rules.cap)
        return healthy

    def _association(self, users: np.ndarray, targets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(association (N,), justified (k,))``: who each target serves and the count its rule reads.

        Under admission control the association is the radio's (a full UAV refuses, the refused join
        their next UAV in range) and a UAV is justified by the users it admits; otherwise users join
        their nearest target and the strategy's count applies (exclusive users for strategy 1).
        """
        if self.rules.admission_control:
            association = admitted_users(users, targets, self.rules)
            return association, np.bincount(association[association >= 0], minlength=len(targets))
        state = assign_users(users, targets, self.rules.radius_m)
        return state.association, state.exclusive_counts if self.rules.exclusive else state.counts

    def _loads(self, predicted: np.ndarray, targets: np.ndarray) -> np.ndarray:
        """``(k,)`` users each target would serve with its reach widened by ``range_margin_m``.

        Zero under admission control: a full UAV refuses newcomers, so no load breaks the rule.
        """
        if self.rules.max_users is None or self.rules.admission_control:
            return np.zeros(len(targets), np.int64)
        return assign_users(predicted, targets, self.rules.radius_m + self.config.range_margin_m).counts

    def _aimed(self, proposals: np.ndarray, peds: np.ndarray, vels: np.ndarray) -> np.ndarray:
        """Each proposal moved with the users it serves for ``lead_s``.

        The same lead for all, so a placement that keeps the rule now keeps it on the crowd the
        UAVs will meet.
        """
        return proposals + self._users_velocity(proposals, peds, vels) * self.config.lead_s

    def _users_velocity(self, targets: np.ndarray, peds: np.ndarray, vels: np.ndarray) -> np.ndarray:
        """``(k, 2)`` mean velocity of the users each target serves (zero for a target serving none)."""
        velocity = np.zeros_like(targets)
        if len(targets) == 0 or len(peds) == 0:
            return velocity
        owner, _ = self._association(peds, targets)
        served = owner >= 0
        counts = np.maximum(np.bincount(owner[served], minlength=len(targets)), 1)
        for axis in (0, 1):
            velocity[:, axis] = np.bincount(owner[served], weights=vels[served, axis], minlength=len(targets))
        return velocity / counts[:, None]

    def _assign(self, uavs: np.ndarray, free: np.ndarray, proposals: np.ndarray) -> np.ndarray:
        """``(n,)`` proposal index of each free UAV (-1: none), by least total squared time to reach."""
        index = np.full(self.n_uavs, -1, dtype=np.int64)
        free = free.copy()
        open_ = np.ones(len(proposals), dtype=bool)
        if self._previous is not None and np.any(free) and len(proposals):
            # a free UAV whose last target drifted less than stick_m keeps it (no jump for a drift)
            ids = np.flatnonzero(free)
            drift = np.linalg.norm(self._previous[ids, None, :] - proposals[None, :, :], axis=-1)
            rows, cols = linear_sum_assignment(drift)
            for row, col in zip(rows, cols, strict=True):
                if drift[row, col] <= self.config.stick_m:
                    index[ids[row]] = col
                    free[ids[row]] = False
                    open_[col] = False
        uav_ids = np.flatnonzero(free)
        cand_ids = np.flatnonzero(open_)
        if len(uav_ids) == 0 or len(cand_ids) == 0:
            return index
        distance = np.linalg.norm(uavs[uav_ids, None, :] - proposals[None, cand_ids, :], axis=-1)
        cost = time_to_reach(distance, self.uav.max_speed_m_s, self.uav.max_accel_m_s2) ** 2
        rows, cols = linear_sum_assignment(cost)
        index[uav_ids[rows]] = cand_ids[cols]
        return index

    def _valid(self, predicted: np.ndarray, targets: np.ndarray) -> bool:
        """Whether every UAV at ``targets`` satisfies the rule on the predicted crowd."""
        _, justified = self._association(predicted, targets)
        return bool(np.all(justified >= self.rules.min_users)
                    and np.all(self._loads(predicted, targets) <= self.rules.cap))

    def _fill(self, predicted: np.ndarray, kept_m: np.ndarray, proposals: np.ndarray, free: int
              ) -> np.ndarray:
        """Indices of the proposals added to the kept UAVs, best first, while the rule holds for all.

        A proposal within the coverage radius of a kept UAV duplicates it and is skipped; a proposal
        that breaks the rule alone is tried again with its nearest neighbour among the proposals
        (a group split between two UAVs needs both).
        """
        chosen: list[int] = []
        near_kept = np.linalg.norm(proposals[:, None, :] - kept_m[None], axis=-1).min(axis=1)
        open_ = [i for i in range(len(proposals)) if near_kept[i] > self.rules.radius_m]
        for i in open_:
            if len(chosen) >= free or i in chosen:
                continue
            base = np.vstack([kept_m, proposals[chosen]]) if chosen else kept_m
            if self._valid(predicted, np.vstack([base, proposals[i]])):
                chosen.append(i)
                continue
            others = [j for j in open_ if j != i and j not in chosen]
            if len(chosen) + 2 > free or not others:
                continue
            j = others[int(np.argmin(np.linalg.norm(proposals[others] - proposals[i], axis=1)))]
            if self._valid(predicted, np.vstack([base, proposals[[i, j]]])):
                chosen += [i, j]
        return np.array(chosen, dtype=np.int64)

    def _option(self, uavs: np.ndarray, peds: np.ndarray, vels: np.ndarray, followed: np.ndarray,
                kept: np.ndarray, proposals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(targets, candidate index)``: kept UAVs follow, free ones fly to the proposals (aimed)."""
        index = self._assign(uavs, ~kept, proposals)
        targets = np.where(kept[:, None], followed, uavs)
        moving = index >= 0
        if np.any(moving):
            targets[moving] = self._aimed(proposals, peds, vels)[index[moving]]
        return targets, index

    def horizon_qos(self, peds: np.ndarray, vels: np.ndarray, uavs: np.ndarray, targets: np.ndarray,
                    serving: np.ndarray | None = None) -> float:
        """The strategy's QoS averaged over the horizon (module docstring, step 4).

        ``serving``: (n,) the UAVs the targets give users (802.11: the others' access points are off).
        """
        return self._judge(peds, vels, uavs, [targets], None if serving is None else [serving])[0]

    def _judge(self, peds: np.ndarray, vels: np.ndarray, uavs: np.ndarray, options: list[np.ndarray],
               serving: list[np.ndarray] | None = None) -> list[float]:
        """Every option's horizon QoS, all options and instants in one radio-model pass."""
        cfg = self.config
        velocities = [self._users_velocity(targets, peds, vels) for targets in options]
        if self.radio.propagation != "802.11" or not self.radio.ieee80211.admits_on_rate:
            serving = None  # spares' APs are off only under admission on rate, as simulate flies them
        return horizon_qos(peds, vels, uavs, options, velocities, self.radio, self.strategy, cfg.horizon_s,
                           cfg.samples, self.uav.max_speed_m_s, self.uav.max_accel_m_s2, serving)

    def _remember(self, peds: np.ndarray, vels: np.ndarray, targets: np.ndarray) -> None:
        """Each UAV's users at its new target (on the crowd ``lead_s`` ahead) and its offset from them."""
        predicted = peds + vels * self.config.lead_s
        association, _ = self._association(predicted, targets)
        for j in range(self.n_uavs):
            users = np.flatnonzero(association == j)
            self._users[j] = users
            self._offsets[j] = (targets[j] - predicted[users].mean(axis=0)) if len(users) else 0.0
        self._n_pedestrians = len(peds)
        self._previous = targets.copy()

    def plan(self, peds: np.ndarray, vels: np.ndarray, uavs: np.ndarray, proposals: np.ndarray) -> MotionPlan:
        """One replan (module docstring).

        Args:
            peds: ``(N, 2)`` pedestrian positions, metres.
            vels: ``(N, 2)`` pedestrian velocities, m/s.
            uavs: ``(n, 2)`` UAV positions, metres.
            proposals: ``(k, 2)`` the base planner's placement of the crowd, metres, best first.
        """
        followed, following = self._followed(peds, vels)
        predicted = peds + vels * self.config.lead_s
        kept = self._healthy(predicted, followed, following)
        uncovered = np.arange(len(proposals))
        if np.any(kept) and len(proposals):
            uncovered = self._fill(predicted, followed[kept], proposals,
                                   self.n_uavs - int(kept.sum()))
        targets, index = self._option(uavs, peds, vels, followed, kept, proposals[uncovered])
        if len(uncovered):
            index = np.where(index >= 0, uncovered[np.maximum(index, 0)], -1)
        option = "hybrid"
        targets, shift = self._finish(targets, index, kept, predicted)
        if np.any(kept):
            none = np.zeros(self.n_uavs, dtype=bool)
            fresh, fresh_index = self._option(uavs, peds, vels, followed, none, proposals)
            fresh, fresh_shift = self._finish(fresh, fresh_index, none, predicted)
            qos, fresh_qos = self._judge(peds, vels, uavs, [targets, fresh],  # both options, one pass
                                         [kept | (index >= 0), fresh_index >= 0])
            if fresh_qos > qos + self.config.switch_margin:
                targets, index, kept, option, qos = fresh, fresh_index, none, "fresh", fresh_qos
                shift = fresh_shift
        else:
            qos = self.horizon_qos(peds, vels, uavs, targets, kept | (index >= 0))
        self._remember(peds, vels, targets)
        return MotionPlan(targets, kept.copy(), index, option, qos, shift)

    def _finish(self, targets: np.ndarray, index: np.ndarray, kept: np.ndarray, predicted: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
        """Targets inside the area, at least ``min_gap_m`` apart; spares parked or holding.

        Under a user cap (strategy 2) a spare (neither following nor flying to a proposal) parks where no
        user is within reach, so it never takes users from a planned UAV nor serves more than the cap;
        without a cap it holds. Then the targets are separated in priority order (kept followers, the
        proposals, the spares): followers that drifted together, or proposals aimed closer than the
        minimum, are moved apart as little as the search finds. Returns the targets and that shift.
        """
        out = np.clip(targets, 0.0, self.area_m)
        spare = (index < 0) & ~kept
        if self.rules.max_users is not None and np.any(spare) and len(predicted):
            reach_m = self.rules.radius_m + self.config.park_margin_m
            for j in np.flatnonzero(spare):
                start = out[j] if self._previous is None else self._previous[j]  # a free spot stays
                out[j] = parking_spot(predicted, start, np.delete(out, j, axis=0), self.area_m, reach_m,
                                      self.min_gap_m)
        priority = np.lexsort((np.arange(self.n_uavs), spare, ~kept))
        separated = separate_targets(out, self.min_gap_m, priority, self.area_m)
        return separated, separated - out

