"""The separation guard flown against simulated autopilots in simulated time, judged on true positions.

:func:`fly_trial` flies one :class:`Trial`: K simulated vehicles (``autopilot``: the point mass
:class:`bridge.simulated.dynamics.PointMassCopter`, or the jerk-limited
:class:`~bridge.simulated.jerk_limited.ArduCopterLikeCopter` and
:class:`~bridge.simulated.jerk_limited.PX4LikeCopter`;
their own speed, acceleration and jerk, command latency and loss, late and noisy positions, wind),
started at rest and apart, each given a new goal every 1-10 s (kept apart from the others' goals); a
:class:`uav_swarm.world.guard.FleetGuard` decides 10 times a second on the vehicles' *reports* and its
points reach them ``command_latency_s`` later (an acknowledgement comes back with the command's effect;
a lost one is never acknowledged). The guard is told the limits the vehicles report: the acceleration
(PX4 applies it on each axis) and the jerk (``PSC_JERK_XY``, ``MPC_JERK_AUTO``; none for the point mass).

**Events** a trial may add (the named cases and random flights with ``events=True``):

- *silent*: a vehicle's link is down both ways for a while (no reports, its commands and their
  acknowledgements lost) while it flies on to the last point it got;
- *no fix*: its reports carry no position for a while (the guard is given nothing); commands still arrive;
- *join in flight*: a vehicle flies to a point sent outside the guard and is taken under the guard
  (``join`` at its measured position, with the point it flies to) while still flying there;
- *stale first rows*: a vehicle's reports are older than the guard's ``position_age_s`` for its first seconds;
- *reversal*: when a vehicle first reaches a speed, its goal moves behind it (it is still accelerating away).

**The judge** is independent of the guard: every 0.05 s, the **true** positions of the vehicles under
the guard, their pair distances by ``scipy.spatial.distance.pdist`` (the closest pair, and the pairs
that came under the minimum, once both are under the guard and have been seen the minimum apart: a
vehicle joined in flight closer than that is the guard's to separate, not its failure), and each
vehicle's true position against the set the guard certifies for it (``centre_m``, ``radius_m``): a
vehicle found outside it is counted, whatever the guard reported.

**Liveness**: the share of *separable* goals reached (the vehicle's true position within ``reach_m`` of
it while it was its goal). A goal is separable when it stays at least the minimum, plus both vehicles'
hover tolerances (``reach_m`` and the wind's tracking error), plus 1 m from every other vehicle's goal
while it is held, and it is held at least twice as long as the same vehicle, unguarded, needs to
reach it (a copy of it, at that moment, sent the goal straight), plus 2 s. A guard that holds everyone
fails it. A goal is reached *in time* when it is reached within ``within_factor`` (1.5) times what that
unguarded copy needed. **Formation moves** (:mod:`~uav_swarm.runs.flight.guard_trial.formation`) send a
whole fleet at once (a grid translated, a circle expanded, a launch line spread); such a goal set is
separable when the same vehicles flown unguarded keep the minimum plus both hover tolerances plus 1 m.

The guard is used through four calls only (``join``, ``measure``, ``decide``; ``sent`` points come back
by ``acknowledged`` / ``unacknowledged``) and judged through ``centre_m`` / ``radius_m``; the few
lines that touch it are :func:`_join`, :func:`_measure` and :func:`_outside_m`.

Examples:
    >>> result = fly_trial(Trial(n_uavs=2, area_m=(60.0, 60.0), seed=0, duration_s=20.0))
    >>> result.closest_m >= 5.0, result.breaches, result.outside
    (True, 0, 0)

May import: ``bridge``, ``uav_swarm.world``.
"""

from uav_swarm.runs.flight.guard_trial.cases import (
           EVENT_TRIALS,
           NAMED_TRIALS,
           WORST_BOUNDS,
           event_of,
           random_trial,
)
from uav_swarm.runs.flight.guard_trial.flight import fly_trial
from uav_swarm.runs.flight.guard_trial.formation import FORMATIONS, formation_trial, separable
from uav_swarm.runs.flight.guard_trial.trial import AUTOPILOTS, EVENTS, Trial, TrialResult

__all__ = ["AUTOPILOTS", "EVENTS", "EVENT_TRIALS", "FORMATIONS", "NAMED_TRIALS", "Trial", "TrialResult",
           "WORST_BOUNDS", "event_of", "fly_trial", "formation_trial", "random_trial", "separable"]
