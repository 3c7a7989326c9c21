"""The Wi-Fi missions (strategies 1 and 2 of the paper).

- :mod:`~uav_swarm.missions.wifi.task`: the :class:`~learning.task.Task` (scenes, rasters, QoS).
- :mod:`~uav_swarm.missions.wifi.rules`: the deployment rules and user association.
- :mod:`~uav_swarm.missions.wifi.expert`, :mod:`~uav_swarm.missions.wifi.exact`: the experts.
- :mod:`~uav_swarm.missions.wifi.refine`, :mod:`~uav_swarm.missions.wifi.relocation`: refinement
  of learned placements with the rules' guarantee.
- :mod:`~uav_swarm.missions.wifi.rule_check`: the rule checked on the network's own input.

May import: ``typed_config``, ``learning``, ``uav_swarm.world``.
"""
