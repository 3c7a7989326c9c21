import math

import numpy as np
import pytest
from pymavlink.dialects.v20 import common as mavlink

from bridge.errors import GeofenceError
from bridge.geo import Home, geodetic_to_enu
from bridge.geofence import GeofenceConfig
from bridge.missions.items import DEG_E7, MissionConfig, MissionItem, build_mission
from typed_config import ConfigError

HOME = Home(lat_deg=47.3977418, lon_deg=8.5455938, alt_m=488.0)
FENCE = GeofenceConfig()
AUTOPILOTS = {
    "ardupilot": mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
    "px4": mavlink.MAV_AUTOPILOT_PX4,
    "generic": mavlink.MAV_AUTOPILOT_GENERIC,
}


@pytest.mark.parametrize("autopilot", AUTOPILOTS.values(), ids=AUTOPILOTS.keys())
@pytest.mark.parametrize(
    "loiter_time_s, rtl", [(0.0, False), (45.0, False), (45.0, True)], ids=["unlim", "timed", "rtl"]
)
def test_mission_shape(autopilot, loiter_time_s, rtl):
    config = MissionConfig(
        takeoff_alt_m=15.0, cruise_alt_m=30.0, loiter_time_s=loiter_time_s, return_to_launch=rtl
    )
    mission = build_mission([(10.0, 20.0), (60.0, -40.0, 45.0)], HOME, config, FENCE, autopilot)
    items = list(mission.items)
    assert [i.seq for i in items] == list(range(len(items)))
    assert sum(i.current for i in items) == 1 and items[0].current == 1
    if autopilot == mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA:
        home_item = items.pop(0)
        assert home_item.command == mavlink.MAV_CMD_NAV_WAYPOINT
        assert home_item.frame == mavlink.MAV_FRAME_GLOBAL_INT
        assert (home_item.x, home_item.y, home_item.z) == (473977418, 85455938, 488.0)
    if rtl:
        last = items.pop()
        assert (last.command, last.frame) == (mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, mavlink.MAV_FRAME_MISSION)
    commands = [i.command for i in items]
    loiter = mavlink.MAV_CMD_NAV_LOITER_TIME if loiter_time_s else mavlink.MAV_CMD_NAV_LOITER_UNLIM
    assert commands == [
        mavlink.MAV_CMD_NAV_TAKEOFF,
        mavlink.MAV_CMD_NAV_WAYPOINT,
        mavlink.MAV_CMD_NAV_WAYPOINT,
        loiter,
    ]
    assert all(i.frame == mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT for i in items)
    assert [i.z for i in items] == [15.0, 30.0, 45.0, 45.0]
    if loiter_time_s:
        assert items[-1].param1 == 45.0
    # coordinates are degE7 and come back to the ENU waypoints
    x_m, y_m, _ = geodetic_to_enu(HOME, items[2].x / DEG_E7, items[2].y / DEG_E7, HOME.alt_m)
    assert (x_m, y_m) == pytest.approx((60.0, -40.0), abs=0.01)
    assert (items[-1].x, items[-1].y) == (items[2].x, items[2].y)


def test_items_hold_float32_values_and_nan_compares_equal():
    item = MissionItem(seq=0, frame=6, command=16, param1=0.1, param4=float("nan"), z=30.00001)
    assert item.param1 == float(np.float32(0.1)) and item.z == float(np.float32(30.00001))
    assert math.isnan(item.param4)
    assert item == MissionItem(seq=0, frame=6, command=16, param1=0.1, param4=float("nan"), z=30.00001)
    assert item != MissionItem(seq=0, frame=6, command=16, param1=0.1, param4=0.0, z=30.00001)


def test_return_to_launch_after_unlimited_loiter_is_a_config_error():
    with pytest.raises(ConfigError, match="return_to_launch = true needs a timed loiter"):
        MissionConfig(loiter_time_s=0.0, return_to_launch=True)


@pytest.mark.parametrize(
    "points, message",
    [
        ([(600.0, 0.0)], r"^target: x_m = 600.00 is outside the geofence: allowed -500.0 <= x_m <= 500.0"),
        ([(0.0, -501.0), (0.0, 0.0)], r"^waypoint 1: y_m = -501.00 is outside"),
        ([(0.0, 0.0), (0.0, -501.0)], r"^target: y_m = -501.00 is outside"),
        ([(0.0, 0.0, 150.0)], r"^target: z_m = 150.00 is outside the geofence: allowed 2.0 <= z_m <= 120.0"),
        ([(0.0, 0.0, 1.0)], r"^target: z_m = 1.00 is outside"),
    ],
)
def test_geofence_refuses_points_outside(points, message):
    with pytest.raises(GeofenceError, match=message):
        build_mission(points, HOME, MissionConfig(), FENCE)


