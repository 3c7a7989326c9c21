"""The separation guard: one rule that keeps every pair of vehicles at least the minimum apart, and its proof.

**The rule** (both models). Vehicles are decided one after the other (their order is their priority). A
vehicle's new command is accepted only if, after it, its *fallback set* (everywhere it can be from now on
if it is given nothing more) keeps the required distance from the fallback set of every other vehicle:
the new set of one decided before it, the current set of one not decided yet (which is where that one
stays if it is given nothing). A refused vehicle is offered other commands (turned round what blocks
it, shorter steps) and otherwise keeps what it has. If every pair of fallback sets is apart when the
vehicles start, it stays so after every decision (each accepted set was checked against every set that
can still be in force), and every vehicle is always inside its fallback set: no pair ever comes closer
than the minimum. Two reachable-set models fill that in:

- **The env** (:mod:`uav_swarm.world.step_guard`, zero delay, exact states): the kinematics are
  :func:`uav_swarm.world.uav.fly_step` and a command acts at once, so the fallback set is the braking
  path (this step, then braking at ``max_accel_m_s2``), exact; :mod:`uav_swarm.world.guard.kernels`
  decides a world in compiled loops.
- **A real autopilot, late and measured with errors** (:class:`FleetGuard`, fed by ``fly``): the
  fallback set is a certified disc (:mod:`uav_swarm.world.guard.holds`), proved below.

**The bounds** (each vehicle's :class:`Bounds`; ``fly`` reads ``a`` and ``j`` from the vehicle and takes the
smaller of those and its ``[guard]`` settings):

(B1) Its autopilot flies a point ``c`` with a stopping controller whose acceleration, braking and
     turning included, is at most ``a``: it wants the speed ``min(v_max, sqrt(2 a d))`` toward ``c``
     (``d`` the distance) and changes its velocity toward that at its limit (ArduCopter's and PX4's
     position controllers, :class:`bridge.simulated.dynamics.PointMassCopter`); a jerk limit ``j``
     takes at most ``2 a / j`` to turn an acceleration of ``a`` away into braking, over which it flies at
     most ``2 |v| a / j + a^3 / j^2`` beyond the braking distance (its run-on; its speed grows by at
     most ``a^2 / 2j`` meanwhile). PX4 limits its acceleration per axis (up to ``sqrt(2)`` times
     ``MPC_ACC_HOR`` on a diagonal), which (B1) does not cover; for it:
(B1x) Its autopilot flies a point ``c`` wanting a velocity toward ``c`` of at most ``sqrt(2 a d)``, and
     changes each horizontal component of its velocity toward the wanted one at a limit ``a`` of its
     own, with the jerk's run-on on each axis (``Bounds.per_axis``; ``fly`` takes it for a vehicle whose
     limits it read from ``MPC_ACC_HOR``).
(B2) The true position is within ``e_t`` of the controller's set point (wind, gusts); a measured
     position within ``e_p`` of the truth, a measured velocity within ``e_v``.
(B3) Commands to a vehicle take effect in the order they are sent: a new point is sent only once the
     previous one is acknowledged or ``command_delay_s`` has passed since it was sent (a command takes
     effect, and its acknowledgement is back, within ``command_delay_s``; one not back may or may not
     have arrived).
(B4) A measurement used was true no earlier than the time given with it.

**Lemma (energy).** Under (B1), for a vehicle flying to ``c``, ``E = |x - c| + |v|^2 / (2 a)`` never grows.
*Proof.* Write ``r`` for the unit vector from ``c`` to ``x``, ``u_r = v . r`` and ``w = -s r`` the wanted
velocity (``s = min(v_max, sqrt(2 a d))``, ``d = |x - c|``). While the velocity equals ``w``, ``|x - c|``
falls at ``s`` and ``|v|^2 / (2 a)`` is constant (at ``v_max``) or equals ``d`` (on ``sqrt(2 a d)``):
``dE/dt`` is ``-s`` or ``-2 s``. Otherwise the acceleration is ``a (w - v) / |w - v|`` and
``dE/dt = u_r + v . (w - v) / |w - v| = u_r - (s u_r + |v|^2) / |w - v|`` with
``|w - v|^2 = s^2 + 2 s u_r + |v|^2``. For ``u_r >= 0`` squaring gives
``u_r^2 |w - v|^2 <= (s u_r + |v|^2)^2``
(term by term, as ``u_r <= |v|``); for ``u_r = -q < 0`` it holds outright when ``s q <= |v|^2`` and, when
``s q > |v|^2``, squaring leaves ``|v|^2 (|v|^2 - q^2) <= 2 s q (|v|^2 - q^2)``, true as ``2 s q > |v|^2``.
So ``dE/dt <= 0``, and the vehicle never gets further than ``E`` from ``c``. (The discrete controller of
:class:`~bridge.simulated.dynamics.PointMassCopter` was checked in 1,500 random states: ``E`` never grew.)
A controller that plans with more acceleration than ``a`` keeps its own, smaller ``E``; one that brakes
more weakly than it plans is outside (B1).

**Lemma (energy on each axis).** Under (B1x), on each axis ``E_i = |x_i - c_i| + v_i^2 / (2 a)`` never
grows. *Proof.* The wanted component points at ``c_i`` with a speed of at most
``sqrt(2 a d) |c_i - x_i| / d <= sqrt(2 a |c_i - x_i|)`` (as ``|c_i - x_i| <= d``). Moving away from
``c_i``, or toward it slower than wanted, the component gains speed toward ``c_i`` at ``a``: ``E_i`` is
constant; faster than wanted, it brakes at ``a`` and ``E_i`` falls at ``2 |v_i|``; holding the wanted
speed, ``d|v_i|/dt`` is at most ``a`` and ``E_i`` does not grow. So the vehicle stays in the box of
half-widths ``E_x``, ``E_y`` around ``c``, within ``hypot(E_x, E_y)`` of it; a measurement bounds each
``E_i`` as above with the run-on on each axis, and the errors, vectors, are added once
(:func:`~uav_swarm.world.guard.reach.axis_energy_radius_m`). That radius is at most ``E``'s but for the
constant run-on, counted on each axis (``sqrt(2) a^3 / j^2``). A chain's steps add on each axis, at most
their lengths to the radius (the triangle inequality), so everything below holds with it.

**The certified disc.** Let the vehicle's chain be the points it may fly to: the last one known in effect
and those sent after it, ``c_0, ..., c_n``. Switching from ``c_i`` to ``c_{i+1}`` raises ``E`` by at most
``|c_i - c_{i+1}|`` (triangle inequality), so, by (B3) and the lemma, whatever arrives when, the vehicle
stays within ``R = max_i (E_i + |c_i - c_{i+1}| + ... + |c_{n-1} - c_n|)`` of ``c_n``, with ``E_i`` its energy
towards ``c_i`` at any instant the chain held. From a measurement, (B2) and (B4) bound ``E_i`` by
``|x_m - c_i| + e_p + e_t + u^2 / (2 a) + 2 u a / j + a^3 / j^2`` (``u = |v_m| + e_v``), and the true
position lies ``e_t`` further: :meth:`Commitment.fresh_radius_m`. Sending a new point ``c`` moves the disc
onto it with radius ``R + |c_n - c|``, which contains the old disc; a hold sends nothing. Hence the
**invariant**: each
vehicle is inside its disc at all times, however late or lost its commands and its positions are, and a
pair whose discs keep ``d`` keeps ``d``. The rule above keeps the discs apart.

**Every state of a flight** (:class:`FleetGuard`). The invariant needs no measurement, so a vehicle that
goes silent or loses its fix keeps its disc (the column over its home is added: its link-loss failsafe
may take it there, climbing first to its own return layer above every cruise layer); a vehicle joins
with the points it may still be flying to in its chain (where its take-off left it, the point it was last
sent before it was taken back), so its disc covers them; a disc of unknown radius refuses every offer near
it; a vehicle under its autopilot's own mode (climbing, RTL, landing) is a disc on its measured position
and the column over its home; only a vehicle known to be on the ground leaves. One lock serialises the
guard's calls.

**Pairs inside** (discs closer than required: homes a few metres apart, a vehicle taken back, a bound
broken) are outside the invariant from the start; the guard lets them only part, by short steps along
which the distance to the other's centre never shrinks, taken only by a vehicle near rest at its point
and not closing on the other. Such a vehicle flies along its step (an autopilot at rest flying to a point
flies the segment to it); the swing off the segment caused by the velocity it still has is bounded in
simulation, not by this proof. Every pair apart keeps the proved rule.

**Failsafe flights and the launch** (:mod:`uav_swarm.world.guard.failsafe`, its own proof). What a vehicle
does on its own is kept apart by construction: a failsafe flight (climb where it is, straight home at its
return layer, descend) keeps the minimum from another whatever their start times when the lower one's way
keeps it from the higher one's columns and the columns from each other; return layers are ordered by
crossing; vehicles climbing together (unsteered) need homes the launch spacing apart,
``min + margin + 2 (e_t + e_p)``, closer homes climb one at a time.

**Liveness** is not part of this proof: the rule says which points may be sent, not that a vehicle ever
gets one. The order of the decisions (the vehicle held longest first), the steps round a blocker (cycles
of holds are found by :mod:`uav_swarm.world.guard.deadlock`) and the parting steps only choose among the
points the rule accepts, so they change nothing above. The certified
set of a moving vehicle is a disc (its braking distance in every direction), which makes
neighbours moving together, crossings and passes beside a hovering vehicle wait
(``benchmarks/flight/guard_liveness.py``). A set shaped along the committed path (a tube) needs a bound on
the swing across the path and on the run past its end. Two steps of it are proved, under (B1) without the
jerk limit (the discrete controller of :class:`~bridge.simulated.dynamics.PointMassCopter` keeps both
exactly, step by step: ``tests/bridge/test_simulated_dynamics.py``):

- *Angular momentum.* For a vehicle flying to ``c``, ``L = (x - c) x v`` keeps its sign and never grows:
  ``dL/dt = (x - c) x acc = -a L / |w - v|``, as the wanted velocity ``w`` has no part across the line to
  ``c``. A vehicle with ``L = 0`` (at rest, or flying straight at ``c``) flies the straight segment to
  ``c``; otherwise its bearing from ``c`` turns one way only.
- *One-sided swing.* On one side of a line through ``c``, ``y + (V + U) / a * max(0, v_y)`` never grows
  (``y`` the distance from the line, ``v_y`` the speed away from it, ``V`` the wanted speed's limit, ``U``
  the larger of ``V`` and the speed at the start): moving away, the acceleration back is at least
  ``a v_y / |w - v|`` and ``|w - v| <= V + U``; moving back, ``y`` falls. A vehicle that starts on the
  line with a speed ``u`` across it swings at most ``(V + U) u / a`` to that side.

Not proved: where a vehicle with ``L != 0`` goes once it passes ``c`` (turned at speed, the simulated
autopilots loop round the point: the run past it exceeds what braking explains by up to 23 m), the lag of a
jerk limit (one jerk-limited turned flight in 200 swung 1.1 m beyond the one-sided bound), and the
per-axis PX4-like model, under (B1x) only (from rest it flies up to 6.3 m off the segment):
``benchmarks/flight/track_swing.py``. Until those are bounded, a moving vehicle's set stays the disc.

**Outside the bounds** nothing is promised; what can be seen is reported and answered
(:class:`FleetGuard`): a position older than ``position_age_s`` (the vehicle is sent nothing new: its
disc needs no measurement), a point not acknowledged within ``command_delay_s`` (kept as possible), a
vehicle measured outside its disc (weaker braking, stronger wind, larger errors: stopped where it is,
its disc widened at half the acceleration, the others kept off it).

Anchors: buffered Voronoi cells (Zhou et al. 2017: each robot stays in a cell shrunk by its safety
radius), ORCA (reciprocal velocity obstacles with stated bounds), Skybrush's show validation (minimum
distance, speed and acceleration checked on every plan); ideas only.

May import: ``typed_config``, ``uav_swarm.world``.
"""

from uav_swarm.world.guard.fleet import Bounds, Decision, FleetGuard
from uav_swarm.world.guard.holds import Commitment

__all__ = ["Bounds", "Commitment", "Decision", "FleetGuard"]
