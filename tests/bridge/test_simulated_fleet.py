"""The simulated fleet over real MAVLink on loopback: homes, the autopilots' parameters and limits, links."""

from __future__ import annotations

import math
import threading
import time

import numpy as np
import pytest
from lossy_relay import free_udp_port

from bridge.config import BridgeConfig, ProtocolConfig
from bridge.flight.params import read_param, set_param
from bridge.geo import geodetic_to_enu
from bridge.link.mavlink import MavlinkLink
from bridge.simulated.ardupilot import ARDUPILOT_PARAMS, GUIDED, ArduCopter
from bridge.simulated.dynamics import Realism
from bridge.simulated.fleet import SimulatedFleet
from bridge.simulated.peer import endpoint_pair, m
from bridge.simulated.px4 import PX4_PARAMS

FAST = ProtocolConfig(handshake_timeout_s=0.5, item_timeout_s=0.2, max_retries=5)


def _bridge(n: int, host: str = "127.0.0.1") -> BridgeConfig:
    vehicles = [{"system_id": 10 + i, "url": f"udpin:{host}:{free_udp_port()}"} for i in range(n)]
    return BridgeConfig.from_dict({"vehicles": vehicles})


def test_each_vehicle_stands_on_its_own_home_along_the_launch_line():
    bridge = _bridge(3)
    with SimulatedFleet("ardupilot", bridge, spacing_m=12.0) as fleet:
        ids = [v.system_id for v in fleet.vehicles]
        homes = [geodetic_to_enu(bridge.home, v.geo_home.lat_deg, v.geo_home.lon_deg, v.geo_home.alt_m)
                 for v in fleet.vehicles]
        failsafes = [v.param("FS_GCS_ENABLE") for v in fleet.vehicles]
    assert ids == [10, 11, 12]
    np.testing.assert_allclose(homes, [(0.0, 0.0, 0.0), (12.0, 0.0, 0.0), (24.0, 0.0, 0.0)], atol=1e-3)
    assert failsafes == [1.0, 1.0, 1.0]  # prepared as an operator would


@pytest.mark.parametrize(("change", "message"), [
    ({"autopilot": "inav"}, "autopilot = 'inav'"), ({"n": 4}, "n = 4"), ({"spacing_m": 0.0}, "spacing_m"),
    ({"host": "10.0.0.2"}, "only udpin:, udpout: or tcp: endpoints on 127.0.0.1")])
def test_a_fleet_that_cannot_be_served_is_refused_before_any_vehicle_starts(change, message):
    bridge = _bridge(3, change.pop("host", "127.0.0.1"))
    with pytest.raises(ValueError, match=message):
        SimulatedFleet(change.pop("autopilot", "px4"), bridge, **change)


@pytest.mark.parametrize(("autopilot", "names", "defaults"), [
    ("ardupilot", ("WPNAV_SPEED", "WPNAV_ACCEL", "PSC_JERK_XY", "RTL_ALT", "FS_GCS_TIMEOUT"),
     (1000.0, 250.0, 5.0, 1500.0, 5.0)),
    ("px4", ("MPC_XY_VEL_MAX", "MPC_ACC_HOR", "MPC_JERK_AUTO", "RTL_RETURN_ALT", "COM_DL_LOSS_T"),
     (12.0, 3.0, 4.0, 60.0, 10.0))])
def test_the_autopilots_limits_are_read_at_their_defaults_and_set_over_mavlink(autopilot, names, defaults):
    bridge = _bridge(1)
    with SimulatedFleet(autopilot, bridge) as fleet:
        link = MavlinkLink(bridge.vehicles[0].url)
        try:
            bytewise = autopilot == "px4"
            read = [read_param(link, 10, name, bytewise=bytewise, protocol=FAST).value for name in names]
            accel = names[1]
            table = ARDUPILOT_PARAMS if autopilot == "ardupilot" else PX4_PARAMS
            set_param(link, 10, accel, 2 * defaults[1], table[accel][1], bytewise=bytewise, protocol=FAST)
            limits = fleet.vehicles[0].limits()
        finally:
            link.close()
    assert read == list(defaults)
    scale = 100.0 if autopilot == "ardupilot" else 1.0  # ArduCopter's are in cm/s^2
    assert limits.max_accel_m_s2 == pytest.approx(2 * defaults[1] / scale)


