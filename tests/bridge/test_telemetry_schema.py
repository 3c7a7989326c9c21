"""Telemetry payloads, keys and session config: round-trips and validation, no network."""

from __future__ import annotations

import json

import numpy as np
import pytest
import zenoh

from bridge.link.vehicle_state import VehicleState
from bridge.telemetry.config import TelemetryConfig, zenoh_config
from bridge.telemetry.keys import (
    alive_key,
    all_alive_key,
    payload_kind,
    plan_key,
    qos_key,
    state_key,
    swarm_root,
    uav_id_from_key,
)
from bridge.telemetry.schema import (
    SCHEMA_VERSION,
    GeoPoint,
    Plan,
    PlanTarget,
    Qos,
    TelemetryFormatError,
    UavState,
    parse_payload,
    state_from_vehicle,
)
from typed_config import ConfigError

FULL_STATE = UavState(
    stamp_s=1_764_000_000.25,
    seq=42,
    source="vehicle",
    uav_id=3,
    position_enu_m=(12.5, -4.0, 30.0),
    velocity_enu_m_s=(1.5, 0.0, -0.25),
    position_wgs84=GeoPoint(47.39, 8.54, 518.0),
    target_enu_m=(20.0, 40.0, 30.0),
    battery_pct=87.5,
    mission_item=2,
    mission_items_total=5,
    separation_held=True,
    nearest_uav_m=6.25,
)
MINIMAL_STATE = UavState(
    stamp_s=0.0, seq=0, source="sim", uav_id=0, position_enu_m=(0, 0, 0), velocity_enu_m_s=(0, 0, 0)
)
PLAN = Plan(
    stamp_s=10.0,
    seq=7,
    source="sim",
    planner="cnn-peaks-hungarian",
    latency_ms=12.5,
    targets=(PlanTarget(0, (1.0, 2.0, 30.0)), PlanTarget(4, (5.0, 6.0, 30.0))),
)
QOS = Qos(stamp_s=10.0, seq=7, source="sim", qos_s1=0.8, qos_s2=0.6, mean_throughput_mbps=12.25, n_users=150)


@pytest.mark.parametrize(
    ("payload", "key"),
    [
        (FULL_STATE, state_key("s", 3)),
        (MINIMAL_STATE, state_key("s", 0)),
        (PLAN, plan_key("s")),
        (QOS, qos_key("s")),
    ],
    ids=["full-state", "minimal-state", "plan", "qos"],
)
def test_json_round_trip_is_lossless(payload, key):
    data = payload.to_json()
    obj = json.loads(data)
    assert obj["schema"] == SCHEMA_VERSION and obj["kind"] == type(payload).kind
    parsed = parse_payload(key, data)
    assert parsed == payload and type(parsed) is type(payload)
    assert payload.key("s") == key


def test_reader_ignores_unknown_fields_and_plan_targets_by_uav():
    obj = json.loads(PLAN.to_json()) | {"added_in_a_later_version": [1, 2]}
    parsed = parse_payload(plan_key("s"), json.dumps(obj).encode())
    assert parsed.targets_by_uav() == {0: (1.0, 2.0, 30.0), 4: (5.0, 6.0, 30.0)}


def _with(payload, **changes) -> bytes:
    return json.dumps(json.loads(payload.to_json()) | changes).encode()


@pytest.mark.parametrize(
    ("key", "data", "reason"),
    [
        (state_key("s", 3), b"{not json", "not JSON"),
        (state_key("s", 3), b"\xff\xfe", "not JSON"),
        (state_key("s", 3), b"[1, 2]", "JSON object"),
        (state_key("s", 3), _with(FULL_STATE, schema=2), "schema = 2"),
        (state_key("s", 3), _with(PLAN), "kind = 'plan'"),
        (state_key("s", 4), FULL_STATE.to_json(), "does not match the key"),
        (state_key("s", 3), _with(FULL_STATE, source="replay"), "source"),
        (state_key("s", 3), _with(FULL_STATE, seq=-1), "seq"),
        (state_key("s", 3), _with(FULL_STATE, position_enu_m=[1, 2]), "position_enu_m"),
        (state_key("s", 3), _with(FULL_STATE, velocity_enu_m_s=[1, "a", 2]), "velocity_enu_m_s"),
        (state_key("s", 3), _with(FULL_STATE, battery_pct=120), "battery_pct"),
        (
            state_key("s", 3),
            _with(FULL_STATE, position_wgs84={"lat_deg": 91, "lon_deg": 0, "alt_m": 0}),
            r"<= 90.0 - at `\$.position_wgs84.lat_deg`",
        ),
        (state_key("s", 3), _with(FULL_STATE, position_wgs84={"lat": 1}), "position_wgs84"),
        (
            state_key("s", 3),
            b'{"schema": 1, "kind": "state", "stamp_s": 1, "seq": 0, "source": "sim"}',
            "missing",
        ),
        (plan_key("s"), _with(PLAN, targets=[{"uav_id": 0, "target_enu_m": [1, 2, 3]}] * 2), "repeated"),
        (plan_key("s"), _with(PLAN, targets=[{"uav_id": 0}]), "target"),
        (qos_key("s"), _with(QOS, qos_s1=1.5), "qos_s1"),
        (qos_key("s"), _with(QOS, n_users=True), "n_users"),
        ("uav_swarm/s/uav/3/alive", FULL_STATE.to_json(), "not a telemetry payload key"),
        ("elsewhere/plan", PLAN.to_json(), "not a telemetry payload key"),
    ],
)
def test_malformed_payloads_raise_a_named_error(key, data, reason):
    with pytest.raises(TelemetryFormatError, match=reason):
        parse_payload(key, data)


