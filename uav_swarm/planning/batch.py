"""Many worlds, one pass: B worlds planned with one forward pass of the utility network.

Each world keeps its own sequence state (what its UAVs serve, its previous targets): the planners of
the worlds are forks (:meth:`~uav_swarm.planning.base.AssigningPlanner.fork`) of one planner, sharing its
settings and its inference engine. :func:`plan_batch` rasterises every world's crowd, runs the
network once on the ``(B, C, h, w)`` batch, then extracts each map's peaks and assigns them exactly as
:meth:`~uav_swarm.planning.base.AssigningPlanner.plan` does, so each world gets the targets its own
single plan would give. Planners that are not learned (the expert) are planned one by one.

Examples:
    >>> from uav_swarm.planning.planner import make_planner
    >>> worlds = [make_planner("expert", n_uavs=1) for _ in range(2)]
    >>> crowds = [np.full((40, 2), 50.0), np.full((40, 2), 150.0)]
    >>> [r.targets_m.tolist() for r in plan_batch(worlds, crowds, np.zeros((2, 1, 2)))]
    [[[50.0, 50.0]], [[150.0, 150.0]]]
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence

import numpy as np

from uav_swarm.planning.base import AssigningPlanner, PlanResult
from uav_swarm.planning.planner import LearnedPlanner

__all__ = ["plan_batch"]


def plan_batch(planners: Sequence[AssigningPlanner], pedestrians_m: Sequence[np.ndarray],
               uav_positions_m: Sequence[np.ndarray] | np.ndarray,
               pedestrian_velocities_m_s: Sequence[np.ndarray | None] | None = None) -> list[PlanResult]:
    """One replan of each of ``B`` worlds; learned planners share one forward pass.

    Args:
        planners: One planner per world (forks of one planner, each holding its world's sequence state).
        pedestrians_m: Each world's ``(N_b, 2)`` pedestrian positions, metres.
        uav_positions_m: Each world's ``(n, 2)`` UAV positions, metres.
        pedestrian_velocities_m_s: Each world's ``(N_b, 2)`` pedestrian velocities (default: at rest).

    Returns:
        Each world's :class:`~uav_swarm.planning.base.PlanResult`; ``latency_ms`` is the world's own
        assignment plus an equal share of the batch's rasters, network and peaks.

    Raises:
        ValueError: The sequences differ in length, an array has the wrong shape, or learned planners
            of different networks or settings are mixed.
    """
    n_worlds = len(planners)
    velocities = [None] * n_worlds if pedestrian_velocities_m_s is None else list(pedestrian_velocities_m_s)
    if not len(pedestrians_m) == len(uav_positions_m) == len(velocities) == n_worlds:
        raise ValueError(f"plan_batch needs one crowd, one UAV array and one velocity array per planner "
                         f"({n_worlds}), got {len(pedestrians_m)}, {len(uav_positions_m)}, {len(velocities)}")
    if n_worlds == 0:
        return []
    worlds = list(zip(planners, pedestrians_m, uav_positions_m, velocities, strict=True))
    lead = planners[0]
    if not isinstance(lead, LearnedPlanner):
        return [p.plan(peds, uavs, vels) for p, peds, uavs, vels in worlds]
    if any(not isinstance(p, LearnedPlanner) or p.engine_choice is not lead.engine_choice
           or p.config != lead.config or p.peak_config != lead.peak_config for p in planners):
        raise ValueError("plan_batch plans learned worlds with forks of one planner (planner.fork()): "
                         "these planners differ in network, engine or settings")
    start = time.perf_counter()
    checked = [p._checked(peds, uavs, vels) for p, peds, uavs, vels in worlds]
    proposals = lead.propose_batch([c[0] for c in checked], [c[1] for c in checked])
    share_ms = (time.perf_counter() - start) * 1e3 / n_worlds
    results = []
    for planner, (peds, vels, uavs), (candidates, utility) in zip(planners, checked, proposals, strict=True):
        result = planner._settle(peds, vels, uavs, candidates, utility, time.perf_counter())
        results.append(dataclasses.replace(result, latency_ms=result.latency_ms + share_ms))
    return results
