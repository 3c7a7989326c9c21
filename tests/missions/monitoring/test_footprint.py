import json
from pathlib import Path

import numpy as np
import pytest

from uav_swarm.missions.monitoring.footprint import (
    Footprint,
    FootprintError,
    fit_to_raster,
    read_footprint,
    read_site,
)
from uav_swarm.missions.monitoring.polygons import is_simple

BUILDINGS = Path(__file__).resolve().parents[2] / "data" / "buildings"


@pytest.mark.parametrize(("name", "vertices"), [("urban_market", 5), ("picnic_shelter", 5),
                                                ("alta_east_outer", 7), ("marta_station", 59)])
def test_real_footprints_are_read_in_metres_and_fit_the_raster(name, vertices):
    footprint = read_footprint(BUILDINGS / f"{name}.geojson")
    assert len(footprint.vertices_m) == vertices and footprint.origin is not None
    fitted = fit_to_raster(footprint)
    v = fitted.polygon.vertices_px
    assert v.min() >= 4 and v.max() <= 59  # the 4 px margin on the 64 px raster
    assert np.ptp(v, axis=0).max() == 55  # the larger side spans the raster less the margins
    # the fitted outline stays within half a pixel of the input, in metres
    back = fitted.to_metres(v)
    distance = np.min(np.linalg.norm(back[:, None] - footprint.vertices_m[None], axis=2), axis=1)
    assert distance.max() <= 0.5 * np.sqrt(2) * fitted.metres_per_px + 1e-9


def test_the_station_sizes_match_the_data_readme():
    extent = np.ptp(read_footprint(BUILDINGS / "marta_station.geojson").vertices_m, axis=0)
    assert extent == pytest.approx([162.0, 228.3], abs=1.0)


def test_input_coordinates_round_trip_through_metres():
    footprint = read_footprint(BUILDINGS / "alta_east_outer.geojson")
    lonlat = json.loads((BUILDINGS / "alta_east_outer.geojson").read_text())["features"][0]["geometry"][
        "coordinates"][0][:-1]
    np.testing.assert_allclose(footprint.to_input(footprint.vertices_m), lonlat, atol=1e-9)


def test_a_courtyard_is_a_hole_and_a_multipolygon_a_site_of_buildings():
    courtyard = read_footprint(BUILDINGS / "alta_east_with_courtyard.geojson")
    outer = read_footprint(BUILDINGS / "alta_east_outer.geojson")
    assert len(courtyard.holes_m) == 1
    outline = courtyard.outline()
    assert outline.polygon.area < outer.outline().polygon.area  # the courtyard is not the building
    site = read_site(BUILDINGS / "ferguson_two_parts.geojson")
    assert len(site) == 2 and site[0].origin == site[1].origin  # one East-North frame for the site
    assert not site[0].outline().polygon.intersects(site[1].outline().polygon)
    with pytest.raises(FootprintError, match="2 buildings; read a site with read_site"):
        read_footprint(BUILDINGS / "ferguson_two_parts.geojson")


def test_a_feature_collection_is_a_site_and_a_courtyard_outside_its_building_is_refused(tmp_path):
    features = [json.loads((BUILDINGS / f"{name}.geojson").read_text())["features"][0]
                for name in ("urban_market", "picnic_shelter")]
    path = tmp_path / "site.geojson"
    path.write_text(json.dumps({"type": "FeatureCollection", "features": features}))
    assert [b.name for b in read_site(path)] == ["Urban Market", "picnic shelter"]
    broken = json.loads((BUILDINGS / "urban_market.geojson").read_text())
    ring = broken["features"][0]["geometry"]["coordinates"][0]
    hole = [[lon + 0.01, lat] for lon, lat in ring]  # a kilometre east: outside the building
    broken["features"][0]["geometry"]["coordinates"].append(hole)
    path.write_text(json.dumps(broken))
    with pytest.raises(FootprintError, match="Hole lies outside shell"):
        read_site(path)


