"""Telemetry payloads: what goes over Zenoh, independent of where the data came from.

Keys (:mod:`bridge.telemetry.keys`): a :class:`UavState` on ``uav_swarm/<swarm>/uav/<id>/state``,
a :class:`Plan` on ``uav_swarm/<swarm>/plan``, a :class:`Qos` on ``uav_swarm/<swarm>/qos``.

Payloads are UTF-8 JSON objects (encoding ``application/json``) sharing a header: ``schema`` (the
integer :data:`SCHEMA_VERSION`), ``kind`` (``state``, ``plan`` or ``qos``), ``stamp_s`` (UNIX time
in seconds when the data was produced), ``seq`` (a sequence number per stream, counting up) and
``source`` (``sim`` or ``vehicle``). Readers ignore unknown fields (additive changes keep the
version) and reject another ``schema`` version.

The payloads are :class:`msgspec.Struct` types: the JSON is encoded and decoded, and every field's type
and range validated, in compiled code. Constructing a payload does not validate it; encoding does
(:func:`encode_payload`, also used by the publisher), so an invalid payload never reaches the wire.
They hold only numbers, strings and tuples, so they are not tracked by the garbage collector
(``gc=False``): high telemetry rates do not trigger collections.

Examples:
    >>> state = UavState(stamp_s=1.5, seq=0, source="sim", uav_id=3,
    ...                  position_enu_m=(1.0, 2.0, 30.0), velocity_enu_m_s=(0.0, 0.0, 0.0))
    >>> parse_payload(state_key("demo", 3), state.to_json()) == state
    True
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Any, ClassVar, Final, Literal, cast

import msgspec
import zenoh

from bridge.telemetry.keys import payload_kind, plan_key, qos_key, state_key, uav_id_from_key

if TYPE_CHECKING:
    from bridge.link.vehicle_state import VehicleState

__all__ = [
    "SCHEMA_VERSION",
    "ENCODING",
    "Source",
    "TelemetryFormatError",
    "GeoPoint",
    "UavState",
    "PlanTarget",
    "Plan",
    "Qos",
    "Presence",
    "Telemetry",
    "Payload",
    "encode_payload",
    "parse_payload",
    "state_from_vehicle",
]

SCHEMA_VERSION: Final = 1
"""Version of the JSON payloads; readers reject any other."""

ENCODING = zenoh.Encoding.APPLICATION_JSON
"""The declared encoding of every payload."""

Source = Literal["sim", "vehicle"]
"""Where the data came from: the simulator or a real (or SITL) vehicle."""

NonNegativeInt = Annotated[int, msgspec.Meta(ge=0)]
Vec3 = tuple[float, float, float]
Share = Annotated[float, msgspec.Meta(ge=0.0, le=1.0)]


class TelemetryFormatError(ValueError):
    """A payload or key is not valid telemetry (bad JSON, wrong schema, wrong field)."""


class _Payload(msgspec.Struct, frozen=True, kw_only=True, gc=False, tag_field="kind"):
    """Fields shared by every payload; ``kind`` (the tag) is written first, then ``schema``."""

    kind: ClassVar[str]
    schema: Literal[1] = SCHEMA_VERSION
    stamp_s: float
    seq: NonNegativeInt
    source: Source

    def key(self, swarm: str) -> str:
        """The key expression this payload is published on in ``swarm``."""
        raise NotImplementedError

    def to_json(self) -> bytes:
        """The UTF-8 JSON payload sent over Zenoh (validated, see :func:`encode_payload`)."""
        return encode_payload(cast("Payload", self))

    def to_dict(self) -> dict[str, Any]:
        """The JSON object of this payload, as plain dicts, lists and numbers."""
        return msgspec.json.decode(encode_payload(cast("Payload", self)))


class GeoPoint(msgspec.Struct, frozen=True, gc=False):
    """A WGS84 position: latitude and longitude in degrees, altitude in metres in the home's datum (AMSL)."""

    lat_deg: Annotated[float, msgspec.Meta(ge=-90.0, le=90.0)]
    lon_deg: Annotated[float, msgspec.Meta(ge=-180.0, le=180.0)]
    alt_m: float


