"""Missions: ENU waypoints to MAVLink items, the mission protocol (upload, download, clear), files, compare.

A mission is data (:class:`~bridge.missions.items.Mission`) that round-trips through the vehicle and
through ``.plan`` / ``.waypoints`` files; the autopilot's item-0 convention is applied when it is built.

May import: ``typed_config``, ``bridge``.
"""