@pytest.mark.parametrize(
    ("changes", "where"),
    [
        ({"stamp_s": float("nan")}, "stamp_s"),
        ({"position_enu_m": (0.0, float("inf"), 0.0)}, "position_enu_m"),
        ({"position_enu_m": (1.0, 2.0)}, "position_enu_m"),
        ({"battery_pct": -1.0}, "battery_pct"),
        ({"nearest_uav_m": -0.5}, "nearest_uav_m"),
        ({"source": "replay"}, "source"),
    ],
)
def test_invalid_payloads_are_refused_when_encoded(changes, where):
    fields = {"stamp_s": 0.0, "seq": 0, "source": "sim", "uav_id": 0, "position_enu_m": (0.0, 0.0, 0.0),
              "velocity_enu_m_s": (0.0, 0.0, 0.0)} | changes
    with pytest.raises(TelemetryFormatError, match=where):
        UavState(**fields).to_json()


def test_numpy_values_are_encoded_as_numbers():
    state = UavState(stamp_s=np.float64(1.5), seq=0, source="sim", uav_id=0,
                     position_enu_m=np.array([1.0, 2.0, 3.0]), velocity_enu_m_s=(np.float32(0.5), 0.0, 0.0))
    parsed = parse_payload(state_key("s", 0), state.to_json())
    assert parsed.position_enu_m == (1.0, 2.0, 3.0) and parsed.velocity_enu_m_s == (0.5, 0.0, 0.0)


def test_keys_are_canonical_and_parse_back():
    assert state_key("s", 3) == "uav_swarm/s/uav/3/state"
    assert alive_key("s", 3) == "uav_swarm/s/uav/3/alive"
    assert zenoh.KeyExpr(swarm_root("s")).includes(state_key("s", 9))
    assert zenoh.KeyExpr(all_alive_key("s")).includes(alive_key("s", 9))
    assert [payload_kind(k) for k in (state_key("s", 1), plan_key("s"), qos_key("s"), alive_key("s", 1))] == [
        "state",
        "plan",
        "qos",
        None,
    ]
    assert uav_id_from_key(alive_key("s", 12)) == 12 and uav_id_from_key(plan_key("s")) is None


@pytest.mark.parametrize("swarm", ["", "a/b", "*", "**", "$x", "a b", "é"])
def test_invalid_swarm_names_are_rejected(swarm):
    with pytest.raises(ValueError, match="swarm name"):
        state_key(swarm, 0)
    with pytest.raises(ConfigError, match="TelemetryConfig.swarm"):
        TelemetryConfig(swarm=swarm)


@pytest.mark.parametrize("uav_id", [-1, 1.0, True, "3"])
def test_invalid_uav_ids_are_rejected(uav_id):
    with pytest.raises(ValueError, match="uav_id"):
        state_key("s", uav_id)


def test_default_config_is_loopback_only():
    config = zenoh_config(TelemetryConfig())
    assert json.loads(config.get_json("mode")) == "peer"
    assert json.loads(config.get_json("scouting/multicast/enabled")) is False
    assert json.loads(config.get_json("listen/endpoints")) == ["tcp/127.0.0.1:7447"]
    assert json.loads(config.get_json("connect/endpoints")) == []
    assert json.loads(config.get_json("connect/timeout_ms")) == 2000
    assert json.loads(config.get_json("queries_default_timeout")) == 2000


