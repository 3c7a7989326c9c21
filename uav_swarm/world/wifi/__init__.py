"""The 802.11 radio model (the product's default radio), batch-first and pure numpy.

On the world floor: imports only ``typed_config`` and other ``uav_swarm.world`` modules.

- :mod:`~uav_swarm.world.wifi.config`: its settings; :mod:`~uav_swarm.world.wifi.tables`: MCS thresholds and
  rates (the shipped table in ``uav_swarm/world/data``).
- :mod:`~uav_swarm.world.wifi.phy`: path loss, received power, SINR and rates.
- :mod:`~uav_swarm.world.wifi.airtime`: carrier sense, airtime sharing and collisions.
- :mod:`~uav_swarm.world.wifi.channels`: the channel plan.
- :mod:`~uav_swarm.world.wifi.coverage`: association and coverage of users under this model.
"""
