"""Planning: from the live crowd to one target per UAV.

- :mod:`~uav_swarm.planning.planner`: the planners (learned: CNN, peaks, optional rule check and
  refinement; expert), built from a :class:`~uav_swarm.planning.planner.PlannerConfig`.
- :mod:`~uav_swarm.planning.assignment`: UAVs to targets (Hungarian matching with hysteresis).
"""
