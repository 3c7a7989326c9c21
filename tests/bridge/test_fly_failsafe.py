"""``fly``'s failsafe flights and launch rule on ArduPilot-like and PX4-like peers, MAVLink on loopback.

Before arming each vehicle's return path is set and read back (no cone, RTL only); a parameter that
cannot be set refuses the flight naming it; homes between the minimum and the launch spacing climb one at
a time, judged from the peers' own tracks.
"""

from __future__ import annotations

import json
import math

import pytest
from lossy_relay import free_udp_port
from peer_fleet import bridge_toml, close_all, swift, wait_until
from peer_tracks import closest_approach
from pymavlink.dialects.v20 import common as mavlink

from bridge.simulated.ardupilot import FAILSAFE_ON as ARDUPILOT_FAILSAFE
from bridge.simulated.ardupilot import ArduCopter
from bridge.simulated.fleet import launch_home
from bridge.simulated.peer import endpoint_pair
from bridge.simulated.px4 import FAILSAFE_ON as PX4_FAILSAFE
from bridge.simulated.px4 import Px4Copter
from uav_swarm.cli import main

FAST = {"handshake_timeout_s": 0.3, "item_timeout_s": 0.1, "max_retries": 3}
MIN_M = 5.0
SPACING_M = 8.0  # the launch spacing with the [guard] defaults: 5 + 1 + 2 (0.5 + 0.5)


def _fleet(kinds: list[str], homes: list) -> tuple[list, list[str]]:
    vehicles, urls = [], []
    for sid, (kind, home) in enumerate(zip(kinds, homes, strict=True), start=1):
        vehicle_url, gcs_url = endpoint_pair("udpin", free_udp_port())
        cls, failsafe = (Px4Copter, PX4_FAILSAFE) if kind == "px4" else (ArduCopter, ARDUPILOT_FAILSAFE)
        vehicles.append(cls(vehicle_url, sid, home=home, params=failsafe | swift(kind)))
        urls.append(gcs_url)
    return vehicles, urls


def _argv(tmp_path, urls: list[str], *extra: str) -> list[str]:
    toml = str(bridge_toml(tmp_path / "bridge.toml", urls, FAST))
    return ["fly", "--bridge-config", toml, "--out", str(tmp_path / "out"), "--duration-s", "4", "--speedup",
            "2", "--no-telemetry", *extra]


def test_the_return_path_is_set_and_read_back_before_arming_on_both_autopilots(tmp_path):
    """At their defaults both would lower the return near home by a cone (RTL_CONE_SLOPE 3,
    RTL_CONE_ANG 45), ArduPilot would fly on in a pilot's mode (FS_OPTIONS 16) and PX4 would hold 5 s after
    its link-loss timeout before returning (COM_FAIL_ACT_T 5): all pinned, read back and reported, and
    the flight flies."""
    vehicles, urls = _fleet(["ardupilot", "px4"], [launch_home(0), launch_home(1)])
    assert vehicles[0].param("RTL_CONE_SLOPE") == 3.0 and vehicles[1].param("RTL_CONE_ANG") == 45.0
    assert vehicles[1].param("COM_FAIL_ACT_T") == 5.0
    try:
        assert main(_argv(tmp_path, urls)) == 0
        assert wait_until(lambda: not any(v.armed for v in vehicles), 90.0)  # home and landed
    finally:
        close_all(vehicles)
    ardupilot, px4 = vehicles
    assert ardupilot.param("RTL_CONE_SLOPE") == 0.0 and ardupilot.param("RTL_ALT_TYPE") == 0.0
    assert ardupilot.param("FS_OPTIONS") == 0.0
    assert px4.param("RTL_CONE_ANG") == 0.0 and px4.param("RTL_TYPE") == 0.0
    assert px4.param("COM_FAIL_ACT_T") == 0.0
    assert px4.param("RTL_DESCEND_ALT") <= px4.param("RTL_RETURN_ALT")
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    paths = {r["system_id"]: r["return_path"] for r in summary["preflight"]}
    assert paths[1] == {"RTL_CONE_SLOPE": 0.0, "RTL_ALT_TYPE": 0.0, "FS_OPTIONS": 0.0}
    assert paths[2]["RTL_CONE_ANG"] == 0.0 and paths[2]["RTL_TYPE"] == 0.0
    assert paths[2]["COM_FAIL_ACT_T"] == 0.0
    assert summary["launch_spacing_m"] == SPACING_M
    for vehicle in vehicles:
        assert math.hypot(*vehicle.enu[:2]) < 1.0 and vehicle.enu[2] == 0.0


