"""The link's hot paths: packed messages, requests answered from the raw frame, a lent reader."""

import threading
import time
import types

from lossy_relay import free_udp_port

from bridge.link.frames import crc_function
from bridge.link.mavlink import MavlinkLink, use_mavlink2
from bridge.link.signing import SigningKey

mavutil = use_mavlink2()
m = mavutil.mavlink

ITEM = {
    "target_system": 3,
    "target_component": 1,
    "seq": 2,
    "frame": m.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
    "command": m.MAV_CMD_NAV_WAYPOINT,
    "current": 0,
    "autocontinue": 1,
    "param1": 0.0,
    "param2": 2.5,
    "param3": 0.0,
    "param4": float("nan"),
    "x": 473977418,
    "y": 85455938,
    "z": 20.0,
    "mission_type": 0,
}


def _captured(link: MavlinkLink) -> list[bytes]:
    sent: list[bytes] = []
    link._conn.write = sent.append
    return sent


def _reference(msg, seq: int) -> bytes:
    encoder = m.MAVLink(None, srcSystem=255, srcComponent=190)
    encoder.seq = seq
    return msg.pack(encoder)


def test_packed_messages_are_what_pymavlink_sends():
    with MavlinkLink(f"udpin:127.0.0.1:{free_udp_port()}") as link:
        sent = _captured(link)
        item = link.pack("mission_item_int", **ITEM)
        count = link.pack("mission_count", count=5, target_system=3, target_component=1, mission_type=0)
        seq0 = link._conn.mav.seq
        for packed in (item, count, item):  # the sequence number and CRC follow each send
            link.send_packed(packed)
        assert link._conn.mav.seq == (seq0 + 3) % 256
    assert sent[0] == _reference(m.MAVLink_mission_item_int_message(**ITEM), seq0)
    count_msg = m.MAVLink_mission_count_message(target_system=3, target_component=1, count=5, mission_type=0)
    assert sent[1] == _reference(count_msg, seq0 + 1)  # its trailing zeros cut as pymavlink does
    assert sent[2] == _reference(m.MAVLink_mission_item_int_message(**ITEM), seq0 + 2)


def test_packed_message_on_a_signing_link_is_signed_at_each_send():
    key = SigningKey(bytes(range(32)))
    with MavlinkLink(f"udpin:127.0.0.1:{free_udp_port()}", signing_key=key) as link:
        sent = _captured(link)
        packed = link.pack("mission_item_int", **ITEM)
        link.send_packed(packed)
        link.send_packed(packed)
    assert packed.body is None
    assert all(frame[2] & m.MAVLINK_IFLAG_SIGNED for frame in sent)
    assert sent[0][-13:] != sent[1][-13:]  # a new signature (timestamp) each time


def test_crc_with_and_without_the_native_function():
    data = bytes(range(60))
    pure_python = types.SimpleNamespace(mcrf4xx=None, x25crc=m._x25crc_slow)
    assert crc_function(m)(data) == crc_function(pure_python)(data) == m._x25crc_slow(data).crc


def _request_frame(seq: int, target_system: int = 255, mission_type: int = 0) -> bytes:
    vehicle = m.MAVLink(None, srcSystem=7, srcComponent=1)
    return m.MAVLink_mission_request_int_message(target_system, 190, seq, mission_type).pack(vehicle)


def test_item_requests_are_answered_from_checked_raw_frames_only():
    with MavlinkLink(f"udpin:127.0.0.1:{free_udp_port()}") as link:
        asked: list[int] = []
        with link.protocol_handler(7, lambda msg: None, asked.append):
            assert link._answer_request(_request_frame(4))
            assert link._answer_request(_request_frame(5, target_system=0))  # broadcast
            corrupted = bytearray(_request_frame(6))
            corrupted[10] ^= 0xFF
            assert not link._answer_request(bytes(corrupted))
            assert not link._answer_request(_request_frame(6, target_system=9))  # another ground station
            assert not link._answer_request(_request_frame(6, mission_type=1))  # a fence item
        assert not link._answer_request(_request_frame(6))  # no operation running
    assert asked == [4, 5]


def test_a_lent_reader_reads_on_the_borrowing_thread_only():
    port = free_udp_port()
    with MavlinkLink(f"udpin:127.0.0.1:{port}") as link:
        vehicle = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=7, source_component=1)
        readers: list[str] = []
        link.add_listener(lambda msg: readers.append(threading.current_thread().name))
        with link.reader.lend() as step:
            assert step is not None
            with link.reader.lend() as other:
                assert other is None  # one borrower at a time; the other one waits
            vehicle.mav.heartbeat_send(m.MAV_TYPE_QUADROTOR, m.MAV_AUTOPILOT_PX4, 0, 0, 0)
            deadline_s = time.monotonic() + 2.0
            while not readers and time.monotonic() < deadline_s:
                step(0.05)
        vehicle.mav.heartbeat_send(m.MAV_TYPE_QUADROTOR, m.MAV_AUTOPILOT_PX4, 0, 0, 0)
        link.wait_heartbeat(7, 2.0)
        time.sleep(0.1)
        vehicle.close()
    assert readers[0] == threading.current_thread().name
    assert readers[1:] and all(name != threading.current_thread().name for name in readers[1:])


def test_messages_no_one_reads_are_not_decoded():
    vehicle = m.MAVLink(None, srcSystem=7, srcComponent=1)
    attitude = m.MAVLink_attitude_message(0, 0.1, 0.2, 0.3, 0.0, 0.0, 0.0).pack(vehicle)
    position = m.MAVLink_global_position_int_message(0, 1, 2, 3, 4, 0, 0, 0, 0).pack(vehicle)
    heartbeat = m.MAVLink_heartbeat_message(m.MAV_TYPE_QUADROTOR, 12, 0, 0, 0, 3).pack(vehicle)
    with MavlinkLink(f"udpin:127.0.0.1:{free_udp_port()}") as link:
        assert link._wanted(heartbeat, False)  # ours: discovery
        assert not link._wanted(attitude, False) and not link._wanted(position, False)
        assert link._wanted(_request_frame(1), False) and not link._wanted(_request_frame(1), True)
        link.add_listener(lambda msg: None, {"GLOBAL_POSITION_INT"})
        assert link._wanted(position, False) and not link._wanted(attitude, False)
        assert link._wanted(attitude + position, False)  # two frames: the parser decides
        link.add_listener(lambda msg: None)  # every message
        assert link._wanted(attitude, False)
