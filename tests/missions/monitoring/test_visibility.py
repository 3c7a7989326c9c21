from fractions import Fraction

import numpy as np
import pytest

from uav_swarm.missions.monitoring.guards import boundary_points, exterior_pixels, interior_pixels
from uav_swarm.missions.monitoring.polygons import Polygon, PolygonConfig, random_polygon
from uav_swarm.missions.monitoring.visibility import visibility_matrix

# U shape: two arms x in [0, 2] and [4, 6] above a base y in [0, 2]; the notch 2 < x < 4, y > 2 is outside.
U_SHAPE = Polygon(np.array([[0, 0], [6, 0], [6, 6], [4, 6], [4, 2], [2, 2], [2, 6], [0, 6]]), size_px=10)
SQUARE = Polygon(np.array([[2, 2], [6, 2], [6, 6], [2, 6]]), size_px=10)


def _fraction_point(p):
    return tuple(Fraction(float(c)).limit_denominator(10_000) for c in p)


def _exact_location(p, vertices):
    """Pure-Python exact point location with Fractions: 1 inside, 0 boundary, -1 outside."""
    n = len(vertices)
    crossings = 0
    for i in range(n):
        a, b = vertices[i], vertices[(i + 1) % n]
        cross = (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
        within = min(a[0], b[0]) <= p[0] <= max(a[0], b[0]) and min(a[1], b[1]) <= p[1] <= max(a[1], b[1])
        if cross == 0 and within:
            return 0
        if (a[1] > p[1]) != (b[1] > p[1]):
            x = a[0] + (p[1] - a[1]) * (b[0] - a[0]) / (b[1] - a[1])
            crossings += x > p[0]
    return 1 if crossings % 2 else -1


def _exact_visible(polygon, guard, witness, region):
    """Oracle: split the segment at every boundary contact and test each piece's midpoint exactly."""
    vertices = [tuple(Fraction(int(c)) for c in v) for v in polygon.vertices_px]
    g, w = _fraction_point(guard), _fraction_point(witness)
    d = (w[0] - g[0], w[1] - g[1])
    cuts = {Fraction(0), Fraction(1)}
    for i in range(len(vertices)):
        a, b = vertices[i], vertices[(i + 1) % len(vertices)]
        e = (b[0] - a[0], b[1] - a[1])
        den = d[0] * e[1] - d[1] * e[0]
        r = (a[0] - g[0], a[1] - g[1])
        if den != 0:
            t, u = (r[0] * e[1] - r[1] * e[0]) / den, (r[0] * d[1] - r[1] * d[0]) / den
            if 0 <= t <= 1 and 0 <= u <= 1:
                cuts.add(t)
        elif d != (0, 0):
            for c in (a, b):
                q = (c[0] - g[0], c[1] - g[1])
                if q[0] * d[1] - q[1] * d[0] == 0:
                    t = (q[0] * d[0] + q[1] * d[1]) / (d[0] ** 2 + d[1] ** 2)
                    if 0 <= t <= 1:
                        cuts.add(t)
    cuts = sorted(cuts)
    wrong = -1 if region == "interior" else 1
    for s, t in zip(cuts, cuts[1:], strict=False):
        m = (s + t) / 2
        if _exact_location((g[0] + d[0] * m, g[1] + d[1] * m), vertices) == wrong:
            return False
    return True


@pytest.mark.parametrize(
    ("guard", "witness", "visible"),
    [
        ((1, 5), (5, 5), False),  # across the notch
        ((0, 2), (6, 2), True),  # along the notch floor, through both reflex vertices
        ((0, 4), (4, 0), True),  # grazes reflex vertex (2, 2) and stays inside
        ((0, 0), (6, 6), False),  # through reflex vertex (2, 2) into the notch
        ((1, 5), (5, 0), False),  # properly crosses the wall x = 2
        ((1, 1), (5, 1), True),
        ((0, 6), (2, 6), True),  # along the top of an arm
    ],
)
def test_art_gallery_hand_cases(guard, witness, visible):
    result = visibility_matrix(U_SHAPE, np.array([guard]), np.array([witness]), "interior")
    assert bool(result[0, 0]) is visible
    assert _exact_visible(U_SHAPE, guard, witness, "interior") is visible


@pytest.mark.parametrize(
    ("guard", "witness", "visible"),
    [
        ((0, 2), (5, 2), True),  # through convex vertex (2, 2), then along the bottom edge
        ((0, 0), (6, 6), False),  # through the interior
        ((0, 0), (2, 2), True),
        ((0, 0), (4, 2), True),
        ((0, 0), (2, 5), True),
        ((0, 0), (6, 4), False),  # the far side
        ((4, 0), (4, 6), False),
        ((8, 9), (6, 3.5), True),
    ],
)
def test_fortress_hand_cases(guard, witness, visible):
    result = visibility_matrix(SQUARE, np.array([guard]), np.array([witness]), "exterior")
    assert bool(result[0, 0]) is visible
    assert _exact_visible(SQUARE, guard, witness, "exterior") is visible


def test_convex_polygon_sees_everything_from_everywhere():
    hexagon = Polygon(np.array([[4, 1], [9, 1], [12, 5], [9, 10], [4, 10], [1, 5]]), size_px=14)
    points = interior_pixels(hexagon)
    assert np.all(visibility_matrix(hexagon, points, points, "interior"))


@pytest.mark.parametrize("region", ["interior", "exterior"])
def test_random_polygons_match_the_exact_oracle(region):
    rng = np.random.default_rng(11)
    config = PolygonConfig(size_px=24, margin_px=2, min_vertices=8, max_vertices=14)
    for _ in range(3):
        polygon = random_polygon(rng, config)
        if region == "interior":
            guards = witnesses = interior_pixels(polygon)
        else:
            guards, witnesses = exterior_pixels(polygon), boundary_points(polygon, 1.0)
        visible = visibility_matrix(polygon, guards, witnesses, region)
        pairs = [(rng.integers(len(guards)), rng.integers(len(witnesses))) for _ in range(150)]
        # Degenerate pairs: the segment's line passes through a vertex (witnesses at vertices for Fortress).
        lattice = np.flatnonzero(np.all(witnesses == np.round(witnesses), axis=1))
        for v in polygon.vertices_px:
            for j in rng.choice(lattice, size=4):
                d = guards - witnesses[j]
                line = np.abs(d[:, 0] * (v[1] - witnesses[j][1]) - d[:, 1] * (v[0] - witnesses[j][0])) < 1e-9
                pairs.extend((i, j) for i in np.flatnonzero(line)[:4])
        assert len(pairs) > 180
        for i, j in pairs:
            expected = _exact_visible(polygon, guards[i], witnesses[j], region)
            assert visible[i, j] == expected, (guards[i], witnesses[j])


def test_art_gallery_matrix_is_symmetric_and_matches_the_unshared_computation():
    polygon = random_polygon(np.random.default_rng(4), PolygonConfig())
    points = interior_pixels(polygon)
    visible = visibility_matrix(polygon, points, points, "interior")
    assert np.array_equal(visible, visible.T)
    assert np.all(np.diag(visible))
    reordered = points[::-1]  # not the same array: computed without the symmetry shortcut
    np.testing.assert_array_equal(visibility_matrix(polygon, points, reordered, "interior"), visible[:, ::-1])


def test_points_outside_the_region_are_rejected():
    with pytest.raises(ValueError, match="guards_px must lie in the closed interior"):
        visibility_matrix(SQUARE, np.array([[0.0, 0.0]]), np.array([[3.0, 3.0]]), "interior")
    with pytest.raises(ValueError, match="witnesses_px must lie in the closed exterior"):
        visibility_matrix(SQUARE, np.array([[0.0, 0.0]]), np.array([[3.0, 3.0]]), "exterior")
    with pytest.raises(ValueError, match="region = 'inside'"):
        visibility_matrix(SQUARE, np.array([[3.0, 3.0]]), np.array([[3.0, 3.0]]), "inside")
