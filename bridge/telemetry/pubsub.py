"""Swarm telemetry over Eclipse Zenoh: a publisher and a subscriber of typed payloads.

The simulator and the MAVLink bridge publish the same payloads (:mod:`bridge.telemetry.schema`);
only their ``source`` field tells them apart. A :class:`SwarmPublisher` holds one liveliness token
per UAV (so subscribers see UAVs appear and disappear, also when the process dies) and answers
queries with the latest state of every UAV, the latest plan and the latest QoS, so a late joiner
need not wait. A :class:`SwarmSubscriber` parses samples into typed objects, by callback or by
iteration, and skips malformed samples with a logged warning.

Example (two processes; the publisher listens, the subscriber connects)::

    config = TelemetryConfig(swarm="demo")                      # listens on tcp/127.0.0.1:7447
    with SwarmPublisher(config) as pub:
        pub.publish_state(UavState(stamp_s=time.time(), seq=step, source="sim", uav_id=0,
                                   position_enu_m=(10.0, 20.0, 30.0), velocity_enu_m_s=(1.0, 0.0, 0.0)))

    watch = config.replace(listen=(), connect=("tcp/127.0.0.1:7447",))
    with SwarmSubscriber(watch) as sub:
        snapshot = sub.latest()                                 # what a late joiner missed
        for item in sub.messages(duration_s=10.0):              # UavState | Plan | Qos | Presence
            ...
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from types import TracebackType

import msgspec
import zenoh

from bridge.geo import Home, enu_to_geodetic
from bridge.telemetry.config import TelemetryConfig, open_session
from bridge.telemetry.keys import (
    alive_key,
    all_alive_key,
    is_payload_key,
    plan_key,
    qos_key,
    state_key,
    swarm_root,
    uav_id_from_key,
)
from bridge.telemetry.schema import (
    ENCODING,
    GeoPoint,
    Payload,
    Plan,
    Presence,
    Qos,
    Telemetry,
    TelemetryFormatError,
    UavState,
    parse_payload,
)

__all__ = ["SwarmPublisher", "SwarmSubscriber", "Snapshot"]

logger = logging.getLogger(__name__)


class SwarmPublisher:
    """Publishes the states, plan and QoS of one swarm; a context manager owning its Zenoh session.

    Publishing never blocks on a slow subscriber: on a congested link Zenoh drops samples (its default
    congestion control) rather than stall the simulator; the queryable still holds the latest of each.

    Args:
        config: Session settings and swarm name.
        home: The geodetic origin of the ENU frame; when given, states without ``position_wgs84``
            get it filled in.
        uav_ids: UAVs announced (liveliness token) at once; others are announced on their first state.

    Examples:
        ``with SwarmPublisher(config) as pub: pub.publish_state(state); pub.publish_plan(plan)``
    """

    def __init__(self, config: TelemetryConfig, *, home: Home | None = None, uav_ids: Iterable[int] = ()):
        self.config = config
        self.home = home
        self._initial_ids = tuple(uav_ids)
        self._session: zenoh.Session | None = None
        self._publishers: dict[str, zenoh.Publisher] = {}
        self._state_publishers: dict[int, tuple[str, zenoh.Publisher]] = {}
        self._tokens: dict[int, zenoh.LivelinessToken] = {}
        self._latest: dict[str, bytes] = {}
        self._lock = threading.Lock()

    def __enter__(self) -> SwarmPublisher:
        self.open()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    def open(self) -> None:
        """Open the session, declare the queryable and announce the initial UAVs."""
        if self._session is not None:
            return
        self._session = open_session(self.config)
        swarm = self.config.swarm
        self._session.declare_queryable(swarm_root(swarm), self._answer)
        for key in (plan_key(swarm), qos_key(swarm)):
            self._publishers[key] = self._session.declare_publisher(key, encoding=ENCODING)
        for uav_id in self._initial_ids:
            self.announce(uav_id)

    def close(self) -> None:
        """Withdraw every UAV's token and close the session (idempotent)."""
        if self._session is None:
            return
        for token in self._tokens.values():
            token.undeclare()
        self._tokens.clear()
        self._publishers.clear()
        self._state_publishers.clear()
        self._session.close()
        self._session = None

    @property
    def session(self) -> zenoh.Session:
        """The open Zenoh session."""
        if self._session is None:
            raise RuntimeError("SwarmPublisher is not open: use it in a with block or call open()")
        return self._session

    def announce(self, uav_id: int) -> None:
        """Declare UAV ``uav_id``'s liveliness token (no-op when already announced)."""
        if uav_id not in self._tokens:
            key = alive_key(self.config.swarm, uav_id)
            self._tokens[uav_id] = self.session.liveliness().declare_token(key)

    def retire(self, uav_id: int) -> None:
        """The UAV left the swarm: withdraw its token and forget its latest state."""
        token = self._tokens.pop(uav_id, None)
        if token is not None:
            token.undeclare()
        known = self._state_publishers.pop(uav_id, None)
        if known is not None:
            known[1].undeclare()
        with self._lock:
            self._latest.pop(state_key(self.config.swarm, uav_id), None)

    def wait_for_subscriber(self, timeout_s: float) -> bool:
        """Wait until a subscriber matches the swarm's keys; True when one does within ``timeout_s``."""
        publisher = self._publishers[plan_key(self.config.swarm)]
        deadline = time.monotonic() + timeout_s
        while not publisher.matching_status.matching:  # type: ignore[attr-defined]  # stub: bool; runtime: MatchingStatus
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.01)
        return True

    def publish_state(self, state: UavState, *, announce: bool = True) -> None:
        """Publish one UAV's state; with ``announce``, the UAV's token is declared on its first state.

        A caller whose token means more than "publishing" (``fly``: flying under the planner) passes
        ``announce=False`` and calls :meth:`announce` itself.

        Raises:
            TelemetryFormatError: A field is invalid (e.g. NaN); nothing is sent.
        """
        data = state.to_json()
        if self.home is not None and state.position_wgs84 is None and state.position_enu_m is not None:
            geo = GeoPoint(*enu_to_geodetic(self.home, *state.position_enu_m))
            data = msgspec.structs.replace(state, position_wgs84=geo).to_json()
        known = self._state_publishers.get(state.uav_id)
        if known is None:
            if announce:
                self.announce(state.uav_id)
            key = state.key(self.config.swarm)
            known = self._state_publishers[state.uav_id] = (
                key, self.session.declare_publisher(key, encoding=ENCODING))
        self._put(known[0], known[1], data)

    def publish_plan(self, plan: Plan) -> None:
        """Publish the swarm's placement plan (raises TelemetryFormatError when invalid)."""
        key = plan.key(self.config.swarm)
        self._put(key, self._publishers[key], plan.to_json())

    def publish_qos(self, qos: Qos) -> None:
        """Publish the swarm's quality of service (raises TelemetryFormatError when invalid)."""
        key = qos.key(self.config.swarm)
        self._put(key, self._publishers[key], qos.to_json())

    def _put(self, key: str, publisher: zenoh.Publisher, data: bytes) -> None:
        with self._lock:
            self._latest[key] = data
        publisher.put(data)

    def _answer(self, query: zenoh.Query) -> None:
        """Reply with every latest payload whose key the query selects."""
        with self._lock:
            latest = list(self._latest.items())
        try:
            for key, data in latest:
                if query.key_expr.intersects(key):
                    query.reply(key, data, encoding=ENCODING)
        except zenoh.ZError as exc:  # the querier went away mid-reply
            logger.debug("query %s: reply failed: %s", query.selector, exc)


