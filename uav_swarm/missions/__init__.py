"""Missions implemented as :class:`learning.task.Task`: Wi-Fi strategies and building monitoring."""
