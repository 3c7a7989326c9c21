"""The ROS 2 swarm markers under the 802.11 radio: each UAV's channel and whom it serves, as recorded.

Built by the node's own functions from telemetry states (no node, no peer: the messages themselves).
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("visualization_msgs")  # the ros2 extra

from bridge.telemetry.schema import UavState  # noqa: E402
from uav_swarm.runs.outputs.radio_report import service_rgb, uav_service  # noqa: E402
from uav_swarm.runs.outputs.ros2.messages import stamp, swarm_markers  # noqa: E402

USERS = np.array([[10.0, 10.0], [12.0, 9.0], [50.0, 40.0], [90.0, 90.0]])
COVERED = np.array([True, True, True, False])
ASSOCIATION = np.array([3, 3, 0, -1])  # UAV ids (not rows): a fleet whose ids are 0 and 3


def _state(uav_id: int, x_m: float, channel: int | None) -> UavState:
    return UavState(stamp_s=0.0, seq=1, source="vehicle", uav_id=uav_id, position_enu_m=(x_m, 20.0, 10.0),
                    velocity_enu_m_s=(0.0, 0.0, 0.0), wifi_channel=channel)


def _by_ns(markers) -> dict[str, list]:
    found: dict[str, list] = {}
    for marker in markers.markers[1:]:
        found.setdefault(marker.ns, []).append(marker)
    return found


def test_under_802_11_each_uav_has_its_colour_its_channel_and_a_line_to_each_user_it_serves():
    states = [_state(0, 40.0, 36), _state(3, 15.0, 149)]
    service = uav_service(states, USERS, COVERED, ASSOCIATION)
    uavs = {s.uav_id: s.position_enu_m for s in states}
    markers = swarm_markers(stamp(1.5), uavs, 30.0, 5.0, service)
    assert markers.markers[0].action == markers.markers[0].DELETEALL
    by_ns = _by_ns(markers)
    assert "coverage" not in by_ns  # 802.11 has no coverage disc
    assert [m.text for m in by_ns["channels"]] == ["UAV 0, ch 36, 1 users", "UAV 3, ch 149, 2 users"]
    assert [m.id for m in by_ns["uavs"]] == [0, 3]
    for sphere in by_ns["uavs"]:
        assert (sphere.color.r, sphere.color.g, sphere.color.b) == pytest.approx(service_rgb(sphere.id))
    lines = {m.id: [(p.x, p.y, p.z) for p in m.points] for m in by_ns["service"]}
    assert lines == {0: [(40.0, 20.0, 10.0), (50.0, 40.0, 0.0)],
                     3: [(15.0, 20.0, 10.0), (10.0, 10.0, 0.0), (15.0, 20.0, 10.0), (12.0, 9.0, 0.0)]}
    assert len(by_ns["separation"]) == 2


def test_under_the_paper_radio_the_markers_keep_their_coverage_discs():
    states = [_state(0, 40.0, None), _state(1, 15.0, None)]
    assert uav_service(states, USERS, COVERED, np.array([1, 1, 0, -1])) is None
    markers = swarm_markers(stamp(1.5), {s.uav_id: s.position_enu_m for s in states}, 30.0, 5.0, None)
    by_ns = _by_ns(markers)
    assert sorted(by_ns) == ["coverage", "separation", "uavs"]
    assert [m.scale.x for m in by_ns["coverage"]] == [60.0, 60.0]
