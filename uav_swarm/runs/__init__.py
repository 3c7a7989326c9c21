"""The runs users start: ``simulate`` (crowd and swarm simulated) and ``fly`` (real or SITL autopilots).

- :mod:`~uav_swarm.runs.simulate`, :mod:`~uav_swarm.runs.simulate_config`: the main loop and its TOML config;
  :mod:`~uav_swarm.runs.separation_watch`: its transitions checked for separation.
- :mod:`~uav_swarm.runs.fly`, :mod:`~uav_swarm.runs.fly_config`: closed-loop guided flight; the loop itself
  lives in :mod:`uav_swarm.runs.flight`.
- :mod:`~uav_swarm.runs.radio_altitude`: the radio and altitude settings both configs share;
  :mod:`~uav_swarm.runs.service`: QoS served against the static reference;
  :mod:`~uav_swarm.runs.summary`: the results summary of both jobs;
  :mod:`~uav_swarm.runs.steering`: the operator targets a run takes, validated.
- :mod:`uav_swarm.runs.flight`: the live flight of ``fly`` (vehicles, launch, step, guard, safety, end).
- :mod:`uav_swarm.runs.outputs`: what a run fans out to (records, plots, animation, Foxglove, ROS 2).

May import: ``typed_config``, ``learning``, ``bridge``, ``uav_swarm.world``, ``uav_swarm.missions``,
``uav_swarm.env``, ``uav_swarm.planning``.
"""
