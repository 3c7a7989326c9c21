"""Mission uploads to one or many vehicles at once, driven by the vehicles' requests.

Each request is answered on the link's reader thread the moment it arrives (no hand-off
to another thread); the calling thread only watches the clock for all uploads at once:
it re-sends MISSION_COUNT (handshake, ``handshake_timeout_s``) or the last item (whose
MISSION_ACK may be lost, ``item_timeout_s``) when a wait runs out, and gives up after
``max_retries`` with :class:`~bridge.errors.MissionTimeoutError`.

The vehicle owns the item retries (it requests an item again when it does not arrive),
so other items are sent once per request: re-sending them would only duplicate them,
and a vehicle that restarts its own timer on every message (MAVSDK does) would then
never re-request the item it is missing. ``MAV_MISSION_INVALID_SEQUENCE`` during the
transfer, which vehicles (ArduPilot among them) send for a duplicated item while the
transfer goes on, is raised only if the vehicle then stops answering; every other
error acknowledgement raises its named exception at once, except during the handshake:

Every item is sent as MISSION_ITEM_INT (degE7 positions, exact), whether the vehicle
asks with MISSION_REQUEST_INT or with the legacy MISSION_REQUEST (as ArduPilot does):
MAVLink deprecated the float MISSION_ITEM, and QGroundControl answers the same way.

A vehicle that answers MISSION_COUNT with ``MAV_MISSION_NO_SPACE`` (ArduPilot does
for a few seconds after boot, saying "Only 0 items are supported") or
``MAV_MISSION_DENIED`` (busy with another transfer; MAVLink has no BUSY code) is
asked again with back-off (0.25 s, doubling, at most 2 s) for up to
``busy_retry_s``; a NO_SPACE whose STATUSTEXT gives a real capacity (more than 0
items) is final at once. Errors carry the STATUSTEXT the vehicle sent during the transfer.
"""

from __future__ import annotations

import contextlib
import logging
import re
import threading
import time
from collections.abc import Callable, Mapping, Sequence

from bridge.config import ProtocolConfig
from bridge.errors import BridgeError, MissionResultError, MissionTimeoutError, mission_result_error
from bridge.mavlink import MavlinkLink
from bridge.mission import MissionItem

__all__ = ["upload_concurrently", "is_mission_message", "vehicle_says"]

log = logging.getLogger(__name__)

_MISSION = 0  # MAV_MISSION_TYPE_MISSION
_BACKOFF_FIRST_S = 0.25
_BACKOFF_MAX_S = 2.0
_CAPACITY = re.compile(r"Only (\d+) items are supported")


def vehicle_says(texts: Sequence[str]) -> str:
    """``vehicle says: "..."; "..."`` for an error message, or ``""`` when there is nothing."""
    return "vehicle says: " + "; ".join(f'"{t}"' for t in dict.fromkeys(texts)) if texts else ""


def is_mission_message(msg: object) -> bool:
    """True unless the message belongs to another mission type (fence, rally points)."""
    return getattr(msg, "mission_type", _MISSION) == _MISSION


