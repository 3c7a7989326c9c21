"""A telemetry peer run as a separate process by the telemetry tests (not a test module).

It listens on ``tcp/127.0.0.1:<port>``, prints ``ready`` once its session is open, does its job,
prints ``done`` and then holds its session open (so its liveliness tokens and queryable stay up)
until its stdin closes or ``--hold-s`` passes.

Modes:
    stream: wait for a subscriber, then publish ``--rounds`` rounds of ``--uavs`` states (seq = round)
        at ``--rate-hz`` rounds per second, with a plan and a QoS every round.
    raw: wait for a subscriber, then put malformed payloads on our keys with a raw Zenoh publisher,
        followed by one valid state (seq 7) for UAV 0.
"""

from __future__ import annotations

import argparse
import select
import sys
import time

import zenoh

from bridge.geo import Home
from bridge.telemetry import SwarmPublisher
from bridge.telemetry.config import TelemetryConfig, open_session
from bridge.telemetry.keys import plan_key, qos_key, state_key
from bridge.telemetry.schema import ENCODING, Plan, PlanTarget, Qos, UavState

MALFORMED: tuple[tuple[str, bytes], ...] = (
    ("state", b"{not json"),
    ("state", b'{"schema": 99, "kind": "state"}'),
    ("state", b"[1, 2, 3]"),
    ("state_other_id", None),  # a valid state of UAV 5 on UAV 0's key
    ("plan", b'{"schema": 1, "kind": "plan", "stamp_s": 1.0, "seq": 0, "source": "sim"}'),
    (
        "qos",
        b'{"schema": 1, "kind": "qos", "stamp_s": 1.0, "seq": 0, "source": "alien", '
        b'"qos_s1": 0.5, "qos_s2": 0.4, "mean_throughput_mbps": 3.0, "n_users": 4}',
    ),
)


def make_state(uav_id: int, seq: int) -> UavState:
    return UavState(
        stamp_s=time.time(),
        seq=seq,
        source="sim",
        uav_id=uav_id,
        position_enu_m=(float(uav_id), float(seq), 30.0),
        velocity_enu_m_s=(1.0, 0.0, 0.0),
        target_enu_m=(50.0, 50.0, 30.0),
        battery_pct=90.0,
    )


def stream(config: TelemetryConfig, args: argparse.Namespace, pub: SwarmPublisher) -> None:
    for seq in range(args.rounds):
        for uav_id in range(args.uavs):
            pub.publish_state(make_state(uav_id, seq))
        targets = tuple(PlanTarget(uav_id, (50.0, 10.0 * uav_id, 30.0)) for uav_id in range(args.uavs))
        pub.publish_plan(Plan(stamp_s=time.time(), seq=seq, source="sim", targets=targets, planner="test"))
        pub.publish_qos(
            Qos(
                stamp_s=time.time(),
                seq=seq,
                source="sim",
                qos_s1=0.5,
                qos_s2=0.25,
                mean_throughput_mbps=12.0,
                n_users=100,
            )
        )
        if args.rate_hz > 0:
            time.sleep(1.0 / args.rate_hz)


def raw(config: TelemetryConfig) -> zenoh.Session:
    session = open_session(config)
    keys = {
        "state": state_key(config.swarm, 0),
        "state_other_id": state_key(config.swarm, 0),
        "plan": plan_key(config.swarm),
        "qos": qos_key(config.swarm),
    }
    publishers = {name: session.declare_publisher(key, encoding=ENCODING) for name, key in keys.items()}
    print("ready", flush=True)
    deadline = time.monotonic() + 10.0
    while not publishers["state"].matching_status.matching and time.monotonic() < deadline:
        time.sleep(0.01)
    for name, data in MALFORMED:
        publishers[name].put(data if data is not None else make_state(5, 0).to_json())
    publishers["state"].put(make_state(0, 7).to_json())
    return session


def hold(hold_s: float) -> None:
    print("done", flush=True)
    deadline = time.monotonic() + hold_s
    while time.monotonic() < deadline:
        readable, _, _ = select.select([sys.stdin], [], [], 0.1)
        if readable and not sys.stdin.readline():
            return


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("mode", choices=["stream", "raw"])
    parser.add_argument("--port", type=int, required=True)
    parser.add_argument("--swarm", default="test")
    parser.add_argument("--uavs", type=int, default=10)
    parser.add_argument("--rounds", type=int, default=20)
    parser.add_argument("--rate-hz", type=float, default=0.0)
    parser.add_argument("--no-wait", action="store_true", help="publish without waiting for a subscriber")
    parser.add_argument("--hold-s", type=float, default=30.0)
    parser.add_argument("--home", action="store_true", help="publish WGS84 positions around the default home")
    parser.add_argument("--retire", type=int, action="append", default=[], help="retire this UAV at the end")
    args = parser.parse_args()
    config = TelemetryConfig(swarm=args.swarm, listen=(f"tcp/127.0.0.1:{args.port}",))
    if args.mode == "raw":
        with raw(config):
            hold(args.hold_s)
        return
    with SwarmPublisher(config, home=Home() if args.home else None) as pub:
        print("ready", flush=True)
        if not args.no_wait and not pub.wait_for_subscriber(10.0):
            sys.exit("no subscriber within 10 s")
        stream(config, args, pub)
        for uav_id in args.retire:
            pub.retire(uav_id)
        hold(args.hold_s)


if __name__ == "__main__":
    main()
