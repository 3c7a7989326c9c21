"""Learning sensor placement from demonstration: a generic, task-agnostic library.

Nothing here knows about crowds or drones; missions plug in through :mod:`learning.task`.

May import: ``typed_config``.
"""
