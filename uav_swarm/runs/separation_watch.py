"""A simulated run's separation: the transition between plans it flies, and how close the UAVs came.

:class:`SeparationWatch` is what ``simulate`` calls at each replan and step:

- :meth:`~SeparationWatch.replan`: the transition to the new targets
  (:func:`uav_swarm.planning.transitions.plan_transition`): which UAVs hold, and until when;
- :meth:`~SeparationWatch.commands`: the waypoints to fly now (a held UAV's hold point, else its target);
- :meth:`~SeparationWatch.observe`: the UAVs' positions after the step, into a
  :class:`uav_swarm.world.separation.SeparationMonitor` (closest pair, conflicts, time below the minimum),
  with the env's step guard's holds when its ``infos`` carry ``separation_held``;
- :meth:`~SeparationWatch.summary`: the ``separation`` table of ``summary.json``.

Holds count UAV commands held back: each UAV a transition makes wait (once per replan), and each step
the env's guard turned or braked a UAV.

Examples:
    >>> from uav_swarm.world.uav import UAVConfig
    >>> watch = SeparationWatch(UAVConfig(min_separation_m=5.0), n_uavs=2)
    >>> watch.replan(0.0, np.array([[20.0, 50.0], [50.0, 20.0]]), np.zeros((2, 2)),
    ...              np.array([[80.0, 50.0], [50.0, 80.0]]))
    >>> watch.commands(0.0).tolist()  # UAV 1 holds where it is while UAV 0 crosses its path
    [[80.0, 50.0], [50.0, 20.0]]
    >>> nearest, held = watch.observe(0.1, np.array([[20.5, 50.0], [50.0, 20.0]]), {})
    >>> nearest.round(1).tolist(), held.tolist(), watch.summary()["holds"]
    ([42.1, 42.1], [False, True], 1)
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from uav_swarm.planning.transitions import Transition, plan_transition, warm_up
from uav_swarm.world.separation import SeparationMonitor, pair_distances_m
from uav_swarm.world.uav import UAVConfig

__all__ = ["SeparationWatch"]

GUARD_HELD_KEY = "separation_held"
"""The key of a UAV's ``infos`` entry in which the env's step guard says it held that UAV's command."""


class SeparationWatch:
    """Transitions and the separation record of one run (module docstring).

    Args:
        config: The UAVs' limits, ``min_separation_m`` and ``layer_step_m``.
        n_uavs: Number of UAVs.
        area_m: ``(width, height)`` of the area: detours stay inside it (None: no border).
        keep_tracks: Keep every observed position (:attr:`tracks_m`), for a check after the run.
        step_s: The env's step: transitions are planned on flights flown with it.
    """

    def __init__(self, config: UAVConfig, n_uavs: int, area_m: tuple[float, float] | None = None,
                 keep_tracks: bool = True, step_s: float = 0.1) -> None:
        self.config = config
        self.step_s = float(step_s)
        self._area_m = None if area_m is None else np.asarray(area_m, dtype=np.float64)
        self.altitudes_m = config.altitudes_m(n_uavs)
        """``(K,)`` each UAV's flight altitude (one value unless ``layer_step_m`` > 0)."""
        self._layers = self.altitudes_m if config.layer_step_m > 0 else None
        self.monitor = SeparationMonitor(config.min_separation_m, self._layers)
        self._transition: Transition | None = None
        self._replan_s = 0.0
        self.transition_holds = 0
        self.guard_holds = 0
        self.unresolved = 0
        """Pairs a transition left predicted under their required distance (the step guard's to hold)."""
        self._keep = keep_tracks
        warm_up()  # the transition's compiled kernels, loaded now rather than at the first replan
        self._tracks: list[np.ndarray] = []
        self.times_s: list[float] = []

    def replan(self, time_s: float, positions_m: np.ndarray, velocities_m_s: np.ndarray,
               targets_m: np.ndarray) -> None:
        """Plan the transition from the UAVs' state at ``time_s`` to the new ``targets_m``."""
        self._transition = plan_transition(positions_m, velocities_m_s, targets_m, self.config, self._layers,
                                           step_s=self.step_s, area_m=self._area_m)
        self._replan_s = float(time_s)
        self.transition_holds += int(np.count_nonzero(self._transition.held))
        self.unresolved += len(self._transition.unresolved)

    def commands(self, time_s: float) -> np.ndarray:
        """``(K, 2)`` the waypoints to fly at ``time_s``: a held UAV's hold point, else its target."""
        if self._transition is None:
            raise RuntimeError("SeparationWatch.commands before the first replan")
        return self._transition.targets_at(float(time_s) - self._replan_s)

    def observe(self, time_s: float, positions_m: np.ndarray, infos: Mapping[str, Mapping[str, Any]]
                ) -> tuple[np.ndarray, np.ndarray]:
        """Record the positions after a step; ``(nearest_m (K,), held (K,))`` of each UAV.

        Args:
            time_s: Run time of the positions.
            positions_m: ``(K, 2)`` the UAVs' positions.
            infos: The env's per-agent infos of the step (in agent order); the guard's holds are read
                from their ``separation_held`` entries where present.

        Returns:
            Each UAV's distance to its nearest other UAV (3-D with layers; ``inf`` alone), and whether it
            is held now (waiting for its departure, or held by the env's guard this step).
        """
        p = np.array(positions_m, dtype=np.float64)
        self.monitor.observe(time_s, p)
        if self._keep:
            self._tracks.append(p)
            self.times_s.append(float(time_s))
        nearest = pair_distances_m(p, self._layers).min(axis=1) if len(p) > 1 else np.full(len(p), np.inf)
        guard = np.array([bool(info.get(GUARD_HELD_KEY, False)) for info in infos.values()], dtype=bool)
        if guard.size == len(p):
            self.guard_holds += int(np.count_nonzero(guard))
        else:
            guard = np.zeros(len(p), dtype=bool)
        waiting = (np.zeros(len(p), dtype=bool) if self._transition is None
                   else float(time_s) - self._replan_s <= self._transition.delays_s)
        return nearest, guard | waiting

    @property
    def tracks_m(self) -> np.ndarray:
        """``(T, K, 2)`` every observed position (empty without ``keep_tracks``)."""
        return np.array(self._tracks).reshape(-1, len(self.altitudes_m), 2)

    def summary(self) -> dict[str, Any]:
        """``summary.json``'s ``separation`` table.

        The monitor's figures (:meth:`uav_swarm.world.separation.SeparationMonitor.summary`: the closest
        pair, when, conflicts, time below the minimum), ``holds`` (transition and guard holds together, and
        apart), ``unresolved_transition_pairs`` and ``layer_step_m``.
        """
        figures = self.monitor.summary()
        figures["holds"] = self.transition_holds + self.guard_holds
        figures.update(transition_holds=self.transition_holds, guard_holds=self.guard_holds,
                       unresolved_transition_pairs=self.unresolved, layer_step_m=self.config.layer_step_m)
        return figures
