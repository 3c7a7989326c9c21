"""The pure-numpy world: scenarios, crowd, radio model and rasters (no PettingZoo, torch or drawing).

- Scenes: :mod:`~uav_swarm.world.scenario` (obstacles, routes, groups, random scenes),
  :mod:`~uav_swarm.world.scenario_toml` and :mod:`~uav_swarm.world.pedsim` (files in),
  :mod:`~uav_swarm.world.geometry` (points, segments, rectangles).
- The crowd: :mod:`~uav_swarm.world.crowd` (the social force of one world),
  :mod:`~uav_swarm.world.crowd_batch` (B worlds in one), :mod:`~uav_swarm.world.pair_forces` (the compiled
  pair kernel), :mod:`~uav_swarm.world.walls`, :mod:`~uav_swarm.world.walls_batch`.
- The radio: :mod:`~uav_swarm.world.radio_config` (``[task.radio]``), :mod:`~uav_swarm.world.comms`
  (the paper's model and association), :mod:`~uav_swarm.world.comms_batch` (B worlds),
  :mod:`~uav_swarm.world.coverage` (what a radio tells), :mod:`~uav_swarm.world.admission`, and
  :mod:`uav_swarm.world.wifi` (the 802.11 model).
- The UAVs: :mod:`~uav_swarm.world.uav` (kinematics), :mod:`~uav_swarm.world.separation`,
  :mod:`~uav_swarm.world.step_guard`, and :mod:`uav_swarm.world.guard` (the flight's guard and its proof).
- :mod:`~uav_swarm.world.raster`: metres to density maps and pixels.

May import: ``typed_config``.
"""