class UavState(_Payload, frozen=True, kw_only=True, gc=False, tag="state"):
    """The state of one UAV, from the simulator or from a vehicle.

    A vehicle without a position fix (``fix`` False: before its GPS fix, or the EKF without a
    position) has no position: ``position_enu_m``, ``velocity_enu_m_s`` and ``position_wgs84`` are
    then None, never a placeholder; with a fix, ``position_enu_m`` and ``velocity_enu_m_s`` are given.

    Attributes:
        uav_id: The UAV number (>= 0), also in the key.
        fix: The position is known (False: "no fix", the position fields are None).
        position_enu_m: East, north, up in metres from the swarm's local origin (the home); None
            without a fix.
        velocity_enu_m_s: East, north, up velocity in metres per second; None without a fix.
        position_wgs84: The same position in WGS84 when a home is known, else None.
        target_enu_m: The UAV's current target (east, north, up metres), None when it has none.
        battery_pct: Remaining battery in percent [0, 100], None when unknown.
        mission_item: Index of the mission item being flown (0-based), None when unknown.
        mission_items_total: Number of items in the mission, None when unknown.
        separation_held: The separation guard holds the UAV now (it waits before leaving for its target,
            or its command was turned or braked to keep its distance), None when no guard runs.
        nearest_uav_m: Distance to the nearest other UAV in metres (3-D where the UAVs fly in altitude
            layers), None when unknown or the UAV flies alone.
        wifi_channel: The 802.11 channel number of the UAV's access point, None when not known (the paper's
            radio has no channels).
        airtime_share: The share of time the UAV's access point holds the medium, in [0, 1] (co-channel
            neighbours that hear it take the rest), None when not known.
        n_stations: Users associated with the UAV's access point, None when not known.
    """

    kind: ClassVar[str] = "state"
    uav_id: NonNegativeInt
    position_enu_m: Vec3 | None
    velocity_enu_m_s: Vec3 | None
    fix: bool = True
    position_wgs84: GeoPoint | None = None
    target_enu_m: Vec3 | None = None
    battery_pct: Annotated[float, msgspec.Meta(ge=0.0, le=100.0)] | None = None
    mission_item: NonNegativeInt | None = None
    mission_items_total: NonNegativeInt | None = None
    separation_held: bool | None = None
    nearest_uav_m: Annotated[float, msgspec.Meta(ge=0.0)] | None = None
    wifi_channel: Annotated[int, msgspec.Meta(ge=1)] | None = None
    airtime_share: Share | None = None
    n_stations: NonNegativeInt | None = None

    def __post_init__(self) -> None:
        known = (self.position_enu_m is not None, self.velocity_enu_m_s is not None)
        if self.fix and not all(known):
            raise ValueError("UavState with fix = true needs position_enu_m and velocity_enu_m_s")
        if not self.fix and (any(known) or self.position_wgs84 is not None):
            raise ValueError("UavState with fix = false (no position fix) must have null positions and "
                             "velocity")

    def key(self, swarm: str) -> str:
        """``uav_swarm/<swarm>/uav/<id>/state``."""
        return state_key(swarm, self.uav_id)


class PlanTarget(msgspec.Struct, frozen=True, gc=False):
    """One UAV's target in a plan: east, north, up metres from the swarm's local origin."""

    uav_id: NonNegativeInt
    target_enu_m: Vec3


class Plan(_Payload, frozen=True, kw_only=True, gc=False, tag="plan"):
    """A placement plan: one target per UAV.

    Attributes:
        targets: One :class:`PlanTarget` per UAV (distinct ids).
        planner: The planner's name (e.g. ``cnn-peaks-hungarian``).
        latency_ms: How long the planner took, in milliseconds, None when unknown.
    """

    kind: ClassVar[str] = "plan"
    targets: tuple[PlanTarget, ...]
    planner: str
    latency_ms: Annotated[float, msgspec.Meta(ge=0.0)] | None = None

    def __post_init__(self) -> None:
        ids = [target.uav_id for target in self.targets]
        if len(set(ids)) != len(ids):
            raise ValueError(f"Plan.targets has repeated uav ids {sorted(ids)}")

    def key(self, swarm: str) -> str:
        """``uav_swarm/<swarm>/plan``."""
        return plan_key(swarm)

    def targets_by_uav(self) -> dict[int, tuple[float, float, float]]:
        """The targets as ``{uav_id: (east_m, north_m, up_m)}``."""
        return {t.uav_id: t.target_enu_m for t in self.targets}


class Qos(_Payload, frozen=True, kw_only=True, gc=False, tag="qos"):
    """Quality of service of the swarm's Wi-Fi at one instant (the paper's strategies S1 and S2).

    Attributes:
        qos_s1: Share of users covered, in [0, 1].
        qos_s2: Share of users covered with at least the minimum rate, in [0, 1].
        mean_throughput_mbps: Mean throughput over all users (uncovered count as 0), in Mbit/s.
        n_users: Number of users.
        median_sinr_db: The users' median SINR in dB (802.11 radio: each user at its access point, or its
            strongest one when it has none), None when not known.
        co_channel_pairs: Pairs of UAVs on one channel that hear each other and so share airtime (802.11
            radio), None when not known.
    """

    kind: ClassVar[str] = "qos"
    qos_s1: Share
    qos_s2: Share
    mean_throughput_mbps: Annotated[float, msgspec.Meta(ge=0.0)]
    n_users: NonNegativeInt
    median_sinr_db: float | None = None
    co_channel_pairs: NonNegativeInt | None = None

    def key(self, swarm: str) -> str:
        """``uav_swarm/<swarm>/qos``."""
        return qos_key(swarm)


