"""Planning in motion's two compiled kernels against the numpy code they replace, on the same inputs.

- **Parking** (:func:`uav_swarm.planning.parking.parking_spot`): a strategy-2 spare's nearest free point
  on 5 m rings, against the reference that queried a k-d tree (``scipy.spatial.cKDTree``) ring by ring.
- **Association** (:func:`uav_swarm.missions.wifi.rules.assign_users`): each user's nearest UAV within the
  radius, with the counts the rules read, against the ``(N, K)`` broadcast with ``argmin`` and ``bincount``.

Inputs are seeded random crowds in the 200 m area (1-600 users around a centre, 1-10 UAVs, radii of the
paper's radio and of the 802.11 radio's reach); each case's two answers must be equal (the run stops
otherwise); the calls alternate so that the machine's load hits both alike. Medians per call, the ratio,
and the load average before and after.

Usage: python benchmarks/learning/motion_kernels.py [--cases 400] [--seed 0]
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np
from scipy.spatial import cKDTree

from uav_swarm.missions.wifi.rules import assign_users, squared_distances
from uav_swarm.planning.parking import RING_STEP_M, parking_spot
from uav_swarm.planning.parking import warm_up as parking_warm_up

AREA_M = np.array([200.0, 200.0])


def parking_reference(users: np.ndarray, start: np.ndarray, others: np.ndarray, reach_m: float,
                      gap_m: float) -> np.ndarray:
    """The ring search as numpy and a k-d tree ran it: one ball query per ring."""
    tree = cKDTree(users)
    for radius in np.arange(0.0, float(np.hypot(*AREA_M)), RING_STEP_M):
        count = max(1, int(np.ceil(2.0 * np.pi * radius / RING_STEP_M)))
        angles = np.linspace(0.0, 2.0 * np.pi, count, endpoint=False)
        ring = np.clip(start + radius * np.stack([np.cos(angles), np.sin(angles)], axis=1), 0.0, AREA_M)
        free = tree.query_ball_point(ring, reach_m, return_length=True) == 0
        if len(others):
            free &= np.linalg.norm(ring[:, None] - others[None], axis=-1).min(axis=1) >= gap_m
        if np.any(free):
            return ring[int(np.argmax(free))]
    return start


def association_reference(users: np.ndarray, uavs: np.ndarray, radius_m: float) -> tuple[np.ndarray, ...]:
    """The association as the ``(N, K)`` broadcast computed it."""
    d2 = squared_distances(users, uavs)
    nearest = np.argmin(d2, axis=1)
    best = d2[np.arange(len(users)), nearest]
    association = np.where(best <= radius_m * radius_m, nearest, -1)
    counts = np.bincount(association[association >= 0], minlength=len(uavs))
    covering = np.count_nonzero(d2 <= radius_m * radius_m, axis=1)
    return association, best, counts, covering, np.bincount(association[covering == 1], minlength=len(uavs))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=400)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    load = ", ".join(f"{v:.2f}" for v in os.getloadavg())
    print(f"python {platform.python_version()}, {platform.machine()}, {os.cpu_count()} CPUs; "
          f"load average {load}")
    parking_warm_up()
    assign_users(np.zeros((1, 2)), np.zeros((1, 2)), 1.0)
    rng = np.random.default_rng(args.seed)
    times: dict[str, list[float]] = {"parking reference": [], "parking": [], "association reference": [],
                                     "association": []}
    for case in range(args.cases):
        users = rng.normal(rng.uniform(0.0, 200.0, 2), rng.uniform(5.0, 60.0), (int(rng.integers(1, 600)), 2))
        uavs = rng.uniform(0.0, 200.0, (int(rng.integers(1, 11)), 2))
        start, reach_m = rng.uniform(0.0, 200.0, 2), float(rng.choice([35.0, 60.0, 95.0]))
        t0 = time.perf_counter()
        slow = parking_reference(users, start, uavs, reach_m, 5.0)
        t1 = time.perf_counter()
        fast = parking_spot(users, start, uavs, AREA_M, reach_m, 5.0)
        t2 = time.perf_counter()
        reference = association_reference(users, uavs, reach_m)
        t3 = time.perf_counter()
        state = assign_users(users, uavs, reach_m)
        t4 = time.perf_counter()
        compiled = (state.association, state.distance_sq_m2, state.counts, state.n_covering,
                    state.exclusive_counts)
        if not np.allclose(slow, fast, rtol=0.0, atol=1e-9) or not all(
                np.array_equal(a, b) for a, b in zip(reference, compiled, strict=True)):
            raise SystemExit(f"case {case}: the compiled answer differs from the reference")
        for name, seconds in zip(times, (t1 - t0, t2 - t1, t3 - t2, t4 - t3), strict=True):
            times[name].append(seconds * 1e3)
    medians = {name: float(np.median(values)) for name, values in times.items()}
    print(f"{args.cases} cases, every answer equal to the reference's")
    for kernel in ("parking", "association"):
        reference_ms, compiled_ms = medians[kernel + " reference"], medians[kernel]
        print(f"{kernel:<12}: reference {reference_ms:8.4f} ms, compiled {compiled_ms:8.4f} ms per call "
              f"(median), {reference_ms / compiled_ms:6.1f}x")
    load = ", ".join(f"{v:.2f}" for v in os.getloadavg())
    print(f"load average after: {load}")


if __name__ == "__main__":
    main()
