"""The live flight of ``fly``: the loop around the separation guard, vehicle by vehicle.

- :mod:`~uav_swarm.runs.flight.loop`: the loop (:class:`~uav_swarm.runs.flight.loop.Flight`) that ties the
  parts together.
- :mod:`~uav_swarm.runs.flight.vehicles`: the vehicle table (state, target, outcome).
- :mod:`~uav_swarm.runs.flight.launch_plan`, :mod:`~uav_swarm.runs.flight.launch`: how and when vehicles
  take off, and the links they keep.
- :mod:`~uav_swarm.runs.flight.step`: one planning and guard step; :mod:`~uav_swarm.runs.flight.guard`: the
  adapter between measured vehicles and :mod:`uav_swarm.world.guard`.
- :mod:`~uav_swarm.runs.flight.safety`: pre-flight checks and failsafes;
  :mod:`~uav_swarm.runs.flight.end`: the returns and the end.
- :mod:`~uav_swarm.runs.flight.status`, :mod:`~uav_swarm.runs.flight.holds`: the status lines and the holds
  record.
- :mod:`~uav_swarm.runs.flight.guard_trial` (a package): the guard flown by simulated autopilots in simulated
  time (the fuzz's and the tests' harness).

May import: ``typed_config``, ``bridge``, ``uav_swarm.world``, ``uav_swarm.planning``,
``uav_swarm.runs.outputs``, ``uav_swarm.runs.fly_config``, ``uav_swarm.runs.steering``.
"""