@pytest.mark.parametrize(("kind", "name", "value"), [
    ("px4", "RTL_CONE_ANG", None),  # an autopilot that does not answer it
    ("px4", "COM_FAIL_ACT_T", None),
    ("ardupilot", "FS_OPTIONS", None),
    ("ardupilot", "FS_GCS_ENABLE", 5.0),  # LAND where it is: not the return the guard separates
    ("px4", "NAV_DLL_ACT", 3.0)])
def test_a_failsafe_that_cannot_be_pinned_refuses_arming_naming_the_parameter(tmp_path, capsys, kind, name,
                                                                               value):
    vehicles, urls = _fleet([kind, kind], [launch_home(0), launch_home(1)])
    if value is None:
        del vehicles[1].params[name]
    else:
        vehicles[1].params[name] = (value, vehicles[1].params[name][1])
    try:
        assert main(_argv(tmp_path, urls)) == 2
        err = capsys.readouterr().err
        assert f"vehicle 2: {name}" in err and "nothing was armed" in err, err
        for vehicle in vehicles:
            assert not vehicle.armed and mavlink.MAV_CMD_COMPONENT_ARM_DISARM not in vehicle.commands
        assert not (tmp_path / "out").exists()
    finally:
        close_all(vehicles)


def _climb(vehicle, alt_m: float) -> tuple[float, float]:
    """(left the ground, reached ``alt_m`` - 1 m) of its first climb, from its own track."""
    up = next(t for t, _, _, z in vehicle.track if z > 0.05)
    top = next(t for t, _, _, z in vehicle.track if t >= up and z >= alt_m - 1.0)
    return up, top


def test_homes_closer_than_the_launch_spacing_climb_one_at_a_time_and_closer_than_the_minimum_are_refused(
        tmp_path, capsys):
    """Three ArduCopters 6 m apart (between the minimum and the 8 m launch spacing): each climbs only when
    its neighbour has climbed and moved off; they keep the minimum. Homes 4 m apart are refused, the
    message naming the minimum and the launch spacing."""
    vehicles, urls = _fleet(["ardupilot"] * 3, [launch_home(i, 6.0) for i in range(3)])
    try:
        assert main([*_argv(tmp_path, urls), "--duration-s", "40"]) == 0
        assert wait_until(lambda: not any(v.armed for v in vehicles), 90.0)
        approach = closest_approach(vehicles)
        climbs = [_climb(v, 10.0) for v in vehicles]
    finally:
        close_all(vehicles)
    for first, second in ((0, 1), (1, 2)):  # neighbours never climb together
        a, b = climbs[first], climbs[second]
        assert a[1] <= b[0] or b[1] <= a[0], climbs
    assert approach.distance_m >= MIN_M, approach
    vehicles, urls = _fleet(["ardupilot", "px4"], [launch_home(0, 4.0), launch_home(1, 4.0)])
    try:
        assert main(_argv(tmp_path, urls, "--out", str(tmp_path / "close"))) == 2
        err = capsys.readouterr().err
        assert "4.0 m apart" in err and "uav.min_separation_m = 5 m" in err
        assert f"{SPACING_M:g} m apart (the launch spacing" in err
        assert not any(mavlink.MAV_CMD_COMPONENT_ARM_DISARM in v.commands for v in vehicles)
    finally:
        close_all(vehicles)
