"""Simulated vehicles: multicopters flown in simulated time, and the MAVLink autopilots built on them.

:mod:`bridge.simulated.dynamics` is the kinematic core: a point mass flown as an autopilot flies it
(speed and acceleration limits, a stopping controller) with bounded imperfections (command latency and
loss, late and noisy positions, wind), pure and deterministic in simulated time;
:mod:`bridge.simulated.jerk_limited` flies the same interface with ArduCopter's and PX4's jerk-limited
position controllers (their acceleration and jerk limits; PX4's on each axis).
:mod:`bridge.simulated.peer` is a vehicle's MAVLink side (link, parameters, mission server);
:mod:`bridge.simulated.ardupilot` and :mod:`bridge.simulated.px4` answer as ArduCopter and PX4 do and fly
on the core in real time; :mod:`bridge.simulated.fleet` starts a fleet of them on a bridge config's
loopback endpoints, each on its own home along a launch line (``uav-swarm vehicles``, ``fly --simulated``).

May import: ``typed_config``, ``bridge``.
"""
