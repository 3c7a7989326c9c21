"""The parameter protocol against a vehicle that answers late: real MAVLink on loopback."""

from __future__ import annotations

import threading

import pytest
from lossy_relay import free_udp_port

from bridge.config import ProtocolConfig
from bridge.flight.params import ParamError, set_param
from bridge.link.mavlink import MavlinkLink
from bridge.simulated.peer import endpoint_pair, m, mavutil

PROTOCOL = ProtocolConfig(handshake_timeout_s=0.5, item_timeout_s=0.2, max_retries=2)


def _vehicle(url: str, answers: list[float], stop: threading.Event) -> threading.Thread:
    """A vehicle (system 10) that answers each PARAM_SET with the PARAM_VALUEs ``answers``, in order."""
    conn = mavutil.mavlink_connection(url, source_system=10, source_component=1)

    def run() -> None:
        while not stop.is_set():
            conn.mav.heartbeat_send(m.MAV_TYPE_QUADROTOR, m.MAV_AUTOPILOT_PX4, 0, 0, m.MAV_STATE_ACTIVE)
            msg = conn.recv_match(type="PARAM_SET", blocking=True, timeout=0.1)
            if msg is not None:
                for value in answers:
                    conn.mav.param_value_send(msg.param_id.encode(), value, m.MAV_PARAM_TYPE_REAL32, 1, 0)
        conn.close()

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread


@pytest.mark.parametrize(("answers", "refused"), [
    ([45.0, 0.0], False),  # an earlier read's late answer (45) first, then the answer to the set
    ([45.0], True)])  # the vehicle keeps 45: refused, naming the value it holds
def test_a_late_answer_with_the_old_value_is_not_taken_for_a_refusal(answers, refused):
    vehicle_url, gcs_url = endpoint_pair("udpin", free_udp_port())
    stop = threading.Event()
    link = MavlinkLink(gcs_url)
    thread = _vehicle(vehicle_url, answers, stop)
    try:
        if refused:
            with pytest.raises(ParamError, match="set to 0, the vehicle holds 45"):
                set_param(link, 10, "RTL_CONE_ANG", 0.0, m.MAV_PARAM_TYPE_REAL32, bytewise=False,
                          protocol=PROTOCOL)
        else:
            held = set_param(link, 10, "RTL_CONE_ANG", 0.0, m.MAV_PARAM_TYPE_REAL32, bytewise=False,
                             protocol=PROTOCOL)
            assert held.value == 0.0
    finally:
        stop.set()
        thread.join(timeout=2.0)
        link.close()
