"""The guard's decision: which vehicle gets which next point, so that every certified disc keeps the minimum.

:func:`choose_points` decides one vehicle after the other (their order is their priority). A vehicle
that may be sent a point (:meth:`~uav_swarm.world.guard.holds.Commitment.may_send`) and has a goal
elsewhere is offered points on the way from its current point to its goal, the whole way first, then
shorter steps; a vehicle held for ``detour_after_s`` is also offered steps turned away from that way
(it goes round what blocks it). The first point whose certified disc (centre the point, radius
``radius + step``) keeps the required distance to the disc of every other vehicle is chosen: to the
new disc of a vehicle decided before it, to the current disc of one not decided yet (which it keeps
if it is sent nothing: that is its hold). A pair already closer than that (homes closer than the
guard can certify, a vehicle taken back, a bound broken) may only part: against such a pair
(``parting``) a short step passes when every point of it is at least as far from the other's centre as
the vehicle is (its distance grows along the whole step: the vehicle, at rest, flies along it), whatever
it does to the discs; no other step passes. Where no step towards its goal passes, or first where the
discs overlap, such a vehicle **yields**: it is offered a step straight away from each vehicle it is
inside with (a vehicle hovering makes room for one that came too close: taken back in flight, outside
its bounds). A disc of unknown radius (a vehicle never
measured) refuses every offer.
No point passes: the vehicle is **held**: it is sent nothing and keeps flying to the point it has,
inside its disc. No point is set further than ``max_step_m`` from the disc's centre, nor from where the
vehicle was last measured.

Examples:
    >>> centres = np.array([[0.0, 0.0], [20.0, 0.0]])
    >>> points, radii, blockers = choose_points(centres, np.zeros(2), np.array([[40.0, 0.0], [20.0, 0.0]]),
    ...                                         np.ones(2, bool), np.full((2, 2), 5.0), np.zeros(2, bool))
    >>> points[0].tolist(), float(radii[0]), int(blockers[0])  # 4 m on: its disc reaches 12 m from the other
    ([4.0, 0.0], 4.0, 1)
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["choose_points", "finite_point", "STEPS_M"]

STEPS_M = (64.0, 32.0, 16.0, 8.0, 4.0, 2.0, 1.0, 0.5)
"""The steps offered on the way to a goal, metres (each half the one before); the whole way first when
shorter than the first: a vehicle is never committed further ahead, so a new goal can turn it soon."""
_DETOURS_RAD = (math.pi / 4, -math.pi / 4, math.pi / 2, -math.pi / 2, 3 * math.pi / 4, -3 * math.pi / 4)
_COS, _SIN = np.cos(_DETOURS_RAD), np.sin(_DETOURS_RAD)
_ARRIVED_M = 1e-3


def finite_point(point_m: np.ndarray) -> bool:
    """Whether both coordinates of a (2,) point are finite (NaN: none; cheaper than numpy on two numbers)."""
    return math.isfinite(point_m[0]) and math.isfinite(point_m[1])


def _offers(centre: np.ndarray, goal: np.ndarray, detour: bool, detour_m: float,
            area_m: np.ndarray | None = None, max_step_m: float = STEPS_M[0]) -> np.ndarray:
    """(M, 2) points offered to one vehicle, best first (module docstring)."""
    way = goal - centre
    length = float(np.hypot(*way))
    if length <= _ARRIVED_M:
        return np.zeros((0, 2))
    unit = way / length
    steps = [length] if length <= max_step_m else []
    steps += [s for s in STEPS_M if s < length and s <= max_step_m]
    offers = centre + unit * np.array(steps)[:, None]  # (S, 2)
    if not detour:
        return offers
    turned = np.stack([_COS * unit[0] - _SIN * unit[1], _SIN * unit[0] + _COS * unit[1]], axis=1)  # (T, 2)
    turns = (centre + turned[:, None] * np.array([detour_m, detour_m / 2, detour_m / 4])[None, :, None])
    turns = turns.reshape(-1, 2)  # each turn's three lengths, turn after turn
    if area_m is not None:
        turns = turns[np.all((turns >= 0.0) & (turns <= area_m), axis=1)]
    return np.vstack([offers, turns])


def choose_points(centres_m: np.ndarray, radii_m: np.ndarray, goals_m: np.ndarray, may_send: np.ndarray,
                  required_m: np.ndarray, detour: np.ndarray, detour_m: float = 5.0,
                  area_m: np.ndarray | None = None, *, order: np.ndarray | None = None,
                  max_step_m: float = STEPS_M[0], parting: np.ndarray | None = None,
                  parting_step_m: float = 4.0, positions_m: np.ndarray | None = None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each vehicle's next point, in priority order (module docstring).

    Args:
        centres_m: (K, 2) each certified disc's centre (the newest point sent).
        radii_m: (K,) their radii (``inf``: unknown, a vehicle never measured).
        goals_m: (K, 2) where each wants to go (NaN: nowhere; it keeps its point).
        may_send: (K,) whether a new point may be sent to it now.
        required_m: (K, K) distance each pair's discs must keep (the minimum, per altitude layers,
            plus the margin).
        detour: (K,) whether it may also be offered steps turned away from its way.
        detour_m: Length of the longest turned step, metres.
        area_m: (2,) the area's upper corner: turned steps stay in ``[0, area_m]`` (None: anywhere).
        order: (K,) the order in which they are decided, first the highest priority (None: by index).
        max_step_m: The farthest a new point is set from the disc's centre, metres.
        parting: (K, K) the pairs inside (closer than required) that may part: the first at rest toward
            the second (None: none). Against such a pair a step of at most ``parting_step_m`` passes when
            no point of it is nearer the other's centre than the vehicle's centre is (module docstring).
        parting_step_m: The longest such step, metres.
        positions_m: (K, 2) where each vehicle was last measured (NaN: unknown): no point is set more than
            ``max_step_m`` from it (a vehicle never runs after a point far ahead of it).

    Returns:
        ``points`` (K, 2) the point to send (NaN: none), ``radii`` (K,) the certified radii after, and
        ``blockers`` (K,) the vehicle whose disc refused its first offer (-1: none).
    """
    centres = np.array(centres_m, dtype=np.float64)
    radii = np.array(radii_m, dtype=np.float64)
    k = centres.shape[0]
    points = np.full((k, 2), np.nan)
    blockers = np.full(k, -1)
    if k == 0:
        return points, radii, blockers
    threshold = np.asarray(required_m, dtype=np.float64) - 1e-9  # an unknown disc (inf) refuses every offer
    others = ~np.eye(k, dtype=bool)
    for i in (range(k) if order is None else (int(j) for j in order)):
        goal = goals_m[i]
        if not may_send[i] or not math.isfinite(radii[i]):
            continue
        offers = _offers(centres[i], goal, bool(detour[i]), detour_m, area_m, max_step_m) \
            if finite_point(goal) else np.zeros((0, 2))
        if positions_m is not None and finite_point(positions_m[i]):
            offers = offers[np.hypot(*(offers - positions_m[i]).T) <= max_step_m + 1e-9]
        if parting is not None and parting[i].any():  # then yield: straight away from each one inside
            base = positions_m[i] if positions_m is not None and finite_point(positions_m[i]) \
                else centres[i]
            away = base - centres[parting[i]]
            away = away / np.maximum(np.hypot(*away.T), 1e-9)[:, None] * min(parting_step_m, max_step_m)
            overlap = np.hypot(*(centres[i] - centres[parting[i]]).T) < radii[i] + radii[parting[i]]
            first = overlap.any()  # a disc overlapping its own: making room comes before its goal
            offers = np.vstack([base + away, offers] if first else [offers, base + away])
        if offers.shape[0] == 0:
            continue
        grown = radii[i] + np.hypot(*(offers - centres[i]).T)  # (M,)
        apart = np.hypot(*(offers[:, None] - centres[None]).transpose(2, 0, 1)) - grown[:, None] - radii[None]
        ok = (apart >= threshold[i][None]) | ~others[i][None]  # (M, K)
        if parting is not None and parting[i].any():
            base = positions_m[i] if positions_m is not None and finite_point(positions_m[i]) \
                else centres[i]  # it flies from where it is to the offer
            step = offers - base  # (M, 2): parting when every point of it is farther from the other
            away = step @ (base - centres).T >= 0.0  # (M, K): the distance grows along the whole step
            short = np.hypot(*step.T) <= parting_step_m + 1e-9
            ok = np.where(parting[i][None], away & short[:, None], ok)
        fine = ok.all(axis=1)
        if not fine[0]:
            blockers[i] = int(np.argmin(np.where(others[i], apart[0] - threshold[i], np.inf)))
        if fine.any():
            m = int(np.argmax(fine))
            points[i], radii[i], centres[i] = offers[m], grown[m], offers[m]
    return points, radii, blockers
