from itertools import combinations

import numpy as np
import pytest

from uav_swarm.missions.monitoring.guards import (
    art_gallery_problem,
    boundary_points,
    fortress_problem,
    interior_pixels,
    solve_guards,
    tie_break_cost,
)
from uav_swarm.missions.monitoring.polygons import Polygon, PolygonConfig, locate_points, random_polygon
from uav_swarm.missions.monitoring.setcover import InfeasibleCoverError


def comb(teeth: int) -> tuple[Polygon, list[int]]:
    """A base 4 px high with ``teeth`` teeth 2 px wide, 14 px high, 6 px apart; returns the teeth's left x."""
    left = [2 + 6 * i for i in range(teeth)]
    vertices = [(1, 1), (6 * teeth + 1, 1), (6 * teeth + 1, 5)]
    for a in reversed(left):
        vertices += [(a + 2, 5), (a + 2, 19), (a, 19), (a, 5)]
    vertices.append((1, 5))
    return Polygon(np.array(vertices), size_px=max(21, 6 * teeth + 3)), left


@pytest.mark.parametrize("teeth", [1, 2, 3, 4])
def test_comb_with_k_teeth_needs_k_guards_one_per_tooth(teeth):
    polygon, left = comb(teeth)
    problem = art_gallery_problem(polygon)
    guards = problem.candidates_px[solve_guards(problem)]
    assert len(guards) == teeth
    for a in left:
        assert np.any(np.abs(guards[:, 0] - (a + 1)) <= 2)


def test_convex_polygons_need_one_art_gallery_guard():
    rng = np.random.default_rng(3)
    for _ in range(5):
        angles = np.sort(rng.uniform(0, 2 * np.pi, size=8))
        points = np.unique(np.rint(20 + 15 * np.stack([np.cos(angles), np.sin(angles)], axis=1)), axis=0)
        hull = _convex_hull(points)
        problem = art_gallery_problem(Polygon(hull, size_px=40))
        assert len(solve_guards(problem)) == 1


def _convex_hull(points):
    """Monotone chain, strictly convex (collinear points dropped)."""
    pts = sorted(map(tuple, points))

    def half(seq):
        out = []
        for p in seq:
            while len(out) >= 2 and ((out[-1][0] - out[-2][0]) * (p[1] - out[-2][1])
                                     - (out[-1][1] - out[-2][1]) * (p[0] - out[-2][0])) <= 0:
                out.pop()
            out.append(p)
        return out[:-1]

    return np.array(half(pts) + half(pts[::-1]))


def test_fortress_of_a_square_needs_two_guards_that_see_all_of_it():
    square = Polygon(np.array([[10, 10], [30, 10], [30, 30], [10, 30]]), size_px=40)
    problem = fortress_problem(square)
    chosen = solve_guards(problem)
    assert len(chosen) == 2
    assert np.all(problem.visibility[chosen].any(axis=0))
    assert np.all(locate_points(problem.candidates_px[chosen], square.vertices_px) == -1)


def test_boundary_points_are_on_the_boundary_and_close_enough():
    polygon = random_polygon(np.random.default_rng(9), PolygonConfig())
    for spacing in (0.5, 1.0, 3.0):
        points = boundary_points(polygon, spacing)
        assert np.all(locate_points(points, polygon.vertices_px) == 0)
        gaps = np.hypot(*np.diff(np.vstack([points, points[:1]]), axis=0).T)
        assert gaps.max() <= spacing + 1e-9
        assert {tuple(v) for v in polygon.vertices_px} <= {tuple(p) for p in points}
    with pytest.raises(ValueError, match="spacing_px = 0"):
        boundary_points(polygon, 0.0)
    with pytest.raises(ValueError, match="allowed at most 1000"):
        boundary_points(polygon, 0.01)


def _brute_force(problem):
    """Fewest guards by enumeration over distinct visibility sets, and the least tie-break cost then."""
    cost = tie_break_cost(problem)
    best: dict[int, float] = {}
    for row, c in zip(problem.visibility, cost, strict=True):
        mask = int("".join("1" if b else "0" for b in row) or "0", 2)
        best[mask] = min(best.get(mask, np.inf), c)
    masks = list(best)
    full = (1 << problem.visibility.shape[1]) - 1
    for k in range(1, 5):
        covers = [sum(best[m] for m in combo) for combo in combinations(masks, k)
                  if _union(combo) == full]
        if covers:
            return k, min(covers)
    raise AssertionError("needs more than 4 guards: pick a smaller polygon")


def _union(masks):
    out = 0
    for m in masks:
        out |= m
    return out


@pytest.mark.parametrize("kind", ["agp", "fp"])
def test_expert_is_optimal_on_small_polygons_by_brute_force(kind):
    rng = np.random.default_rng(21)
    config = PolygonConfig(size_px=14, margin_px=1, min_vertices=6, max_vertices=9, min_reflex_vertices=2)
    counts = []
    while len(counts) < 4:
        polygon = random_polygon(rng, config)
        problem = art_gallery_problem(polygon) if kind == "agp" else fortress_problem(polygon)
        try:
            chosen = solve_guards(problem)
        except InfeasibleCoverError:
            assert not np.all(problem.visibility.any(axis=0))
            continue
        assert np.all(problem.visibility[chosen].any(axis=0))
        count, cost = _brute_force(problem)
        assert len(chosen) == count
        assert tie_break_cost(problem)[chosen].sum() == cost
        counts.append(count)
    assert max(counts) >= 2  # the check covered non-trivial instances


def test_art_gallery_candidates_are_the_interior_pixels_and_the_expert_is_deterministic():
    polygon = random_polygon(np.random.default_rng(8), PolygonConfig())
    problem = art_gallery_problem(polygon)
    np.testing.assert_array_equal(problem.candidates_px, interior_pixels(polygon))
    first = solve_guards(problem)
    np.testing.assert_array_equal(solve_guards(art_gallery_problem(polygon)), first)
