"""The monitoring missions: Art Gallery (``agp``) and Fortress (``fp``) guards of a building.

- :mod:`~uav_swarm.missions.monitoring.task`: the :class:`~learning.task.Task` for both problems.
- :mod:`~uav_swarm.missions.monitoring.polygons`: random orthogonal buildings and their rasters.
- :mod:`~uav_swarm.missions.monitoring.visibility`: what a guard sees.
- :mod:`~uav_swarm.missions.monitoring.setcover`, :mod:`~uav_swarm.missions.monitoring.guards`:
  the exact experts (a set cover over candidate guards).
- :mod:`~uav_swarm.missions.monitoring.guard_repair`: repair of learned guards with the guarantee.
- :mod:`~uav_swarm.missions.monitoring.footprint`: a user's building (GeoJSON) in the task's frame.
"""