def test_client_config_and_scouting_switch():
    config = TelemetryConfig(
        mode="client", listen=(), connect=("tcp/127.0.0.1:7448",), multicast_scouting=True
    )
    zconf = zenoh_config(config)
    assert json.loads(zconf.get_json("mode")) == "client"
    assert json.loads(zconf.get_json("scouting/multicast/enabled")) is True
    assert json.loads(zconf.get_json("connect/exit_on_failure")) is True


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"listen": ("http/127.0.0.1:80",)}, r"listen\[0\] = 'http/127.0.0.1:80': must start with one of"),
        ({"listen": ("127.0.0.1:7447",)}, r"listen\[0\].*must start with one of"),
        ({"connect": ("tcp/127.0.0.1",)}, r"connect\[0\].*<host>:<port>"),
        ({"connect": ("tcp/127.0.0.1:70000",)}, r"0 <= port <= 65535"),
        ({"connect": ("tcp/",)}, "address after tcp/ is empty"),
        ({"listen": "tcp/127.0.0.1:7447"}, "must be a list"),
        ({"mode": "router"}, "choose one of"),
        ({"mode": "client", "listen": ()}, "client mode needs a router endpoint"),
        ({"mode": "client", "connect": ("tcp/127.0.0.1:7447",)}, "a client does not listen"),
        ({"listen": (), "connect": ()}, "could reach nobody"),
        ({"timeout_s": 0.0}, r"0.0 < timeout_s <= 60.0"),
        ({"scouting": True}, "unknown key"),
    ],
    ids=[
        "scheme",
        "no-scheme",
        "no-port",
        "port-range",
        "empty-address",
        "not-a-list",
        "mode",
        "client-no-connect",
        "client-listens",
        "isolated",
        "timeout",
        "unknown-key",
    ],
)
def test_config_validation_names_the_field(fields, message):
    with pytest.raises(ConfigError, match=message):
        TelemetryConfig.from_dict(fields)


def test_config_accepts_other_locators():
    config = TelemetryConfig.from_dict(
        {
            "listen": ["tcp/[::1]:7447", "unixsock-stream//tmp/zenoh.sock"],
            "connect": ["quic/localhost:7447#iface=lo"],
        }
    )
    assert config.to_dict()["connect"] == ["quic/localhost:7447#iface=lo"]


def test_state_from_vehicle_carries_position_velocity_battery_and_mission():
    vehicle = VehicleState(system_id=2, lat_deg=47.4, lon_deg=8.55, alt_m=518.0, x_m=10.0, y_m=-5.0, z_m=30.0,
                           vx_m_s=1.0, vy_m_s=2.0, vz_m_s=-0.5, battery_remaining_pct=76.0,
                           mission_seq_current=3, mission_total=6, position_time_s=1234.5)
    state = state_from_vehicle(vehicle, seq=9, target_enu_m=(20.0, 0.0, 30.0))
    assert state == UavState(
        stamp_s=1234.5, seq=9, source="vehicle", uav_id=2, position_enu_m=(10.0, -5.0, 30.0),
        velocity_enu_m_s=(1.0, 2.0, -0.5), position_wgs84=GeoPoint(47.4, 8.55, 518.0),
        target_enu_m=(20.0, 0.0, 30.0), battery_pct=76.0, mission_item=3, mission_items_total=6)
    assert parse_payload(state_key("s", 2), state.to_json()) == state
    assert state_from_vehicle(vehicle, seq=0, uav_id=0).uav_id == 0


def test_state_from_vehicle_waits_for_a_position():
    assert state_from_vehicle(VehicleState(system_id=1, battery_remaining_pct=90.0), seq=0) is None


def test_a_state_without_a_fix_carries_no_position():
    no_fix = UavState(stamp_s=1.0, seq=0, source="vehicle", uav_id=2, fix=False, position_enu_m=None,
                      velocity_enu_m_s=None)
    data = no_fix.to_json()
    obj = json.loads(data)
    assert obj["fix"] is False
    assert obj["position_enu_m"] is obj["velocity_enu_m_s"] is obj["position_wgs84"] is None
    assert parse_payload(state_key("s", 2), data) == no_fix
    placeholder = data.replace(b'"position_enu_m":null', b'"position_enu_m":[0.0,0.0,0.0]')
    with pytest.raises(TelemetryFormatError, match="fix = false"):
        parse_payload(state_key("s", 2), placeholder)
    with pytest.raises(ValueError, match="fix = true needs position_enu_m"):
        UavState(stamp_s=1.0, seq=0, source="vehicle", uav_id=2, position_enu_m=None, velocity_enu_m_s=None)


def test_a_vehicle_without_a_fix_is_published_as_no_fix():
    seen = VehicleState(system_id=3, position_time_s=5.0, relative_alt_m=0.0, fix_type=1)  # its 0, 0 dropped
    state = state_from_vehicle(seen, 4, uav_id=2)
    assert state is not None and state.fix is False and state.position_enu_m is None
    assert state_from_vehicle(VehicleState(system_id=3), 0) is None  # no GLOBAL_POSITION_INT yet
    fixed = VehicleState(system_id=3, position_time_s=5.0, lat_deg=47.0, lon_deg=8.0, alt_m=500.0, x_m=1.0,
                         y_m=2.0, z_m=3.0, vx_m_s=0.0, vy_m_s=0.0, vz_m_s=0.0)
    assert state_from_vehicle(fixed, 0).fix is True
