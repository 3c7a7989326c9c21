"""``uav-swarm place`` end to end on real OpenStreetMap footprints (tests/data/buildings, ODbL)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from bridge.geo import Home, geodetic_to_enu
from bridge.mission_files import load_plan
from uav_swarm.cli import main
from uav_swarm.missions.monitoring.footprint import read_footprint

BUILDINGS = Path(__file__).resolve().parents[1] / "data" / "buildings"


def _bridge_toml(path: Path, home: Home, system_ids: list[int]) -> Path:
    lines = ["[home]", f"lat_deg = {home.lat_deg}", f"lon_deg = {home.lon_deg}", f"alt_m = {home.alt_m}", "",
             "[mission]", "cruise_alt_m = 25.0", ""]
    for sid in system_ids:
        lines += ["[[vehicles]]", f"system_id = {sid}", f'url = "udpin:127.0.0.1:{14550 + sid}"', ""]
    path.write_text("\n".join(lines))
    return path


def test_a_geojson_building_gets_covering_guards_points_a_picture_and_missions(tmp_path):
    building = BUILDINGS / "alta_east_outer.geojson"
    home = Home(lat_deg=33.7450, lon_deg=-84.3615, alt_m=300.0)  # beside the building
    bridge = _bridge_toml(tmp_path / "bridge.toml", home, [11, 12, 13, 14, 15, 16])
    out = tmp_path / "out"
    assert main(["place", "--task", "fp", "--building", str(building), "--out", str(out),
                 "--bridge-config", str(bridge)]) == 0
    summary = json.loads((out / "placement.json").read_text())
    assert summary["method"] == "refined" and summary["fully_covered"] and summary["seen_fraction"] == 1.0
    geojson = json.loads((out / "guards.geojson").read_text())
    guards = [f for f in geojson["features"] if f["properties"]["role"] == "guard"]
    assert len(guards) == summary["n_guards"] >= 1
    outline = read_footprint(building)
    for feature, guard_m in zip(guards, summary["guards_m"], strict=True):
        lon, lat = feature["geometry"]["coordinates"]
        assert -84.37 < lon < -84.35 and 33.74 < lat < 33.75  # WGS84, near the building
        x, y, _ = geodetic_to_enu(outline.origin, lat, lon, 0.0)
        assert np.hypot(x - guard_m[0], y - guard_m[1]) < 0.01
    plans = sorted((out / "missions").glob("vehicle_*.plan"))
    assert [p.name for p in plans] == [f"vehicle_{11 + i}.plan" for i in range(len(guards))]
    for plan, feature in zip(plans, guards, strict=True):
        target = load_plan(plan).items[-1]
        lon, lat = feature["geometry"]["coordinates"]
        assert target.x == pytest.approx(lat * 1e7, abs=2) and target.y == pytest.approx(lon * 1e7, abs=2)
        assert target.z == pytest.approx(25.0)
    assert (out / "placement.png").stat().st_size > 10_000


@pytest.mark.parametrize("task", ["agp", "fp"])
def test_the_expert_never_uses_more_guards_than_the_refined_placement(tmp_path, task):
    building = BUILDINGS / "marta_station.geojson"
    counts = {}
    for method in ("refined", "expert"):
        out = tmp_path / method
        assert main(["place", "--task", task, "--building", str(building), "--out", str(out),
                     "--method", method]) == 0
        summary = json.loads((out / "placement.json").read_text())
        assert summary["fully_covered"]
        counts[method] = summary["n_guards"]
    assert counts["expert"] <= counts["refined"]


def test_metres_in_metres_out(tmp_path):
    building = tmp_path / "hall.csv"
    building.write_text("0,0\n60,0\n60,40\n30,40\n30,20\n0,20\n")  # an L, 60 x 40 m
    out = tmp_path / "out"
    assert main(["place", "--task", "agp", "--building", str(building), "--out", str(out),
                 "--method", "expert"]) == 0
    summary = json.loads((out / "placement.json").read_text())
    assert summary["n_guards"] == 1  # the corner where the L's arms meet sees both (exact expert)
    features = json.loads((out / "guards.geojson").read_text())["features"]
    points = [f["geometry"]["coordinates"] for f in features if f["properties"]["role"] == "guard"]
    for x, y in points:  # metres of the input, inside the L
        assert 0 <= x <= 60 and 0 <= y <= 40 and not (x > 30.5 and y > 20.5)


@pytest.mark.parametrize(("name", "message"), [
    ("alta_east_with_courtyard.geojson", "hole"),
    ("ferguson_two_parts.geojson", "MultiPolygon of 2 separate parts"),
])
def test_buildings_the_method_cannot_take_exit_2_and_write_nothing(tmp_path, capsys, name, message):
    out = tmp_path / "out"
    assert main(["place", "--task", "agp", "--building", str(BUILDINGS / name), "--out", str(out)]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_a_building_too_large_for_the_accuracy_and_a_fence_refusal_write_nothing(tmp_path, capsys):
    out = tmp_path / "out"
    station = str(BUILDINGS / "marta_station.geojson")
    assert main(["place", "--task", "fp", "--building", station, "--out", str(out),
                 "--max-pixel-m", "2"]) == 2
    assert "max_pixel_m = 2.0" in capsys.readouterr().err and not out.exists()
    far_home = Home(lat_deg=47.0, lon_deg=8.0, alt_m=400.0)  # another continent: outside the fence
    bridge = _bridge_toml(tmp_path / "bridge.toml", far_home, [])
    assert main(["place", "--task", "fp", "--building", station, "--out", str(out),
                 "--bridge-config", str(bridge)]) == 2
    assert "Geofence" in capsys.readouterr().err and not out.exists()
