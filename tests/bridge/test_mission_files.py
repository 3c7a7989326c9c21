import json
import math
import os
import stat

import pytest
from pymavlink import mavwp
from pymavlink.dialects.v20 import common as mavlink

from bridge.geo import Home
from bridge.geofence import GeofenceConfig
from bridge.missions.files import load_mission, load_plan, load_wpl, save_mission, save_plan, save_wpl
from bridge.missions.items import DEG_E7, MissionConfig, build_mission

HOME = Home(lat_deg=-33.8567844, lon_deg=151.2152967, alt_m=12.345678)
AUTOPILOTS = {"ardupilot": mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, "px4": mavlink.MAV_AUTOPILOT_PX4}


def _mission(autopilot):
    config = MissionConfig(
        cruise_alt_m=33.3, acceptance_radius_m=1.7, loiter_time_s=12.5, return_to_launch=True, speed_m_s=7.5
    )
    return build_mission(
        [(12.34, -56.78), (-123.456, 222.2, 47.77)], HOME, config, GeofenceConfig(), autopilot
    )


@pytest.mark.parametrize("autopilot", AUTOPILOTS.values(), ids=AUTOPILOTS.keys())
def test_plan_round_trip_is_lossless(tmp_path, autopilot):
    mission = _mission(autopilot)
    path = tmp_path / "m.plan"
    save_plan(path, mission)
    assert load_plan(path) == mission
    document = json.loads(path.read_text())
    assert document["fileType"] == "Plan" and document["mission"]["firmwareType"] == autopilot
    assert document["mission"]["plannedHomePosition"] == [HOME.lat_deg, HOME.lon_deg, HOME.alt_m]
    # ArduPilot's home placeholder is implied by the planned home, as in QGroundControl
    listed = len(mission.items) - (1 if autopilot == mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA else 0)
    assert len(document["mission"]["items"]) == listed
    assert document["mission"]["items"][0]["params"][3] is None  # NaN yaw is JSON null


@pytest.mark.parametrize("autopilot", AUTOPILOTS.values(), ids=AUTOPILOTS.keys())
def test_wpl_round_trip_is_lossless(tmp_path, autopilot):
    mission = _mission(autopilot)
    path = tmp_path / "m.waypoints"
    save_wpl(path, mission.items)
    assert path.read_text().splitlines()[0] == "QGC WPL 110"
    assert load_wpl(path) == mission.items
    assert load_mission(path, HOME, autopilot) == mission


def test_wpl_loads_in_pymavlink_mavwploader(tmp_path):
    mission = _mission(mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA)
    path = tmp_path / "m.waypoints"
    save_mission(path, mission)
    loader = mavwp.MAVWPLoader()
    assert loader.load(str(path)) == len(mission.items)
    for ours, theirs in zip(mission.items, (loader.wp(i) for i in range(loader.count())), strict=True):
        assert (theirs.seq, theirs.frame, theirs.command, theirs.current, theirs.autocontinue) == (
            ours.seq,
            ours.frame,
            ours.command,
            ours.current,
            ours.autocontinue,
        )
        assert round(theirs.x * DEG_E7) == ours.x and round(theirs.y * DEG_E7) == ours.y
        assert theirs.z == ours.z
        for name in ("param1", "param2", "param3", "param4"):
            a, b = getattr(theirs, name), getattr(ours, name)
            assert a == b or (math.isnan(a) and math.isnan(b))


def test_writes_are_atomic_and_replace_existing_files(tmp_path):
    path = tmp_path / "m.plan"
    path.write_text("old")
    save_mission(path, _mission(mavlink.MAV_AUTOPILOT_PX4))
    assert json.loads(path.read_text())["fileType"] == "Plan"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.plan"]  # no temporary file left


def test_mission_files_get_the_permissions_of_any_other_output(tmp_path):
    umask = os.umask(0o022)
    try:
        for name in ("m.plan", "m.waypoints"):
            save_mission(tmp_path / name, _mission(mavlink.MAV_AUTOPILOT_PX4))
            assert stat.S_IMODE((tmp_path / name).stat().st_mode) == 0o644
        (tmp_path / "other.json").write_text("{}")
        assert stat.S_IMODE((tmp_path / "other.json").stat().st_mode) == 0o644
    finally:
        os.umask(umask)


def test_failed_write_leaves_the_old_file(tmp_path):
    path = tmp_path / "m.plan"
    path.write_text("old")
    mission = _mission(mavlink.MAV_AUTOPILOT_PX4)
    broken = type(mission)(
        home=mission.home, items=mission.items, autopilot=object()
    )  # not JSON-serialisable
    with pytest.raises(TypeError):
        save_plan(path, broken)
    assert path.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.plan"]


@pytest.mark.parametrize(
    "name, text, message",
    [
        ("a.waypoints", "QGC WPL 100\n", "first line must be 'QGC WPL 110'"),
        ("b.waypoints", "QGC WPL 110\n0\t1\t0\n", "a WPL row has 12 fields, found 3"),
        ("c.plan", '{"fileType": "Other"}', "not a QGroundControl plan file"),
        ("d.kml", "", "unknown mission file suffix"),
    ],
)
def test_malformed_files_are_refused(tmp_path, name, text, message):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        load_mission(path, HOME, mavlink.MAV_AUTOPILOT_PX4)
