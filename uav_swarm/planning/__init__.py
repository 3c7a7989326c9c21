"""Planning: from the live crowd to one target per UAV.

- :mod:`~uav_swarm.planning.planner`: the planners (learned: CNN, peaks, optional rule check and
  refinement; expert), built from a :class:`~uav_swarm.planning.planner.PlannerConfig`.
- :mod:`~uav_swarm.planning.base`: the planners' settings, result, interface and assignment step.
- :mod:`~uav_swarm.planning.batch`: many worlds planned with one forward pass of the network.
- :mod:`~uav_swarm.planning.motion`: planning in motion (follow, keep, re-solve when it pays).
- :mod:`~uav_swarm.planning.horizon`: the motion horizon's options and instants in one radio-model pass.
- :mod:`~uav_swarm.planning.parking`: where a spare UAV parks under a user cap (a compiled ring search).
- :mod:`~uav_swarm.planning.assignment`: UAVs to targets (Hungarian matching with hysteresis).
- :mod:`~uav_swarm.planning.spacing`: the targets kept the minimum separation apart (the last projection).
- :mod:`~uav_swarm.planning.transitions`: between two plans, when and by where each UAV leaves so that no
  pair comes closer than the minimum; :mod:`~uav_swarm.planning.departures` its search and
  :mod:`~uav_swarm.planning.trajectory` the flights it checks, flown step by step with the env's kinematics.

May import: ``typed_config``, ``learning``, ``uav_swarm.world``, ``uav_swarm.missions``, ``uav_swarm.env``.
"""
