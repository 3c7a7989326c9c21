"""Bridge to real and simulated aircraft: MAVLink missions and Zenoh telemetry.

Nothing here knows about crowds or learning: inputs are waypoints in local
East-North-Up metres around a geodetic home, and per-vehicle endpoints.

May import: ``typed_config``.
"""
