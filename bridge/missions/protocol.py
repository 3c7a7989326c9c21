"""The MAVLink mission protocol, ground-station side: upload, download, clear, set current.

Timing follows the protocol: the first answer is awaited ``handshake_timeout_s``
(1.5 s), each later one ``item_timeout_s`` (0.25 s); an unanswered message is sent
again up to ``max_retries`` (5) times, then :class:`~bridge.errors.MissionTimeoutError`
is raised. Every wait is bounded, so no call can hang. Error acknowledgements raise
the named exception of their ``MAV_MISSION_RESULT`` code. Uploads run in
:mod:`bridge.missions.upload` (requests answered as they arrive, on the thread that reads;
its docstring gives the re-send rules).

A transfer that breaks off after the handshake (the vehicle answered, then fell
silent through every retry) is started again from the beginning, up to
``transfer_attempts`` times in all; a vehicle that never answers is not.
"""

from __future__ import annotations

import functools
import logging
import queue
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TypeVar

from bridge.config import ProtocolConfig
from bridge.errors import BridgeError, MissionMismatchError, MissionTimeoutError, mission_result_error
from bridge.link.frames import MavMessage
from bridge.link.mavlink import MavlinkLink
from bridge.missions.compare import compare_missions
from bridge.missions.items import DEG_E7, MissionItem
from bridge.missions.upload import is_mission_message, upload_concurrently, vehicle_says

__all__ = ["MissionClient", "UploadTimes"]

log = logging.getLogger(__name__)

T = TypeVar("T")


def _is_item(seq: int, msg: MavMessage) -> bool:
    """``msg`` is mission item ``seq`` (as MISSION_ITEM_INT, or the float MISSION_ITEM)."""
    return bool(msg.get_type() in ("MISSION_ITEM_INT", "MISSION_ITEM") and msg.seq == seq)


@dataclass(frozen=True)
class UploadTimes:
    """Seconds spent by a verified upload, over all its attempts.

    Attributes:
        upload_s: Sending the mission (MISSION_COUNT to the final MISSION_ACK).
        verify_s: Reading it back and comparing (0 when not verified).
    """

    upload_s: float
    verify_s: float = 0.0


class _Exchange:
    """Send-and-wait with the protocol's timeouts and retries, on one vehicle's inbox."""

    def __init__(self, client: MissionClient, box: queue.Queue) -> None:
        self.client = client
        self.box = box
        self.resend: Callable[[], None] = lambda: None
        self.timeout_s = client.protocol.handshake_timeout_s
        self.tries = 0
        self.stage = ""
        self.seq: int | None = None
        self.deadline_s = time.monotonic() + self.timeout_s

    def expect(self, stage: str, seq: int | None, timeout_s: float, send: Callable[[], None]) -> None:
        """Send now; ``next`` re-sends it whenever ``timeout_s`` passes without progress."""
        self.stage, self.seq, self.timeout_s, self.tries, self.resend = stage, seq, timeout_s, 0, send
        self.deadline_s = time.monotonic() + timeout_s
        send()

    def next(self) -> MavMessage:
        """The next message for this vehicle, re-sending on timeouts; raises when retries run out.

        The wait is measured from the last send, not from the last message: unrelated
        traffic (MISSION_CURRENT streams, duplicates) cannot extend it. When retries run
        out, :class:`MissionTimeoutError` is raised.
        """
        while True:
            try:
                return self.box.get(timeout=max(0.0, self.deadline_s - time.monotonic()))
            except queue.Empty:
                self.tries += 1
                if self.tries > self.client.protocol.max_retries:
                    waited_s = self.timeout_s * self.tries
                    raise MissionTimeoutError(self.client.system_id, self.seq, self.stage, waited_s) from None
                log.debug("vehicle %d: no %s, retry %d", self.client.system_id, self.stage, self.tries)
                self.deadline_s = time.monotonic() + self.timeout_s
                self.resend()