def test_a_multipolygon_of_one_part_is_that_part(tmp_path):
    data = json.loads((BUILDINGS / "urban_market.geojson").read_text())
    geometry = data["features"][0]["geometry"]
    data["features"][0]["geometry"] = {"type": "MultiPolygon", "coordinates": [geometry["coordinates"]]}
    path = tmp_path / "one_part.geojson"
    path.write_text(json.dumps(data))
    np.testing.assert_allclose(read_footprint(path).vertices_m,
                               read_footprint(BUILDINGS / "urban_market.geojson").vertices_m)


def test_vertices_in_metres_from_json_and_csv(tmp_path):
    square = [[0.0, 0.0], [30.0, 0.0], [30.0, 20.0], [0.0, 20.0]]
    (tmp_path / "a.json").write_text(json.dumps(square))
    (tmp_path / "b.csv").write_text("# x, y\n" + "\n".join(f"{x}, {y}" for x, y in square) + "\n0, 0\n")
    (tmp_path / "c.txt").write_text("\n".join(f"{x} {y}" for x, y in square))
    for name in ("a.json", "b.csv", "c.txt"):
        footprint = read_footprint(tmp_path / name)
        np.testing.assert_array_equal(footprint.vertices_m, square)
        assert footprint.origin is None
        np.testing.assert_array_equal(footprint.to_input(footprint.vertices_m), square)


@pytest.mark.parametrize(("content", "suffix", "match"), [
    ("[[0, 0], [10, 10], [10, 0], [0, 10]]", ".json", "not a simple polygon"),
    ("[[0, 0], [20, 0], [0, 10], [10, 12]]", ".json", "not a simple polygon"),
    ("[[0, 0], [10, 0], [20, 0]]", ".json", "no area"),
    ("[[0, 0], [10, 0]]", ".json", "at least 3"),
    ("[[0, 0], [10, 0], [\"a\", 1]]", ".json", "pairs of"),
    ("{not json", ".geojson", "not valid JSON"),
    ('{"type": "Point", "coordinates": [1, 2]}', ".geojson", "no Polygon"),
    ('{"type": "Polygon", "coordinates": [[[0, 0], [500, 0], [0, 1]]]}', ".geojson", "longitude"),
    ('{"type": "Polygon", "coordinates": [[]]}', ".geojson", "no vertices; a building needs at least 3"),
    ("0 0\n1 0\n", ".kml", "unknown building file type"),
])
def test_malformed_buildings_get_a_clear_error(tmp_path, content, suffix, match):
    path = tmp_path / f"building{suffix}"
    path.write_text(content)
    with pytest.raises(FootprintError, match=match):
        read_footprint(path)


def test_too_many_vertices_and_missing_files_are_refused(tmp_path):
    angles = np.linspace(0, 2 * np.pi, 80, endpoint=False)
    (tmp_path / "round.json").write_text(json.dumps((50 * np.c_[np.cos(angles), np.sin(angles)]).tolist()))
    with pytest.raises(FootprintError, match="80 vertices; allowed at most 64"):
        read_footprint(tmp_path / "round.json")
    with pytest.raises(FootprintError, match="cannot read"):
        read_footprint(tmp_path / "missing.geojson")


def test_a_building_too_large_or_too_detailed_for_the_raster_is_refused():
    big = Footprint(np.array([[0.0, 0.0], [1000.0, 0.0], [1000.0, 800.0], [0.0, 800.0]]))
    with pytest.raises(FootprintError, match="max_pixel_m = 10.0"):
        fit_to_raster(big)
    comb = [[0.0, 0.0], [100.0, 0.0], [100.0, 10.0]]
    for i in range(10):  # teeth 0.2 m apart: finer than a pixel of 1.8 m
        x = 100.0 - 10.0 * i
        comb += [[x - 4.9, 10.0], [x - 4.9, 30.0], [x - 5.1, 30.0], [x - 5.1, 10.0]]
    comb += [[0.0, 10.0]]
    footprint = Footprint(np.array(comb))
    assert is_simple(footprint.vertices_m)
    with pytest.raises(FootprintError, match="finer than a pixel"):
        fit_to_raster(footprint)
