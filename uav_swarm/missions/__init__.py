"""Missions implemented as :class:`learning.task.Task`.

- :mod:`~uav_swarm.missions.wifi`: Wi-Fi strategies 1 and 2.
- :mod:`~uav_swarm.missions.monitoring`: Art Gallery and Fortress guards.
- :mod:`~uav_swarm.missions.registry`: task names to Tasks, refiners and rule checks.

May import: ``typed_config``, ``learning``, ``bridge``, ``uav_swarm.world``.
"""