class MissionClient:
    """Mission transfers with one vehicle (system id, component 1) over a shared link.

    Args:
        link: The connection reaching the vehicle.
        system_id: The vehicle's system id.
        protocol: Timeouts and retries.
        component_id: The vehicle's autopilot component.
    """

    def __init__(
        self, link: MavlinkLink, system_id: int, protocol: ProtocolConfig | None = None, component_id: int = 1
    ) -> None:
        self.link = link
        self.system_id = system_id
        self.component_id = component_id
        self.protocol = protocol or ProtocolConfig()
        self._m = link.mavlink

    def _targets(self) -> dict[str, int]:
        return {"target_system": self.system_id, "target_component": self.component_id}

    def _upload_once(self, items: Sequence[MissionItem], attempts: int = 1) -> None:
        """Upload with ``attempts`` whole-transfer attempts (see :func:`upload_concurrently`)."""
        _, errors = upload_concurrently(
            {self.system_id: self.link}, {self.system_id: items}, self.protocol, attempts, self.component_id
        )
        if errors:
            raise errors[self.system_id]

    def _download_once(self) -> tuple[tuple[MissionItem, ...], frozenset[int]]:
        """One download attempt: the items, and the seqs the vehicle sent as float MISSION_ITEM."""
        m = self._m
        as_float = set()
        with self.link.inbox(self.system_id) as box:
            ex = _Exchange(self, box)
            ex.expect(
                "MISSION_COUNT",
                None,
                self.protocol.handshake_timeout_s,
                lambda: self.link.send(
                    lambda mav: mav.mission_request_list_send(
                        mission_type=m.MAV_MISSION_TYPE_MISSION, **self._targets()
                    )
                ),
            )
            count = self._await(ex, lambda msg: msg.get_type() == "MISSION_COUNT").count
            items = []
            for seq in range(count):
                ex.expect("MISSION_ITEM_INT", seq, self.protocol.item_timeout_s,
                          functools.partial(self._request_item, seq))
                msg = self._await(ex, functools.partial(_is_item, seq))
                items.append(self._item_from(msg))
                if msg.get_type() == "MISSION_ITEM":
                    as_float.add(seq)
            self.link.send(
                lambda mav: mav.mission_ack_send(
                    type=m.MAV_MISSION_ACCEPTED, mission_type=m.MAV_MISSION_TYPE_MISSION, **self._targets()
                )
            )
        return tuple(items), frozenset(as_float)

    def _request_item(self, seq: int) -> None:
        """Ask the vehicle for item ``seq`` (MISSION_REQUEST_INT)."""
        self.link.send(lambda mav: mav.mission_request_int_send(
            seq=seq, mission_type=self._m.MAV_MISSION_TYPE_MISSION, **self._targets()))

    def _await(self, ex: _Exchange, wanted: Callable[[MavMessage], bool]) -> MavMessage:
        """The next message satisfying ``wanted``; error acknowledgements raise."""
        while True:
            msg = ex.next()
            if not is_mission_message(msg):
                continue
            if wanted(msg):
                return msg
            if msg.get_type() == "MISSION_ACK" and msg.type != self._m.MAV_MISSION_ACCEPTED:
                raise mission_result_error(msg.type, self.system_id, ex.seq)

    def _item_from(self, msg: MavMessage) -> MissionItem:
        x, y = msg.x, msg.y
        if msg.get_type() == "MISSION_ITEM":
            x, y = round(x * DEG_E7), round(y * DEG_E7)
        return MissionItem(
            seq=msg.seq,
            frame=msg.frame,
            command=msg.command,
            current=msg.current,
            autocontinue=msg.autocontinue,
            param1=msg.param1,
            param2=msg.param2,
            param3=msg.param3,
            param4=msg.param4,
            x=x,
            y=y,
            z=msg.z,
            mission_type=getattr(msg, "mission_type", 0),
        )

    def clear(self) -> None:
        """Delete the vehicle's mission (MISSION_CLEAR_ALL, MISSION_ACK).

        Raises:
            MissionResultError: A named subclass for the vehicle's error code.
            MissionTimeoutError: The vehicle did not acknowledge.
        """
        m = self._m
        with self.link.inbox(self.system_id) as box:
            ex = _Exchange(self, box)
            ex.expect(
                "MISSION_ACK",
                None,
                self.protocol.handshake_timeout_s,
                lambda: self.link.send(
                    lambda mav: mav.mission_clear_all_send(
                        mission_type=m.MAV_MISSION_TYPE_MISSION, **self._targets()
                    )
                ),
            )
            self._await(
                ex, lambda msg: msg.get_type() == "MISSION_ACK" and msg.type == m.MAV_MISSION_ACCEPTED
            )

    def set_current(self, seq: int) -> None:
        """Make item ``seq`` the current one (MISSION_SET_CURRENT, confirmed by MISSION_CURRENT).

        Raises:
            MissionResultError: A named subclass for the vehicle's error code.
            MissionTimeoutError: The vehicle did not confirm.
        """
        with self.link.inbox(self.system_id) as box:
            ex = _Exchange(self, box)
            ex.expect(
                "MISSION_CURRENT",
                seq,
                self.protocol.handshake_timeout_s,
                lambda: self.link.send(lambda mav: mav.mission_set_current_send(seq=seq, **self._targets())),
            )
            self._await(ex, lambda msg: msg.get_type() == "MISSION_CURRENT" and msg.seq == seq)

    def _attempts(self, transfer: Callable[[], T]) -> T:
        """Run a whole transfer again (up to ``transfer_attempts`` times) when it broke off mid-way.

        A transfer breaks off mid-way when the vehicle answered the handshake and then fell
        silent for every retry, or when a verified upload read back something else. A vehicle
        that never answers, or that refuses with an error code, is not asked again. The error
        raised carries what the vehicle said meanwhile (STATUSTEXT).
        """
        start_s = time.monotonic()
        try:
            for attempt in range(1, self.protocol.transfer_attempts + 1):
                try:
                    return transfer()
                except (MissionTimeoutError, MissionMismatchError) as exc:
                    mid_way = isinstance(exc, MissionMismatchError) or exc.seq is not None
                    if not mid_way or attempt == self.protocol.transfer_attempts:
                        raise
                    log.warning("%s; transfer attempt %d", exc, attempt + 1)
        except BridgeError as exc:
            exc.add_detail(vehicle_says(self.link.status_texts(self.system_id, start_s)))
            raise
        raise AssertionError("unreachable")  # pragma: no cover

    def upload(self, items: Sequence[MissionItem]) -> None:
        """Upload a mission (MISSION_COUNT, answer each request, MISSION_ACK).

        Answers MISSION_REQUEST_INT and the legacy MISSION_REQUEST alike with MISSION_ITEM_INT
        (positions exact in degE7), in whatever order the vehicle asks.

        Raises:
            MissionResultError: A named subclass for the vehicle's error code.
            MissionTimeoutError: The vehicle stopped answering.
        """
        self._upload_once(items, attempts=self.protocol.transfer_attempts)

    def download(self) -> tuple[MissionItem, ...]:
        """Download the vehicle's mission (MISSION_REQUEST_LIST, request each item, MISSION_ACK).

        Raises:
            MissionResultError: A named subclass for the vehicle's error code.
            MissionTimeoutError: The vehicle stopped answering.
        """
        return self._attempts(self._download_once)[0]

    def upload_verified(
        self, items: Sequence[MissionItem], *, strict: bool = False, vehicle_home: bool = False
    ) -> UploadTimes:
        """Upload, then download and compare (:func:`~bridge.missions.compare.compare_missions`).

        A final MISSION_ACK lost on the way back is not an error when the vehicle's
        mission, read back, is the one sent.

        Args:
            items: The mission.
            strict: Compare every field exactly, accepting none of ArduPilot's changes.
            vehicle_home: Item 0 is the vehicle's home (ArduPilot): read back as its own.

        Returns:
            The time spent uploading and verifying, over all attempts.

        Raises:
            MissionMismatchError: The vehicle holds something else.
            MissionResultError: A named subclass for the vehicle's error code.
            MissionTimeoutError: The vehicle stopped answering.
        """
        spent = {"upload_s": 0.0, "verify_s": 0.0}

        def transfer() -> None:
            start_s = time.monotonic()
            try:
                self._upload_once(items)
            except MissionTimeoutError as exc:
                if exc.stage != "MISSION_ACK":
                    raise
                log.warning("%s; the final MISSION_ACK may be lost: checking by download", exc)
            finally:
                spent["upload_s"] += time.monotonic() - start_s
            start_s = time.monotonic()
            try:
                received, as_float = self._download_once()
                compare_missions(
                    self.system_id,
                    items,
                    received,
                    strict=strict,
                    vehicle_home=vehicle_home,
                    float_positions=as_float,
                )
            finally:
                spent["verify_s"] += time.monotonic() - start_s

        self._attempts(transfer)
        return UploadTimes(**spent)
