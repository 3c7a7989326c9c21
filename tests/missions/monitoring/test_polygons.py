import numpy as np
import pytest

from typed_config import ConfigError
from uav_swarm.missions.monitoring.polygons import (
    Polygon,
    PolygonConfig,
    PolygonSamplingError,
    is_simple,
    locate_points,
    random_polygon,
    reflex_mask,
    signed_area,
)


def _orient(a, b, c):
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])


def _on_segment(p, a, b):
    return min(a[0], b[0]) <= p[0] <= max(a[0], b[0]) and min(a[1], b[1]) <= p[1] <= max(a[1], b[1])


def _segments_meet(a, b, c, d):
    """Exact integer test (pure Python): closed segments ab and cd share a point."""
    o1, o2, o3, o4 = _orient(a, b, c), _orient(a, b, d), _orient(c, d, a), _orient(c, d, b)
    if o1 * o2 < 0 and o3 * o4 < 0:
        return True
    return ((o1 == 0 and _on_segment(c, a, b)) or (o2 == 0 and _on_segment(d, a, b))
            or (o3 == 0 and _on_segment(a, c, d)) or (o4 == 0 and _on_segment(b, c, d)))


def _brute_force_simple(vertices):
    v = [tuple(int(c) for c in p) for p in vertices]
    n = len(v)
    for i in range(n):
        for j in range(i + 1, n):
            if j == i + 1 or (i == 0 and j == n - 1):
                continue
            if _segments_meet(v[i], v[(i + 1) % n], v[j], v[(j + 1) % n]):
                return False
    return all(_orient(v[i - 1], v[i], v[(i + 1) % n]) != 0 for i in range(n))


@pytest.mark.parametrize("vertex_range", [(6, 6), (6, 20), (20, 20)], ids=["6", "6-20", "20"])
def test_random_polygons_are_simple_and_follow_the_config(vertex_range):
    config = PolygonConfig(min_vertices=vertex_range[0], max_vertices=vertex_range[1], min_reflex_vertices=2)
    rng = np.random.default_rng(123)
    for _ in range(60):
        polygon = random_polygon(rng, config)
        v = polygon.vertices_px
        assert _brute_force_simple(v)
        assert vertex_range[0] <= polygon.n_vertices <= vertex_range[1]
        assert v.min() >= config.margin_px and v.max() <= config.size_px - 1 - config.margin_px
        assert np.all(v == np.round(v))
        assert polygon.signed_area_px2 > 0
        assert np.count_nonzero(polygon.reflex) >= 2
        assert polygon.signed_area_px2 >= 100  # a building, not a sliver


def test_same_seed_same_polygon_and_different_seeds_differ():
    config = PolygonConfig()
    first = random_polygon(np.random.default_rng(5), config)
    again = random_polygon(np.random.default_rng(5), config)
    other = random_polygon(np.random.default_rng(6), config)
    np.testing.assert_array_equal(first.vertices_px, again.vertices_px)
    a, b = first.vertices_px, other.vertices_px
    assert a.shape != b.shape or np.any(a != b)


@pytest.mark.parametrize(
    "vertices",
    [
        [[0, 0], [4, 4], [4, 0], [0, 4]],  # bow-tie
        [[0, 0], [6, 0], [6, 6], [3, 0], [0, 6]],  # vertex touching another edge
        [[0, 0], [2, 0], [4, 0], [4, 4], [0, 4]],  # straight (collinear) vertex
        [[0, 0], [4, 0], [4, 4], [4, 0], [0, 4]],  # repeated vertex
    ],
    ids=["bowtie", "touching", "straight", "repeated"],
)
def test_is_simple_rejects_degenerate_chains(vertices):
    assert not is_simple(np.array(vertices))
    with pytest.raises(ValueError, match="not a simple polygon"):
        Polygon(np.array(vertices), size_px=8)


def test_polygon_is_stored_counter_clockwise_with_its_reflex_vertices():
    clockwise = np.array([[0, 0], [0, 6], [2, 6], [2, 2], [4, 2], [4, 6], [6, 6], [6, 0]])
    assert signed_area(clockwise) < 0
    polygon = Polygon(clockwise, size_px=8)
    assert polygon.signed_area_px2 == pytest.approx(28.0)
    reflex_points = {tuple(p) for p in polygon.vertices_px[polygon.reflex]}
    assert reflex_points == {(2.0, 2.0), (4.0, 2.0)}
    np.testing.assert_array_equal(reflex_mask(clockwise), reflex_mask(clockwise[::-1]))


def test_locate_points_inside_boundary_outside():
    square = np.array([[1, 1], [5, 1], [5, 5], [1, 5]])
    points = np.array([[3, 3], [1, 3], [5, 5], [3.5, 1], [0, 3], [6, 1], [3, 5.5]])
    np.testing.assert_array_equal(locate_points(points, square), [1, 0, 0, 0, -1, -1, -1])


@pytest.mark.parametrize("size", [32, 64, 100])
def test_pixel_locations_match_locate_points_on_every_pixel_centre(size):
    rng = np.random.default_rng(size)
    rows, cols = np.mgrid[0:size, 0:size]
    centres = np.stack([cols.ravel(), rows.ravel()], axis=1)
    for margin in (0, 2):
        for _ in range(15):
            polygon = random_polygon(rng, PolygonConfig(size_px=size, margin_px=margin))
            codes = polygon.pixel_locations()
            assert codes.shape == (size, size) and codes.dtype == np.int8
            expected = locate_points(centres, polygon.vertices_px).reshape(size, size)
            np.testing.assert_array_equal(codes, expected)
            for x, y in polygon.vertices_px.astype(int):
                assert codes[y, x] == 0


def test_pixel_locations_of_axis_aligned_and_diagonal_edges():
    diamond = Polygon(np.array([[4, 0], [8, 4], [4, 8], [0, 4]]), size_px=9)
    codes = diamond.pixel_locations()
    assert codes[4, 4] == 1 and codes[2, 2] == 0 and codes[1, 1] == -1 and codes[0, 4] == 0
    square = Polygon(np.array([[1, 1], [5, 1], [5, 5], [1, 5]]), size_px=7)
    assert square.pixel_locations()[1, 3] == 0 and square.pixel_locations()[3, 3] == 1


@pytest.mark.parametrize(
    ("values", "match"),
    [
        ({"min_vertices": 12, "max_vertices": 8}, "min_vertices = 12"),
        ({"min_reflex_vertices": 10, "max_vertices": 8}, "min_reflex_vertices = 10"),
        ({"size_px": 16, "margin_px": 6}, "margin_px = 6"),
        ({"max_vertices": 100}, "max_vertices = 100"),
        ({"size_px": 4}, "size_px = 4"),
        ({"vertices": 8}, "unknown key"),
    ],
)
def test_config_errors_name_the_field(values, match):
    with pytest.raises(ConfigError, match=match):
        PolygonConfig.from_dict(values)


@pytest.mark.parametrize(
    ("vertices", "match"),
    [
        ([[0, 0], [4, 0]], "shape"),
        ([[0, 0], [4.5, 0], [4, 4]], "integer"),
        ([[0, 0], [9, 0], [4, 4]], "size_px"),
    ],
)
def test_polygon_validation_errors(vertices, match):
    with pytest.raises(ValueError, match=match):
        Polygon(np.array(vertices), size_px=8)


def test_impossible_rules_raise_a_sampling_error():
    config = PolygonConfig(min_vertices=20, max_vertices=20, min_clearance_px=16.0, max_attempts=3)
    with pytest.raises(PolygonSamplingError, match="max_attempts = 3"):
        random_polygon(np.random.default_rng(0), config)
