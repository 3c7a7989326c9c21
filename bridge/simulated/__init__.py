"""Simulated vehicles: multicopters flown in simulated time, and MAVLink autopilots built on them.

:mod:`bridge.simulated.dynamics` is the kinematic core: a point mass flown as an autopilot flies it
(speed and acceleration limits, a stopping controller) with bounded imperfections (command latency and
loss, late and noisy positions, wind), pure and deterministic in simulated time.
"""
