"""The outline in metres: witnesses, candidates and visibility with a margin, checked against GEOS."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from uav_swarm.missions.monitoring.outline import (
    TOUCH_M,
    Outline,
    OutlineError,
    candidates,
    visibility,
    witnesses,
)

SQUARE = np.array([[0.0, 0.0], [20.0, 0.0], [20.0, 10.0], [0.0, 10.0]])
COMB = np.array([[0, 0], [150, 0], [150, 60], [130, 60], [130, 20], [110, 20], [110, 60], [85, 60], [85, 20],
                 [65, 20], [65, 60], [50, 60], [50, 20], [30, 20], [30, 60], [0, 60]], dtype=float)
COURTYARD = (np.array([[0.0, 0.0], [60.0, 0.0], [60.0, 50.0], [0.0, 50.0]]),
             [np.array([[20.0, 15.0], [20.0, 35.0], [40.0, 35.0], [40.0, 15.0]])])


def _geos_sees(outline, guard, point, own, clearance, region):
    """The visibility rules judged one pair at a time with shapely (an independent implementation)."""
    if np.array_equal(guard, point):
        return True  # a guard standing on the witness sees it
    line = shapely.LineString([guard, point])
    direction = (guard - point) / np.hypot(*(guard - point))
    step = point + 1e-6 * direction
    if bool(outline.polygon.contains(shapely.Point(step))) != (region == "interior"):
        return False  # rule 2: leaves w into the region
    for e, (ax, ay, bx, by) in enumerate(outline.walls_m):
        if e in own:
            continue
        wall = shapely.LineString([(ax, ay), (bx, by)])
        near = wall.distance(shapely.Point(point)) < 2 * clearance
        limit = TOUCH_M if (near or clearance == 0) else clearance - TOUCH_M
        if line.distance(wall) < limit:
            return False
    return True


@pytest.mark.parametrize("clearance", [0.0, 0.5, 1.5], ids=lambda c: f"margin{c}")
@pytest.mark.parametrize(("rings", "region"), [((COMB, []), "interior"), ((COMB, []), "exterior"),
                                              (COURTYARD, "interior"), (COURTYARD, "exterior")],
                         ids=["comb-agp", "comb-fp", "courtyard-agp", "courtyard-fp"])
def test_visibility_agrees_with_a_pair_by_pair_geos_judge(rings, region, clearance):
    outline = Outline.from_rings(*rings)
    rng = np.random.default_rng(7)
    targets = witnesses(outline, region, spacing_m=2.0)
    pick = rng.choice(len(targets), size=120, replace=False)
    targets = targets.subset(np.concatenate([np.flatnonzero(targets.walls[:, 1] >= 0), pick]))  # + vertices
    guards = candidates(outline, region, spacing_m=3.0, standoff_m=max(clearance, 0.5), reach_m=10.0)
    guards = guards[rng.choice(len(guards), size=25, replace=False)]
    seen = visibility(outline, guards, targets, clearance, region)
    expected = np.array([[_geos_sees(outline, g, p, set(own[own >= 0].tolist()), clearance, region)
                          for p, own in zip(targets.points_m, targets.walls, strict=True)] for g in guards])
    assert np.array_equal(seen, expected)
    assert 0 < seen.sum() < seen.size  # both outcomes occur


def test_a_guard_on_a_walls_line_does_not_see_along_it():
    outline = Outline.from_rings(SQUARE)
    wall = witnesses(outline, "exterior", 0.5)
    bottom = wall.walls[:, 0] == 0  # the wall (0, 0)-(20, 0)
    grazing = np.array([[25.0, 0.0]])  # beyond its end, on its line
    for clearance in (0.0, 0.5):
        sees = visibility(outline, grazing, wall, clearance, "exterior")[0]
        assert not sees[bottom & (wall.points_m[:, 0] < 19.0)].any()


def test_the_margin_refuses_a_line_past_a_corner_by_a_hair():
    outline = Outline.from_rings(SQUARE)
    target = witnesses(outline, "exterior", 0.5)
    point = np.flatnonzero(np.all(np.isclose(target.points_m, [10.0, 10.0]), axis=1))  # top wall
    # from beside the right wall, the line to (10, 10) passes 0.17 m from the corner (20, 10)
    guard = np.array([[30.0, 10.35]])
    assert visibility(outline, guard, target.subset(point), 0.0, "exterior")[0, 0]
    assert not visibility(outline, guard, target.subset(point), 0.5, "exterior")[0, 0]


def test_a_courtyard_is_seen_from_within_and_excluded_from_the_interior():
    outline = Outline.from_rings(*COURTYARD)
    wall = witnesses(outline, "exterior", 0.5)
    inner = wall.walls[:, 0] >= 4  # the courtyard's walls come after the outer ring's 4
    seen = visibility(outline, np.array([[30.0, 25.0]]), wall, 0.5, "exterior")[0]
    assert seen[inner].mean() > 0.9 and not seen[~inner].any()
    inside = witnesses(outline, "interior", 1.0).points_m
    in_courtyard = (inside[:, 0] > 20) & (inside[:, 0] < 40) & (inside[:, 1] > 15) & (inside[:, 1] < 35)
    assert not in_courtyard.any()
    spots = candidates(outline, "exterior", 1.0, standoff_m=1.0, reach_m=5.0)
    assert np.any((np.abs(spots[:, 0] - 30) < 9) & (np.abs(spots[:, 1] - 25) < 9))  # guards fit in it


def test_witnesses_cover_every_vertex_at_the_stated_spacing():
    outline = Outline.from_rings(COMB)
    wall = witnesses(outline, "exterior", 0.5)
    assert all(np.any(np.all(np.isclose(wall.points_m, v), axis=1)) for v in COMB)
    gaps = []
    for e in range(outline.n_vertices):
        along = np.sort(np.hypot(*(wall.points_m[wall.walls[:, 0] == e] - outline.walls_m[e, :2]).T))
        length = np.hypot(*(outline.walls_m[e, 2:] - outline.walls_m[e, :2]))
        gaps.append(np.diff(np.append(along, length)).max())
    assert max(gaps) <= 0.5 + 1e-9
    inside = witnesses(outline, "interior", 0.5)
    assert shapely.contains_xy(shapely.Polygon(COMB).buffer(1e-9), *inside.points_m.T).all()


def test_candidates_keep_the_standoff():
    outline = Outline.from_rings(*COURTYARD)
    for region in ("interior", "exterior"):
        spots = candidates(outline, region, 1.0, standoff_m=2.0, reach_m=6.0)
        assert len(spots) > 0 and outline.wall_distances(spots).min() >= 2.0
        assert np.all(outline.inside(spots) == (region == "interior"))


@pytest.mark.parametrize(("rings", "match"), [
    ((np.array([[0.0, 0.0], [10.0, 10.0], [10.0, 0.0], [0.0, 10.0]]), []), r"Self-intersection\[5 5\]"),
    ((SQUARE, [np.array([[30.0, 1.0], [35.0, 1.0], [35.0, 5.0]])]), "Hole lies outside shell"),
    ((np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]), []), "no area|Too few|invalid|Self"),
    ((np.array([[0.0, 0.0], [0.0, 0.0], [1.0, 1.0]]), []), "2 distinct"),
])
def test_invalid_outlines_are_refused_with_the_place_in_metres(rings, match):
    with pytest.raises(OutlineError, match=match):
        Outline.from_rings(*rings)