class Presence(msgspec.Struct, frozen=True, gc=False):
    """A UAV appeared (``alive``) or disappeared on the network; derived from liveliness, not a payload.

    Attributes:
        uav_id: The UAV number.
        alive: True when its token appeared, False when it went away (publisher closed or lost).
        received_s: Local UNIX time when the change was seen, in seconds.
    """

    uav_id: int
    alive: bool
    received_s: float


Payload = UavState | Plan | Qos
Telemetry = UavState | Plan | Qos | Presence


def _enc_hook(value: Any) -> Any:
    """Let numpy scalars and arrays through as Python numbers and lists."""
    if hasattr(value, "tolist"):
        return value.tolist()
    raise NotImplementedError(f"cannot encode {type(value).__name__} in telemetry")


_ENCODER = msgspec.json.Encoder(enc_hook=_enc_hook)
_DECODER = msgspec.json.Decoder(Payload)


def encode_payload(payload: Payload) -> bytes:
    """The JSON of ``payload``, validated by decoding it back (about a microsecond).

    Raises:
        TelemetryFormatError: A field has the wrong type, is out of range, or is not finite (JSON has
            no NaN or infinity; they would be written as null).
    """
    try:
        data = _ENCODER.encode(payload)
        _DECODER.decode(data)
    except (msgspec.ValidationError, NotImplementedError, TypeError) as exc:
        raise TelemetryFormatError(f"invalid {type(payload).__name__}: {exc} (NaN and infinity are not "
                                   "allowed; positions are 3 numbers)") from None
    return data


def parse_payload(key: str, data: bytes | str) -> Payload:
    """Parse the JSON payload of a sample on one of our keys into its typed object.

    Args:
        key: The sample's key expression (decides the expected kind; the UAV id must match).
        data: The UTF-8 JSON payload.

    Raises:
        TelemetryFormatError: The key is not a payload key, the JSON is malformed, the schema version
            differs, or a field is missing or invalid.
    """
    expected = payload_kind(key)
    if expected is None:
        raise TelemetryFormatError(f"key {key!r} is not a telemetry payload key")
    try:
        payload = _DECODER.decode(data)
    except msgspec.DecodeError as exc:
        raise TelemetryFormatError(f"{key}: {_explain(data, exc)}") from None
    if payload.kind != expected:
        raise TelemetryFormatError(f"{key}: kind = {payload.kind!r}, expected {expected!r} on this key")
    if isinstance(payload, UavState) and payload.uav_id != uav_id_from_key(key):
        raise TelemetryFormatError(f"{key}: uav_id = {payload.uav_id} does not match the key")
    return payload


def _explain(data: bytes | str, exc: msgspec.DecodeError) -> str:
    """A message for a payload that failed to decode, naming a foreign schema version first."""
    try:
        obj = msgspec.json.decode(data)
    except msgspec.DecodeError:
        return f"payload is not JSON ({exc})"
    if not isinstance(obj, dict):
        return f"payload must be a JSON object, got {type(obj).__name__}"
    if obj.get("schema") != SCHEMA_VERSION:
        return f"schema = {obj.get('schema')!r}, this reader accepts {SCHEMA_VERSION}"
    return str(exc)


def _known(a: float | None, b: float | None, c: float | None) -> tuple[float, float, float] | None:
    """The three values, or None when one of them is unknown."""
    return None if a is None or b is None or c is None else (a, b, c)


def state_from_vehicle(vehicle: VehicleState, seq: int, *, uav_id: int | None = None,
                       target_enu_m: Vec3 | None = None) -> UavState | None:
    """The telemetry state of a real (or SITL) vehicle, from the MAVLink bridge's snapshot.

    Args:
        vehicle: The vehicle's latest :class:`bridge.link.vehicle_state.VehicleState`.
        seq: The sequence number of this state in the UAV's stream.
        uav_id: The UAV number in the swarm (default: the vehicle's MAVLink system id).
        target_enu_m: The UAV's current target, when the caller knows it.

    Returns:
        The state (``fix`` False, no position, when the vehicle has no position fix), or None before
        its first GLOBAL_POSITION_INT.
    """
    if vehicle.position_time_s is None:
        return None
    enu = _known(vehicle.x_m, vehicle.y_m, vehicle.z_m)
    velocity = _known(vehicle.vx_m_s, vehicle.vy_m_s, vehicle.vz_m_s)
    geodetic = _known(vehicle.lat_deg, vehicle.lon_deg, vehicle.alt_m)
    fix = vehicle.has_fix and enu is not None and velocity is not None and geodetic is not None
    return UavState(
        stamp_s=vehicle.position_time_s, seq=seq, source="vehicle",
        uav_id=vehicle.system_id if uav_id is None else uav_id, fix=fix,
        position_enu_m=enu if fix else None, velocity_enu_m_s=velocity if fix else None,
        position_wgs84=GeoPoint(*geodetic) if fix and geodetic is not None else None,
        target_enu_m=target_enu_m,
        battery_pct=vehicle.battery_remaining_pct, mission_item=vehicle.mission_seq_current,
        mission_items_total=vehicle.mission_total)
