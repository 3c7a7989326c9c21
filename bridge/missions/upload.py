"""Mission uploads to one or many vehicles at once, driven by the vehicles' requests.

The calling thread reads the links itself while it waits (it borrows the links' reader,
:meth:`~bridge.link.reader.LinkReader.lend`; when another caller holds it, that one reads and
this one waits): each request is answered the moment it arrives, from the raw frame (see
:meth:`~bridge.link.mavlink.MavlinkLink.protocol_handler`), with items packed once (while the
vehicle answers MISSION_COUNT), and no message crosses a thread. Between messages it
watches the clock for all uploads at once: it re-sends MISSION_COUNT (handshake,
``handshake_timeout_s``) or the last item (whose MISSION_ACK may be lost,
``item_timeout_s``) when a wait runs out, and gives up after ``max_retries`` with
:class:`~bridge.errors.MissionTimeoutError`.

The vehicle drives the transfer and owns the item retries (it requests an item again when
it does not arrive), so MISSION_COUNT is re-sent only while no request came, and other
items are sent once per request: re-sending them would only duplicate them, and a vehicle
that restarts its own timer on every message (MAVSDK does) would then never re-request
the item it is missing. A transfer that breaks off after the handshake (the vehicle fell
silent through every retry) is started again with a new MISSION_COUNT, up to ``attempts``
transfers in all, while a late request of the last transfer is still answered.

Once the vehicle has asked for an item, ``MAV_MISSION_INVALID_SEQUENCE`` (ArduPilot's
answer to a duplicated item) and the "busy" answers to a duplicated MISSION_COUNT
(``MAV_MISSION_ERROR`` from PX4, ``MAV_MISSION_DENIED``) do not stop the transfer that
goes on: they are raised only if the vehicle then stops answering through every retry of the last
transfer attempt (before that, a new attempt starts). Every other error
acknowledgement raises its named exception at once, except during the handshake:

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

import collections
import contextlib
import logging
import re
import threading
import time
from collections.abc import Callable, Mapping, Sequence

from bridge.config import ProtocolConfig
from bridge.errors import BridgeError, MissionResultError, MissionTimeoutError, mission_result_error
from bridge.link.frames import MavMessage, PackedMessage
from bridge.link.mavlink import MavlinkLink
from bridge.missions.items import MissionItem

__all__ = ["upload_concurrently", "is_mission_message", "vehicle_says"]

log = logging.getLogger(__name__)

_MISSION = 0  # MAV_MISSION_TYPE_MISSION
_BACKOFF_FIRST_S = 0.25
_BACKOFF_MAX_S = 2.0
_CAPACITY = re.compile(r"Only (\d+) items are supported")


def vehicle_says(texts: Sequence[str]) -> str:
    """``vehicle says: "..."; "..."`` for an error message, or ``""`` when there is nothing."""
    return "vehicle says: " + "; ".join(f'"{t}"' for t in dict.fromkeys(texts)) if texts else ""


def is_mission_message(msg: MavMessage) -> bool:
    """True unless the message belongs to another mission type (fence, rally points)."""
    return getattr(msg, "mission_type", _MISSION) == _MISSION


class _Upload:
    """The upload of one mission to one vehicle, over all its transfer attempts.

    Every message is packed once (:meth:`~bridge.link.mavlink.MavlinkLink.pack`); a request is
    answered by sending the packed item with a fresh sequence number.
    """

    def __init__(
        self,
        link: MavlinkLink,
        system_id: int,
        component_id: int,
        protocol: ProtocolConfig,
        items: Sequence[MissionItem],
        finished: Callable[[int], None],
        attempts: int,
    ) -> None:
        self.link, self.system_id, self.protocol, self.finished = link, system_id, protocol, finished
        self.attempts, self.attempt = attempts, 1
        self.targets = {"target_system": system_id, "target_component": component_id}
        self.count = link.pack("mission_count", count=len(items), mission_type=_MISSION, **self.targets)
        self.mission = items
        self.items: list[PackedMessage] = []
        self.requested = False  # the vehicle has asked for an item, in this attempt or an earlier one
        self.lock = threading.Lock()
        self.done = False
        self.error: MissionResultError | None = None
        self.deferred: MissionResultError | None = None
        self.started_s = time.monotonic()
        self.busy_since_s: float | None = None
        self.backoff_s = _BACKOFF_FIRST_S
        self.sent_last = not items
        self.stage, self.tries = "MISSION_REQUEST", 0
        self.seq: int | None = None
        self.timeout_s = protocol.handshake_timeout_s
        self.deadline_s = time.monotonic() + self.timeout_s
        self.resend: Callable[[], None] = self._send_count

    def _send_count(self) -> None:
        self.link.send_packed(self.count)

    def _busy_answer(self, result: int) -> bool:
        """True for the codes vehicles use to refuse a MISSION_COUNT while they are busy.

        PX4 answers a MISSION_COUNT that arrives during its transfer with MAV_MISSION_ERROR
        ("Busy") and goes on; ArduPilot answers MAV_MISSION_DENIED while another transfer runs.
        """
        m = self.link.mavlink
        return result in (m.MAV_MISSION_ERROR, m.MAV_MISSION_DENIED)

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
        """Send MISSION_COUNT; again for a new attempt (requests of the last one are still answered).

        The items are packed while the vehicle answers the first MISSION_COUNT.
        """
        with self.lock:
            self.stage, self.seq, self.tries = "MISSION_REQUEST", None, 0
            self.timeout_s = self.protocol.handshake_timeout_s
            self.deadline_s = time.monotonic() + self.timeout_s
            self.resend = self._send_count
            self._send_count()
            if len(self.items) < len(self.mission):
                fields = [{**item.message_fields(), **self.targets} for item in self.mission]
                self.items = [self.link.pack("mission_item_int", **f) for f in fields]

    def on_request(self, seq: int) -> None:
        """Answer a request for item ``seq`` at once (reading thread)."""
        with self.lock:
            if not self.done:
                self._answer(seq)

    def _answer(self, seq: int) -> None:
        """Send item ``seq`` and wait for the next request, or for MISSION_ACK after the last (lock held)."""
        if not 0 <= seq < len(self.items):
            return
        last = seq == len(self.items) - 1
        packed = self.items[seq]
        self.link.send_packed(packed)
        self.stage = "MISSION_ACK" if last else "MISSION_REQUEST"
        self.seq, self.tries, self.deferred, self.requested = seq, 0, None, True
        self.timeout_s = self.protocol.item_timeout_s
        self.deadline_s = time.monotonic() + self.timeout_s
        self.resend = (lambda: self.link.send_packed(packed)) if last else (lambda: None)
        self.sent_last = self.sent_last or last

    def on_message(self, msg: MavMessage) -> None:
        """Answer a request at once; note acknowledgements (reading thread)."""
        m = self.link.mavlink
        kind = msg.get_type()
        with self.lock:
            if self.done or not is_mission_message(msg):
                return
            if kind in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
                self._answer(msg.seq)
            elif kind == "MISSION_ACK":
                result = msg.type
                if result == m.MAV_MISSION_ACCEPTED:
                    self.done = self.sent_last
                elif self.requested and (
                    result == m.MAV_MISSION_INVALID_SEQUENCE or self._busy_answer(result)
                ):  # a duplicated item, or "busy" for a duplicated MISSION_COUNT: the transfer goes on
                    self.deferred = mission_result_error(result, self.system_id, self.seq)
                elif self._transient(result):
                    log.debug("vehicle %d: MISSION_COUNT refused (%d), asking again in %.2f s",
                              self.system_id, result, self.backoff_s)
                    self.tries, self.resend = 0, self._send_count
                    self.deadline_s = time.monotonic() + self.backoff_s
                    self.backoff_s = min(2 * self.backoff_s, _BACKOFF_MAX_S)
                else:
                    self.error = mission_result_error(result, self.system_id, self.seq)
                    if self.busy_since_s is not None:
                        waited_s = time.monotonic() - self.busy_since_s
                        self.error.add_detail(f"still refused after asking again for {waited_s:.1f} s "
                                              f"(busy_retry_s = {self.protocol.busy_retry_s})")
                    self.done = True
            if self.done:
                self.finished(self.system_id)

    def poll(self) -> bool:
        """True once accepted; re-sends when a wait ran out; raises the refusal or the timeout.

        A transfer that broke off after the handshake is started again (a new MISSION_COUNT)
        until ``attempts`` transfers were tried.
        """
        with self.lock:
            if self.done:
                if self.error is not None:
                    raise self.error
                return True
            if time.monotonic() < self.deadline_s:
                return False
            self.tries += 1
            if self.tries <= self.protocol.max_retries:
                log.debug("vehicle %d: no %s, retry %d", self.system_id, self.stage, self.tries)
                self.deadline_s = time.monotonic() + self.timeout_s
                self.resend()
                return False
            # a transfer that went silent after a deferred refusal broke off like any other: the
            # refusal is the error only when no attempt is left
            exc = self.deferred or MissionTimeoutError(self.system_id, self.seq, self.stage,
                                                       self.timeout_s * self.tries)
            if self.seq is None or self.attempt >= self.attempts:
                raise exc
            self.attempt += 1
            self.deferred = None
        log.warning("%s; transfer attempt %d", exc, self.attempt)
        self.start()
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
    start_s = time.monotonic()
    wake = threading.Event()
    finished: collections.deque[int] = collections.deque()

    def finish(sid: int) -> None:
        finished.append(sid)
        wake.set()

    uploads: dict[int, _Upload] = {}
    seconds: dict[int, float] = {}
    errors: dict[int, BridgeError] = {}
    readers = {link.reader for link in links.values()}
    with contextlib.ExitStack() as stack:
        for sid in items:
            upload = _Upload(links[sid], sid, component_id, protocol, items[sid], finish, attempts)
            uploads[sid] = upload
            stack.enter_context(links[sid].protocol_handler(sid, upload.on_message, upload.on_request))
        # read on this thread (unless another caller does): no hand-off between reading and waiting
        step = stack.enter_context(readers.pop().lend()) if len(readers) == 1 else None
        for upload in uploads.values():
            upload.start()
        pending = set(uploads)
        while pending:
            next_deadline_s = min(uploads[sid].deadline_s for sid in pending)
            if not finished:
                timeout_s = max(0.0, next_deadline_s - time.monotonic())
                if step is not None:
                    step(timeout_s)  # requests are answered on this thread, as they arrive
                else:
                    wake.wait(timeout_s)
                    wake.clear()
            if not finished and time.monotonic() < next_deadline_s:
                continue
            due = set(pending) if time.monotonic() >= next_deadline_s else set()
            while finished:
                due.add(finished.popleft())
            for sid in sorted(due & pending):
                try:
                    if uploads[sid].poll():
                        seconds[sid] = time.monotonic() - start_s
                        pending.discard(sid)
                except (MissionResultError, MissionTimeoutError) as exc:
                    errors[sid] = exc
                    pending.discard(sid)
    for sid, error in errors.items():
        error.add_detail(vehicle_says(links[sid].status_texts(sid, start_s)))
    for sid, elapsed_s in seconds.items():
        log.info("vehicle %d: uploaded %d items in %.4f s", sid, len(items[sid]), elapsed_s)
    return seconds, errors
