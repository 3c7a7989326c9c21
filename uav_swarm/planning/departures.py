"""Departures and detours of a transition, chosen on flights flown by the env's kinematics (numba).

The search of :func:`uav_swarm.planning.transitions.plan_transition` (its docstring states the rules) in one
compiled call: every flight is a track of :mod:`uav_swarm.planning.trajectory`, every pair is checked at
every step and exactly between steps, and a pair is clear only if its distance never falls under its
required distance ``req`` (less ``TOLERANCE_M``, for the rounding of a UAV that lands on its target).

Each UAV ``j`` has three ways to fly: *direct* (to its target at once), *held* (to its braking point, wait
there, leave at a departure step), *detoured* (to a point beside the first UAV on its path, wait there,
leave). A held or detoured UAV leaves only once at rest on its hold point, so its tail is the same flight
for every departure.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from uav_swarm.planning.trajectory import _fly, segment_gap, track_at

__all__ = ["TOLERANCE_M", "plan_departures"]

TOLERANCE_M = 1e-9
"""Rounding allowed under a required distance (a UAV landing on its target lands within 1e-14 m)."""


@numba.njit(cache=True, nogil=True)
def _end(head_settle: int, depart: int, tail_settle: int) -> int:  # pragma: no cover - compiled
    return head_settle if depart < 0 else depart + tail_settle


@numba.njit(cache=True, nogil=True)
def _box_gap(a: np.ndarray, b: np.ndarray) -> float:  # pragma: no cover - compiled
    """Least distance between two boxes ``(x_min, x_max, y_min, y_max)``."""
    gx = max(a[0] - b[1], b[0] - a[1], 0.0)
    gy = max(a[2] - b[3], b[2] - a[3], 0.0)
    return math.sqrt(gx * gx + gy * gy)


@numba.njit(cache=True, nogil=True)
def _pair_gap(h1: np.ndarray, s1: int, d1: int, t1: np.ndarray, e1: int, h2: np.ndarray, s2: int, d2: int,
              t2: np.ndarray, e2: int, stop_m: float) -> float:  # pragma: no cover - compiled
    """Least distance of two flights (exact between steps); returns early once under ``stop_m``."""
    end = max(_end(s1, d1, e1), _end(s2, d2, e2))
    x1, y1 = track_at(h1, s1, d1, t1, e1, 0)
    x2, y2 = track_at(h2, s2, d2, t2, e2, 0)
    ax, ay = x1 - x2, y1 - y2
    low = math.sqrt(ax * ax + ay * ay)
    for n in range(1, end + 1):
        if low < stop_m:
            return low
        x1, y1 = track_at(h1, s1, d1, t1, e1, n)
        x2, y2 = track_at(h2, s2, d2, t2, e2, n)
        low = min(low, segment_gap(ax, ay, x1 - x2, y1 - y2))
        ax, ay = x1 - x2, y1 - y2
    return low


@numba.njit(cache=True, nogil=True)
def _clear(j: int, head: np.ndarray, hs: int, dep: int, tail: np.ndarray, ts: int, box: np.ndarray,
           placed: np.ndarray, heads: np.ndarray, hss: np.ndarray, deps: np.ndarray, tails: np.ndarray,
           tss: np.ndarray, boxes: np.ndarray, req: np.ndarray) -> bool:  # pragma: no cover - compiled
    """Whether UAV ``j`` flown this way keeps ``req`` from every placed UAV."""
    for o in range(len(placed)):
        if not placed[o] or o == j or req[j, o] <= 0.0 or _box_gap(box, boxes[o]) >= req[j, o]:
            continue
        stop = req[j, o] - TOLERANCE_M
        if _pair_gap(head, hs, dep, tail, ts, heads[o], hss[o], deps[o], tails[o], tss[o], stop) < stop:
            return False
    return True


@numba.njit(cache=True, nogil=True)
def _place(j: int, head: np.ndarray, hs: int, dep: int, tail: np.ndarray, ts: int, box: np.ndarray,
           hold: np.ndarray, heads: np.ndarray, hss: np.ndarray, deps: np.ndarray, tails: np.ndarray,
           tss: np.ndarray, boxes: np.ndarray, holds: np.ndarray) -> None:  # pragma: no cover - compiled
    heads[j, :hs + 1] = head[:hs + 1]
    hss[j], deps[j] = hs, dep
    if dep >= 0:
        tails[j, :ts + 1] = tail[:ts + 1]
    tss[j] = ts
    boxes[j] = box
    holds[j] = hold


@numba.njit(cache=True, nogil=True)
def _union(a: np.ndarray, b: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    return np.array([min(a[0], b[0]), max(a[1], b[1]), min(a[2], b[2]), max(a[3], b[3])])


@numba.njit(cache=True, nogil=True)
def _first_departure(j: int, head: np.ndarray, hs: int, tail: np.ndarray, ts: int, box: np.ndarray,
                     wait_steps: int, placed: np.ndarray, heads: np.ndarray, hss: np.ndarray,
                     deps: np.ndarray, tails: np.ndarray, tss: np.ndarray, boxes: np.ndarray, req: np.ndarray
                     ) -> int:  # pragma: no cover - compiled
    """The first departure step that keeps UAV ``j`` clear; -1: none.

    Tried: at rest on the hold point, then after waits of ``wait_steps``, 6 times, then growing by 40 %,
    at most until every placed UAV has settled.
    """
    done = 0
    for o in range(len(placed)):
        if placed[o] and o != j:
            done = max(done, _end(hss[o], deps[o], tss[o]))
    limit = max(done - hs, 0)
    wait, fine = 0, 0
    while True:
        dep = hs + wait
        if dep >= 1 and _clear(j, head, hs, dep, tail, ts, box, placed, heads, hss, deps, tails, tss, boxes,
                               req):
            return dep
        if wait >= limit:
            return -1
        if fine < 6:
            wait += wait_steps
            fine += 1
        else:
            wait = wait_steps * int(math.ceil(wait * 1.4 / wait_steps))
        wait = min(wait, limit)


@numba.njit(cache=True, nogil=True)
def _detours(j: int, p: np.ndarray, goal: np.ndarray, placed: np.ndarray, deps: np.ndarray,
             holds: np.ndarray, req: np.ndarray, ux: float, uy: float
             ) -> np.ndarray:  # pragma: no cover - compiled
    """``(M, 2)`` hold points beside the first placed UAV on ``j``'s path.

    The obstacles are the placed UAVs' positions (hold points) and targets; the hold points lie 1.25 and 2
    times the distance needed from the first, either side, inside the area.
    """
    sx, sy = p[j, 0], p[j, 1]
    lx, ly = goal[j, 0] - sx, goal[j, 1] - sy
    length = math.sqrt(lx * lx + ly * ly)
    out = np.empty((4, 2))
    if length < 1e-9:
        return out[:0]
    ex, ey = lx / length, ly / length
    first, bx, by, gap = np.inf, 0.0, 0.0, 0.0
    for o in range(len(placed)):
        if not placed[o] or o == j or req[j, o] <= 0.0:
            continue
        for k in range(2):
            if k == 0:
                qx, qy = (holds[o, 0], holds[o, 1]) if deps[o] >= 0 else (p[o, 0], p[o, 1])
            else:
                qx, qy = goal[o, 0], goal[o, 1]
            along = min(max((qx - sx) * ex + (qy - sy) * ey, 0.0), length)
            off = math.hypot(qx - sx - along * ex, qy - sy - along * ey)
            if off < req[j, o] and along < first:
                first, bx, by, gap = along, qx, qy, req[j, o]
    m = 0
    if np.isfinite(first):
        for scale in (1.25, 2.0):
            for side in (1.0, -1.0):
                vx, vy = bx - side * scale * gap * ey, by + side * scale * gap * ex
                if 0.0 <= vx <= ux and 0.0 <= vy <= uy:
                    out[m, 0], out[m, 1] = vx, vy
                    m += 1
    return out[:m]


@numba.njit(cache=True, nogil=True)
def _schedule(order: np.ndarray, placed: np.ndarray, p: np.ndarray, v: np.ndarray, goal: np.ndarray,
              req: np.ndarray, direct: np.ndarray, ds: np.ndarray, dbox: np.ndarray, brake: np.ndarray,
              bs: np.ndarray, bbox: np.ndarray, btail: np.ndarray, bts: np.ndarray, btbox: np.ndarray,
              dt: float, vmax: float, a: float, ux: float, uy: float, wait_steps: int, heads: np.ndarray,
              hss: np.ndarray, deps: np.ndarray, tails: np.ndarray, tss: np.ndarray, boxes: np.ndarray,
              holds: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """Place the UAVs of ``order`` one by one against those placed before; returns the stuck ones."""
    stuck = np.empty(len(order), np.int64)
    n_stuck = 0
    cap = direct.shape[1] - 1
    scratch_h, scratch_t = np.empty((cap + 1, 2)), np.empty((cap + 1, 2))
    box_h, box_t = np.empty(4), np.empty(4)
    for j in order:
        done = False
        if _clear(j, direct[j], ds[j], -1, direct[j], 0, dbox[j], placed, heads, hss, deps, tails, tss, boxes,
                  req):
            _place(j, direct[j], ds[j], -1, direct[j], 0, dbox[j], goal[j], heads, hss, deps, tails, tss,
                   boxes, holds)
            done = True
        if not done:
            box = _union(bbox[j], btbox[j])
            dep = _first_departure(j, brake[j], bs[j], btail[j], bts[j], box, wait_steps, placed, heads, hss,
                                   deps, tails, tss, boxes, req)
            if dep >= 0:
                _place(j, brake[j], bs[j], dep, btail[j], bts[j], box, brake[j, bs[j]], heads, hss, deps,
                       tails, tss, boxes, holds)
                done = True
        if not done:
            vias = _detours(j, p, goal, placed, deps, holds, req, ux, uy)
            for i in range(len(vias)):
                hs = _fly(p[j, 0], p[j, 1], v[j, 0], v[j, 1], vias[i, 0], vias[i, 1], dt, vmax, a, ux, uy,
                          scratch_h, box_h)
                ts = _fly(vias[i, 0], vias[i, 1], 0.0, 0.0, goal[j, 0], goal[j, 1], dt, vmax, a, ux, uy,
                          scratch_t, box_t)
                box = _union(box_h, box_t)
                dep = _first_departure(j, scratch_h, hs, scratch_t, ts, box, wait_steps, placed, heads, hss,
                                       deps, tails, tss, boxes, req)
                if dep >= 0:
                    _place(j, scratch_h, hs, dep, scratch_t, ts, box, vias[i], heads, hss, deps, tails, tss,
                           boxes, holds)
                    done = True
                    break
        if not done:  # no way found: it flies straight, its pairs are reported
            _place(j, direct[j], ds[j], -1, direct[j], 0, dbox[j], goal[j], heads, hss, deps, tails, tss,
                   boxes, holds)
            stuck[n_stuck] = j
            n_stuck += 1
        placed[j] = True
    return stuck[:n_stuck]


@numba.njit(cache=True, nogil=True)
def _gaps(heads: np.ndarray, hss: np.ndarray, deps: np.ndarray, tails: np.ndarray, tss: np.ndarray,
          boxes: np.ndarray, req: np.ndarray, exact_m: float) -> np.ndarray:  # pragma: no cover - compiled
    """``(K, K)`` closest approach of every pair (pairs whose boxes stay apart: their boxes' distance)."""
    k = len(hss)
    out = np.full((k, k), np.inf)
    for i in range(k):
        for j in range(i + 1, k):
            gap = _box_gap(boxes[i], boxes[j])
            if gap < max(exact_m, req[i, j]):
                gap = _pair_gap(heads[i], hss[i], deps[i], tails[i], tss[i], heads[j], hss[j], deps[j],
                                tails[j], tss[j], -1.0)
            out[i, j] = out[j, i] = gap
    return out


@numba.njit(cache=True, nogil=True)
def _blocking(ids: np.ndarray, p: np.ndarray, goal: np.ndarray, direct: np.ndarray, ds: np.ndarray,
              req: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """Per UAV of ``ids``: how many direct flights pass within ``req`` of its position, less of its target."""
    k = len(p)
    out = np.zeros(k, np.int64)
    for j in ids:
        for o in range(k):
            if o == j or req[j, o] <= 0.0:
                continue
            here, there, need2 = False, False, req[j, o] * req[j, o]
            for n in range(ds[o] + 1):
                x, y = direct[o, n, 0], direct[o, n, 1]
                here = here or (x - p[j, 0]) ** 2 + (y - p[j, 1]) ** 2 < need2
                there = there or (x - goal[j, 0]) ** 2 + (y - goal[j, 1]) ** 2 < need2
                if here and there:
                    break
            out[j] += int(here) - int(there)
    return out


@numba.njit(cache=True, nogil=True)
def plan_departures(p: np.ndarray, v: np.ndarray, goal: np.ndarray, req: np.ndarray, dt: float, vmax: float,
                    a: float, ux: float, uy: float, cap: int, wait_steps: int
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """``(holds (K, 2), departure steps (K,) (-1: direct), gaps (K, K), tracks (K, T + 1, 2))``.

    UAVs whose direct flights keep ``req`` from every other direct flight leave at once (pairs that start
    or end closer than ``req`` are left to the report: no choice helps them); the others are placed in
    order (those sitting on others' paths first, those whose targets lie on them last), then once more
    with the stuck ones first; the pass with fewer stuck UAVs (then the lesser sum of departures) is kept.
    """
    k = len(p)
    direct, brake, btail = np.empty((k, cap + 1, 2)), np.empty((k, cap + 1, 2)), np.empty((k, cap + 1, 2))
    ds, bs, bts = np.empty(k, np.int64), np.empty(k, np.int64), np.empty(k, np.int64)
    dbox, bbox, btbox = np.empty((k, 4)), np.empty((k, 4)), np.empty((k, 4))
    for j in range(k):
        ds[j] = _fly(p[j, 0], p[j, 1], v[j, 0], v[j, 1], goal[j, 0], goal[j, 1], dt, vmax, a, ux, uy,
                     direct[j], dbox[j])
    deps = np.full(k, -1, np.int64)
    gaps = _gaps(direct, ds, deps, direct, np.zeros(k, np.int64), dbox, req, 0.0)
    conflicted = np.zeros(k, np.bool_)
    search = req.copy()  # pairs that start or end under their distance: no choice helps, none is searched
    for i in range(k):
        for j in range(k):
            start = math.hypot(p[i, 0] - p[j, 0], p[i, 1] - p[j, 1])
            end = math.hypot(goal[i, 0] - goal[j, 0], goal[i, 1] - goal[j, 1])
            if i != j and min(start, end) < req[i, j] - TOLERANCE_M:
                search[i, j] = 0.0
            elif gaps[i, j] < req[i, j] - TOLERANCE_M:
                conflicted[i] = True
    holds = goal.copy()
    if not conflicted.any():
        return holds, deps, gaps, _tracks(direct, ds, deps, direct, np.zeros(k, np.int64))
    for j in range(k):
        speed = math.hypot(v[j, 0], v[j, 1])  # the braking point: where braking at the limit stops it
        stop = min(speed, vmax) * speed / (2.0 * a)
        bx, by = p[j, 0], p[j, 1]
        if speed > 0.0:
            bx = min(max(bx + v[j, 0] / speed * stop, 0.0), ux)
            by = min(max(by + v[j, 1] / speed * stop, 0.0), uy)
        bs[j] = _fly(p[j, 0], p[j, 1], v[j, 0], v[j, 1], bx, by, dt, vmax, a, ux, uy, brake[j], bbox[j])
        bts[j] = _fly(bx, by, 0.0, 0.0, goal[j, 0], goal[j, 1], dt, vmax, a, ux, uy, btail[j], btbox[j])
    ids = np.flatnonzero(conflicted)
    blocking = _blocking(ids, p, goal, direct, ds, search)
    order = ids[np.argsort(-blocking[ids], kind="mergesort")]
    best_stuck, best_sum = k + 1, 0
    best = (holds, deps, direct, ds, direct, ds, dbox)
    for _ in range(2):
        heads, tails = np.empty((k, cap + 1, 2)), np.empty((k, cap + 1, 2))
        hss, tss, dps = ds.copy(), np.zeros(k, np.int64), np.full(k, -1, np.int64)
        boxes, hld = dbox.copy(), goal.copy()
        for j in range(k):
            if not conflicted[j]:
                heads[j, :ds[j] + 1] = direct[j, :ds[j] + 1]
        stuck = _schedule(order, ~conflicted, p, v, goal, search, direct, ds, dbox, brake, bs, bbox, btail,
                          bts, btbox, dt, vmax, a, ux, uy, wait_steps, heads, hss, dps, tails, tss, boxes,
                          hld)
        total = int(np.maximum(dps, 0).sum())
        if len(stuck) < best_stuck or (len(stuck) == best_stuck and total < best_sum):
            best_stuck, best_sum = len(stuck), total
            best = (hld, dps, heads, hss, tails, tss, boxes)
        if len(stuck) == 0:
            break
        first = np.zeros(k, np.bool_)
        first[stuck] = True
        order = np.concatenate((stuck, order[~first[order]]))
    hld, dps, heads, hss, tails, tss, boxes = best
    gaps = _gaps(heads, hss, dps, tails, tss, boxes, req, 0.0)
    return hld, dps, gaps, _tracks(heads, hss, dps, tails, tss)


@numba.njit(cache=True, nogil=True)
def _tracks(heads: np.ndarray, hss: np.ndarray, deps: np.ndarray, tails: np.ndarray, tss: np.ndarray
            ) -> np.ndarray:  # pragma: no cover - compiled
    """``(K, T + 1, 2)`` every UAV's positions until the last one settles."""
    k = len(hss)
    end = 0
    for j in range(k):
        end = max(end, _end(hss[j], deps[j], tss[j]))
    out = np.empty((k, end + 1, 2))
    for j in range(k):
        for n in range(end + 1):
            out[j, n, 0], out[j, n, 1] = track_at(heads[j], hss[j], deps[j], tails[j], tss[j], n)
    return out