def test_an_arducopter_flies_within_its_wpnav_speed_and_acceleration():
    vehicle_url, _ = endpoint_pair("udpin", free_udp_port())
    params = {"WPNAV_SPEED": 600.0, "WPNAV_ACCEL": 150.0}
    with ArduCopter(vehicle_url, 1, params=params, position_period_s=0.05) as vehicle:
        vehicle.enu, vehicle.armed, vehicle.custom_mode = [0.0, 0.0, 10.0], True, GUIDED
        vehicle.target = (80.0, 0.0, 10.0)
        deadline = time.monotonic() + 120.0  # bounded; it arrives after ~17 s of its own time
        while time.monotonic() < deadline and not (vehicle.track and vehicle.track[-1][1] > 80.0 - 1e-6):
            time.sleep(0.1)
        track = np.array(vehicle.track)
    east_m = track[:, 1]
    assert 80.0 - 1e-6 < east_m.max() <= 80.0 + 1e-9  # stopped at its target, not beyond
    steps = np.diff(track, axis=0)
    moving = steps[:, 0] > 0.0
    speed_m_s = steps[moving, 1] / steps[moving, 0]
    assert speed_m_s.max() <= 6.0 + 1e-6 and speed_m_s.max() > 5.0  # WPNAV_SPEED 600 cm/s reached
    # from rest, 40 m are covered no sooner than WPNAV_ACCEL allows: t >= v/a + (d - v^2/2a)/v
    at_40 = track[np.argmax(east_m >= 40.0), 0] - track[np.argmax(east_m > 0.0), 0]
    assert at_40 >= 6.0 / 1.5 + (40.0 - 6.0**2 / 3.0) / 6.0 - 0.2


def _ack_times(realism: Realism, n: int) -> list[float]:
    """Send ``n`` COMMAND_LONGs, one at a time, to a vehicle with ``realism``: the delay of each answer."""
    vehicle_url, gcs_url = endpoint_pair("udpin", free_udp_port())
    sent_s = [0.0]
    delays: list[float] = []
    answered = threading.Event()

    def on_ack(msg) -> None:
        if msg.command == m.MAV_CMD_SET_MESSAGE_INTERVAL:
            delays.append(time.monotonic() - sent_s[0])
            answered.set()

    def ask(mav) -> None:  # an interval ArduPilot denies: answered at once, whatever its state
        mav.command_long_send(target_system=1, target_component=1, command=m.MAV_CMD_SET_MESSAGE_INTERVAL,
                              confirmation=0, param1=m.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, param2=-1.0,
                              param3=0, param4=0, param5=0, param6=0, param7=0)

    with ArduCopter(vehicle_url, 1, realism=realism, rng=np.random.default_rng(3), stream_until_asked=False):
        link = MavlinkLink(gcs_url)
        link.add_listener(on_ack, {"COMMAND_ACK"})
        heard = threading.Event()
        link.add_listener(lambda _: heard.set(), {"HEARTBEAT"})
        try:
            assert heard.wait(60.0)  # our udpin end knows where the vehicle is only once it heard it
            for _ in range(n):
                answered.clear()
                sent_s[0] = time.monotonic()
                link.send(ask)
                answered.wait(realism.command_latency_s + 3.0)
        finally:
            link.close()
    return delays


def test_commands_are_answered_no_sooner_than_the_link_latency():
    delays = _ack_times(Realism(command_latency_s=0.6), 4)
    assert len(delays) == 4 and min(delays) >= 0.6


def test_lost_commands_get_no_answer():
    answers = len(_ack_times(Realism(command_loss=0.5), 16))
    assert 2 <= answers <= 14  # seeded: some lost, some answered


def test_positions_carry_their_age():
    """GLOBAL_POSITION_INT's time_boot_ms is when the position was true: ``position_age_s`` earlier."""
    vehicle_url, gcs_url = endpoint_pair("udpin", free_udp_port())
    stamps: list[tuple[float, float]] = []
    realism = Realism(position_age_s=1.5, position_rate_hz=4.0)
    with ArduCopter(vehicle_url, 1, realism=realism, stream_until_asked=False) as vehicle:
        link = MavlinkLink(gcs_url)
        link.add_listener(lambda msg: stamps.append((msg.time_boot_ms / 1000.0, vehicle._copter.now_s)),
                          {"GLOBAL_POSITION_INT"})
        try:
            deadline = time.monotonic() + 60.0
            while time.monotonic() < deadline and not any(now_s > 3.0 for _, now_s in stamps):
                time.sleep(0.1)
        finally:
            link.close()
    late = [(stamp_s, now_s) for stamp_s, now_s in stamps if now_s > 2.0]
    assert late and all(stamp_s <= now_s - 1.5 + 0.001 for stamp_s, now_s in late)  # 1.5 s old at least
    emitted_s = [stamp_s + 1.5 for stamp_s, _ in late]  # emitted 4 times a second, from its start
    assert all(math.isclose(t * 4.0, round(t * 4.0), abs_tol=0.01) for t in emitted_s)