@dataclass
class Snapshot:
    """The latest telemetry of a swarm, as answered by its publishers.

    Attributes:
        states: The latest state of each UAV, by id.
        plan: The latest plan, None when none was published.
        qos: The latest QoS, None when none was published.
    """

    states: dict[int, UavState] = field(default_factory=dict)
    plan: Plan | None = None
    qos: Qos | None = None

    def add(self, payload: Payload) -> None:
        """Keep ``payload`` when it is newer (stamp, then seq) than what is held for its key."""
        def newer(old: Payload | None) -> bool:
            return old is None or (payload.stamp_s, payload.seq) >= (old.stamp_s, old.seq)

        if isinstance(payload, UavState):
            if newer(self.states.get(payload.uav_id)):
                self.states[payload.uav_id] = payload
        elif isinstance(payload, Plan):
            self.plan = payload if newer(self.plan) else self.plan
        elif newer(self.qos):
            self.qos = payload


class SwarmSubscriber:
    """Receives a swarm's telemetry as typed objects; a context manager owning its Zenoh session.

    Without a callback, received objects queue up for :meth:`receive`, :meth:`messages` or iteration.
    With a callback, each object is handed to it on a Zenoh thread (exceptions are logged).
    Malformed samples on the swarm's payload keys are skipped with a warning and counted in
    :attr:`malformed`; samples on other keys under ``uav_swarm/<swarm>/`` are ignored.

    Args:
        config: Session settings and swarm name.
        callback: Called with each :class:`UavState`, :class:`Plan`, :class:`Qos` or :class:`Presence`.
        presence: Also report UAVs appearing and disappearing (liveliness), including those present now.
        max_queue: Objects held for the iterator before new ones are dropped (counted in :attr:`dropped`).
    """

    def __init__(self, config: TelemetryConfig, *, callback: Callable[[Telemetry], object] | None = None,
                 presence: bool = True, max_queue: int = 100_000):
        self.config = config
        self.malformed = 0
        self.dropped = 0
        self._callback = callback
        self._presence = presence
        self._queue: queue.Queue[Telemetry] = queue.Queue(max_queue)
        self._session: zenoh.Session | None = None

    def __enter__(self) -> SwarmSubscriber:
        self.open()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    def open(self) -> None:
        """Open the session and declare the subscribers."""
        if self._session is not None:
            return
        self._session = open_session(self.config)
        self._session.declare_subscriber(swarm_root(self.config.swarm), self._on_sample)
        if self._presence:
            self._session.liveliness().declare_subscriber(
                all_alive_key(self.config.swarm), self._on_liveliness, history=True)

    def close(self) -> None:
        """Close the session (idempotent); queued objects stay readable."""
        if self._session is not None:
            self._session.close()
            self._session = None

    @property
    def session(self) -> zenoh.Session:
        """The open Zenoh session."""
        if self._session is None:
            raise RuntimeError("SwarmSubscriber is not open: use it in a with block or call open()")
        return self._session

    def receive(self, timeout_s: float | None = None) -> Telemetry | None:
        """The next object, waiting at most ``timeout_s`` seconds (forever when None); None on timeout."""
        try:
            return self._queue.get(timeout=timeout_s)
        except queue.Empty:
            return None

    def messages(self, *, duration_s: float | None = None, count: int | None = None) -> Iterator[Telemetry]:
        """Yield received objects until ``duration_s`` seconds have passed or ``count`` were yielded.

        With both None this runs until the subscriber is closed.
        """
        deadline = None if duration_s is None else time.monotonic() + duration_s
        yielded = 0
        while (count is None or yielded < count) and self._session is not None:
            wait_s = 0.1 if deadline is None else min(0.1, deadline - time.monotonic())
            if wait_s <= 0:
                return
            item = self.receive(wait_s)
            if item is not None:
                yielded += 1
                yield item

    def __iter__(self) -> Iterator[Telemetry]:
        """Yield received objects until the subscriber is closed."""
        return self.messages()

    def latest(self, timeout_s: float | None = None) -> Snapshot:
        """Ask the swarm's publishers for the latest state of every UAV, plan and QoS.

        Args:
            timeout_s: Bound on the query, seconds (default: the config's ``timeout_s``).
        """
        snapshot = Snapshot()
        replies = self.session.get(
            swarm_root(self.config.swarm), timeout=timeout_s or self.config.timeout_s,
            consolidation=zenoh.ConsolidationMode.NONE)
        for reply in replies:
            if reply.ok is not None:
                payload = self._parse(reply.ok)
                if payload is not None:
                    snapshot.add(payload)
        return snapshot

    def alive(self, timeout_s: float | None = None) -> set[int]:
        """The ids of the UAVs whose liveliness token is present now."""
        replies = self.session.liveliness().get(
            all_alive_key(self.config.swarm), timeout=timeout_s or self.config.timeout_s)
        ids = (uav_id_from_key(str(reply.ok.key_expr)) for reply in replies if reply.ok is not None)
        return {uav_id for uav_id in ids if uav_id is not None}

    def _parse(self, sample: zenoh.Sample) -> Payload | None:
        key = str(sample.key_expr)
        try:
            return parse_payload(key, sample.payload.to_bytes())
        except TelemetryFormatError as exc:
            self.malformed += 1
            logger.warning("skipping malformed telemetry sample: %s", exc)
            return None

    def _on_sample(self, sample: zenoh.Sample) -> None:
        if sample.kind != zenoh.SampleKind.PUT or not is_payload_key(str(sample.key_expr)):
            logger.debug("ignoring %s sample on %s", sample.kind, sample.key_expr)
            return
        payload = self._parse(sample)
        if payload is not None:
            self._deliver(payload)

    def _on_liveliness(self, sample: zenoh.Sample) -> None:
        uav_id = uav_id_from_key(str(sample.key_expr))
        if uav_id is not None:
            self._deliver(Presence(uav_id, sample.kind == zenoh.SampleKind.PUT, time.time()))

    def _deliver(self, item: Telemetry) -> None:
        if self._callback is not None:
            try:
                self._callback(item)
            except Exception:
                logger.exception("telemetry callback failed on %s", type(item).__name__)
            return
        try:
            self._queue.put_nowait(item)
        except queue.Full:
            self.dropped += 1
            if self.dropped == 1 or self.dropped % 1000 == 0:
                logger.warning("telemetry queue full (%d items): %d dropped so far",
                               self._queue.maxsize, self.dropped)