def test_geofence_config_rejects_empty_interval():
    with pytest.raises(ConfigError, match="x_min_m = 5.0 must be < x_max_m = 5.0"):
        GeofenceConfig(x_min_m=5.0, x_max_m=5.0)


@pytest.mark.parametrize("points", [[], [(1.0,)], [(1.0, 2.0, 3.0, 4.0)]])
def test_malformed_plans_are_refused(points):
    with pytest.raises(ValueError, match="waypoint"):
        build_mission(points, HOME, MissionConfig(), FENCE)


@pytest.mark.parametrize(
    "points, takeoff_m, zs",
    [
        ([(10.0, 20.0)], 20.0, [20.0, 30.0, 30.0]),  # 2-D at cruise 30: climbs, never descends
        ([(10.0, 20.0, 10.0)], 10.0, [10.0, 10.0, 10.0]),  # lower target: take-off no higher than it
        ([(5.0, 5.0, 40.0), (10.0, 20.0, 8.0)], 20.0, [20.0, 40.0, 8.0, 8.0]),  # the user asked to descend
    ],
)
def test_one_altitude_model_never_descends_after_take_off_unasked(points, takeoff_m, zs):
    mission = build_mission(points, HOME, MissionConfig(takeoff_alt_m=20.0, cruise_alt_m=30.0), FENCE)
    assert mission.items[0].z == takeoff_m and [i.z for i in mission.items] == zs
    assert mission.items[1].z >= mission.items[0].z


def test_simulate_missions_fly_at_the_simulated_altitude(tmp_path):
    from bridge.config import BridgeConfig
    from bridge.missions.files import load_plan
    from uav_swarm.runs.simulate_missions import final_plans, write_plan_files
    from uav_swarm.world.uav import UAVConfig

    bridge = BridgeConfig()  # take-off 20 m by default
    plans = final_plans(bridge, np.array([[30.0, 40.0], [5.0, 60.0]]), UAVConfig(alt_m=10.0),
                         np.array([200.0, 200.0]))
    for path in write_plan_files(bridge, plans, tmp_path):
        assert [item.z for item in load_plan(path).items] == [10.0, 10.0, 10.0]  # take-off, target, loiter


@pytest.mark.parametrize(
    "data, message",
    [
        ({"protocol": {"busy_retry_s": 601}}, "busy_retry_s = 601.0 is out of range: allowed 0.0 <="),
        ({"protocol": {"home_timeout_s": 0}}, "protocol.home_timeout_s = 0.0 is out of range: allowed 0.0 <"),
        ({"max_home_offset_m": -1.0}, "max_home_offset_m = -1.0 is out of range: allowed 0.0 <="),
        ({"home_source": "gps"}, "home_source = 'gps' is not allowed: choose one of ['config', 'vehicle']"),
        ({"home": "vehicle", "home_source": "config"}, 'home = "vehicle" contradicts home_source'),
    ],
)
def test_new_bridge_settings_are_validated_with_field_and_range(data, message):
    from bridge.config import BridgeConfig

    with pytest.raises(ConfigError, match=message.replace("(", r"\(").replace("[", r"\[")):
        BridgeConfig.from_dict(data)
    assert BridgeConfig.from_dict({"home": "vehicle"}).home_source == "vehicle"


@pytest.mark.parametrize("autopilot", [mavlink.MAV_AUTOPILOT_PX4, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA],
                         ids=["px4", "ardupilot"])
def test_a_mission_speed_is_a_change_speed_item_right_after_the_take_off(autopilot):
    home, fence = Home(), GeofenceConfig()
    plain = build_mission([(10.0, 20.0)], home, MissionConfig(), fence, autopilot)
    fast = build_mission([(10.0, 20.0)], home, MissionConfig(speed_m_s=9.5), fence, autopilot)
    take_off = next(i.seq for i in fast.items if i.command == mavlink.MAV_CMD_NAV_TAKEOFF)
    speed = fast.items[take_off + 1]
    assert speed.command == mavlink.MAV_CMD_DO_CHANGE_SPEED and speed.frame == mavlink.MAV_FRAME_MISSION
    assert (speed.param1, speed.param2, speed.param3) == (1.0, 9.5, -1.0)  # ground speed, throttle unchanged
    assert len(fast.items) == len(plain.items) + 1
    assert mavlink.MAV_CMD_DO_CHANGE_SPEED not in [i.command for i in plain.items]