class _Upload:
    """One upload attempt to one vehicle."""

    def __init__(
        self,
        link: MavlinkLink,
        system_id: int,
        component_id: int,
        protocol: ProtocolConfig,
        items: Sequence[MissionItem],
        wake: threading.Event,
    ) -> None:
        self.link, self.system_id, self.protocol, self.wake = link, system_id, protocol, wake
        self.targets = {"target_system": system_id, "target_component": component_id}
        self.fields = [{**item.message_fields(), **self.targets} for item in items]
        self.lock = threading.Lock()
        self.done = False
        self.error: MissionResultError | None = None
        self.deferred: MissionResultError | None = None
        self.started_s = time.monotonic()
        self.busy_since_s: float | None = None
        self.backoff_s = _BACKOFF_FIRST_S
        self.sent_last = not self.fields
        self.stage, self.seq, self.tries = "MISSION_REQUEST", None, 0
        self.timeout_s = protocol.handshake_timeout_s
        self.deadline_s = time.monotonic() + self.timeout_s
        self.resend: Callable[[], None] = self._send_count

    def _send_count(self) -> None:
        count = len(self.fields)
        self.link.send(lambda mav: mav.mission_count_send(count=count, mission_type=_MISSION, **self.targets))

    def _send_item(self, fields: dict[str, float | int]) -> None:
        self.link.send(lambda mav: mav.mission_item_int_send(**fields))

    def _transient(self, result: int) -> bool:
        """True when a refusal of MISSION_COUNT is worth asking again (booting or busy vehicle)."""
        m = self.link.mavlink
        if self.seq is not None or result not in (m.MAV_MISSION_NO_SPACE, m.MAV_MISSION_DENIED):
            return False
        if result == m.MAV_MISSION_NO_SPACE:
            said = self.link.status_texts(self.system_id, self.started_s)
            capacities = [int(found.group(1)) for text in said if (found := _CAPACITY.search(text))]
            if capacities and capacities[-1] > 0:  # a real capacity, too small for this mission
                return False
        now_s = time.monotonic()
        self.busy_since_s = now_s if self.busy_since_s is None else self.busy_since_s
        return now_s - self.busy_since_s < self.protocol.busy_retry_s

    def start(self) -> None:
        """Send MISSION_COUNT."""
        with self.lock:
            self.deadline_s = time.monotonic() + self.timeout_s
            self._send_count()

    def on_message(self, msg: object) -> None:
        """Answer a request at once; note acknowledgements (reader thread)."""
        m = self.link.mavlink
        kind = msg.get_type()
        with self.lock:
            if self.done or not is_mission_message(msg):
                return
            if kind in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
                if not 0 <= msg.seq < len(self.fields):
                    return
                last = msg.seq == len(self.fields) - 1
                fields = self.fields[msg.seq]
                self._send_item(fields)
                self.stage = "MISSION_ACK" if last else "MISSION_REQUEST"
                self.seq, self.tries, self.deferred = msg.seq, 0, None
                self.timeout_s = self.protocol.item_timeout_s
                self.deadline_s = time.monotonic() + self.timeout_s
                self.resend = (lambda: self._send_item(fields)) if last else (lambda: None)
                self.sent_last = self.sent_last or last
            elif kind == "MISSION_ACK":
                if msg.type == m.MAV_MISSION_ACCEPTED:
                    self.done = self.sent_last
                elif msg.type == m.MAV_MISSION_INVALID_SEQUENCE and self.seq is not None:
                    self.deferred = mission_result_error(msg.type, self.system_id, self.seq)
                elif self._transient(msg.type):
                    log.debug("vehicle %d: MISSION_COUNT refused (%d), asking again in %.2f s",
                              self.system_id, msg.type, self.backoff_s)
                    self.tries, self.resend = 0, self._send_count
                    self.deadline_s = time.monotonic() + self.backoff_s
                    self.backoff_s = min(2 * self.backoff_s, _BACKOFF_MAX_S)
                else:
                    self.error = mission_result_error(msg.type, self.system_id, self.seq)
                    if self.busy_since_s is not None:
                        waited_s = time.monotonic() - self.busy_since_s
                        self.error.add_detail(f"still refused after asking again for {waited_s:.1f} s "
                                              f"(busy_retry_s = {self.protocol.busy_retry_s})")
                    self.done = True
            if self.done:
                self.wake.set()

    def poll(self) -> bool:
        """True once accepted; re-sends when a wait ran out; raises the refusal or the timeout."""
        with self.lock:
            if self.done:
                if self.error is not None:
                    raise self.error
                return True
            if time.monotonic() < self.deadline_s:
                return False
            self.tries += 1
            if self.tries > self.protocol.max_retries:
                if self.deferred is not None:
                    raise self.deferred
                raise MissionTimeoutError(self.system_id, self.seq, self.stage, self.timeout_s * self.tries)
            log.debug("vehicle %d: no %s, retry %d", self.system_id, self.stage, self.tries)
            self.deadline_s = time.monotonic() + self.timeout_s
            self.resend()
            return False


def upload_concurrently(
    links: Mapping[int, MavlinkLink],
    items: Mapping[int, Sequence[MissionItem]],
    protocol: ProtocolConfig,
    attempts: int | None = None,
    component_id: int = 1,
) -> tuple[dict[int, float], dict[int, BridgeError]]:
    """Upload a mission to each vehicle, all at once, from the calling thread.

    A transfer that breaks off after the handshake (the vehicle answered, then fell silent
    through every retry) is started again from the beginning, up to ``attempts`` (default
    ``protocol.transfer_attempts``) in all; a vehicle that never answers is not.

    Args:
        links: The link reaching each vehicle, by system id.
        items: The mission items of each vehicle, by system id.
        protocol: Timeouts and retries.
        attempts: Whole-transfer attempts per vehicle.
        component_id: The vehicles' autopilot component.

    Returns:
        ``(seconds, errors)``: each successful vehicle's upload time, and each failed
        vehicle's named exception (:class:`MissionResultError` or :class:`MissionTimeoutError`).
    """
    attempts = protocol.transfer_attempts if attempts is None else attempts
    wake = threading.Event()
    start_s = time.monotonic()
    uploads = {sid: _Upload(links[sid], sid, component_id, protocol, items[sid], wake) for sid in items}
    tries = dict.fromkeys(uploads, 1)
    seconds: dict[int, float] = {}
    errors: dict[int, BridgeError] = {}
    with contextlib.ExitStack() as stack:
        for sid in uploads:
            handler = lambda msg, sid=sid: uploads[sid].on_message(msg)  # noqa: E731 - follows restarts
            stack.enter_context(links[sid].protocol_handler(sid, handler))
        for upload in uploads.values():
            upload.start()
        pending = set(uploads)
        while pending:
            wake.clear()
            for sid in sorted(pending):
                try:
                    if uploads[sid].poll():
                        seconds[sid] = time.monotonic() - start_s
                        pending.discard(sid)
                except MissionTimeoutError as exc:
                    if exc.seq is None or tries[sid] >= attempts:
                        errors[sid] = exc
                        pending.discard(sid)
                        continue
                    tries[sid] += 1
                    log.warning("%s; transfer attempt %d", exc, tries[sid])
                    uploads[sid] = _Upload(links[sid], sid, component_id, protocol, items[sid], wake)
                    uploads[sid].start()
                except MissionResultError as exc:
                    errors[sid] = exc
                    pending.discard(sid)
            if pending:
                next_deadline_s = min(uploads[sid].deadline_s for sid in pending)
                wake.wait(max(0.0, next_deadline_s - time.monotonic()))
    for sid, exc in errors.items():
        exc.add_detail(vehicle_says(links[sid].status_texts(sid, start_s)))
    for sid, elapsed_s in seconds.items():
        log.info("vehicle %d: uploaded %d items in %.4f s", sid, len(items[sid]), elapsed_s)
    return seconds, errors
