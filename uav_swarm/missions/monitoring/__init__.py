"""The monitoring missions: Art Gallery (``agp``) and Fortress (``fp``) guards of a building.

- :mod:`~uav_swarm.missions.monitoring.task`: the :class:`~learning.task.Task` for both problems.
- :mod:`~uav_swarm.missions.monitoring.polygons`: random orthogonal buildings and their rasters.
- :mod:`~uav_swarm.missions.monitoring.visibility`: what a guard sees.
- :mod:`~uav_swarm.missions.monitoring.setcover`, :mod:`~uav_swarm.missions.monitoring.guards`:
  the exact experts (a set cover over candidate guards).
- :mod:`~uav_swarm.missions.monitoring.guard_repair`: repair of learned guards with the guarantee.
- :mod:`~uav_swarm.missions.monitoring.footprint`: a user's buildings (GeoJSON, sites, courtyards) and
  the raster the network sees of them.
- :mod:`~uav_swarm.missions.monitoring.outline`: a user's building in metres (GEOS): witnesses, guard
  positions and visibility with a margin, the truth a placement is judged on.
- :mod:`~uav_swarm.missions.monitoring.sightlines`: that visibility's guard-witness test, compiled (numba).
- :mod:`~uav_swarm.missions.monitoring.outline_guards`: guards judged, repaired and solved exactly on
  that outline.

May import: ``typed_config``, ``learning``, ``bridge``, ``uav_swarm.world``.
"""
