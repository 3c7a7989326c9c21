"""The 802.11 radio model (the product's default radio), batch-first and pure numpy.

- :mod:`~uav_swarm.world.wifi.config`: its settings; :mod:`~uav_swarm.world.wifi.tables`: MCS thresholds and
  rates (the shipped table in ``uav_swarm/world/data``).
- :mod:`~uav_swarm.world.wifi.phy`: path loss, received power, SINR and rates.
- :mod:`~uav_swarm.world.wifi.airtime`: carrier sense, airtime sharing and collisions.
- :mod:`~uav_swarm.world.wifi.channels`: the channel plan.
- :mod:`~uav_swarm.world.wifi.stations`: which AP each user joins (incumbents, then the others).
- :mod:`~uav_swarm.world.wifi.coverage`: association and coverage of users under this model.

May import: ``typed_config``, ``uav_swarm.world``.
"""
