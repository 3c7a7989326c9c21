"""The runs users start: ``simulate`` (crowd and swarm simulated) and ``fly`` (real or SITL autopilots).

- :mod:`~uav_swarm.runs.simulate`, :mod:`~uav_swarm.runs.simulate_config`: the main loop and its TOML config.
- :mod:`~uav_swarm.runs.fly`, :mod:`~uav_swarm.runs.fly_config`, :mod:`~uav_swarm.runs.flight_loop`:
  closed-loop guided flight through :mod:`bridge.flight.fleet`; the loop's parts:
  :mod:`~uav_swarm.runs.flight_vehicles` (the vehicle table), :mod:`~uav_swarm.runs.flight_step`
  (planning and guard), :mod:`~uav_swarm.runs.flight_launch` (launch and links),
  :mod:`~uav_swarm.runs.flight_end` (the end and the returns).
- :mod:`~uav_swarm.runs.records`: what a run records (the types the plots and the animation draw).
- :mod:`~uav_swarm.runs.plots`, :mod:`~uav_swarm.runs.animation`: QoS figures, CSV and the scene GIF.
- :mod:`~uav_swarm.runs.recording`, :mod:`~uav_swarm.runs.foxglove_scene`, :mod:`~uav_swarm.runs.live_view`:
  ``--record`` and ``--live``, a run in Foxglove's message types through the Foxglove SDK, as an MCAP
  file for replay and/or streamed to the Foxglove app while it runs (the only modules that import the SDK).
- :mod:`~uav_swarm.runs.outputs`: the one object both loops hand each step and plan to (Zenoh telemetry,
  the Foxglove recorder, ROS 2); :mod:`~uav_swarm.runs.summary`: the results summary of both jobs.
- :mod:`~uav_swarm.runs.ros2`: ``--ros2``, the run on ROS 2 topics (the only package that imports rclpy);
  :mod:`~uav_swarm.runs.steering`: the operator targets it takes, validated.
"""
