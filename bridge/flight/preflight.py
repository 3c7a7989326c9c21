"""Checks before arming: the vehicle's own link-loss failsafe, its geofence, its return flight.

A vehicle flown from a ground station must leave guided flight by itself when that ground
station goes silent (a crash, a cut link, ``kill -9``): otherwise it hovers where it was told
until its battery ends. :func:`preflight` reads, with the parameter protocol
(:mod:`bridge.flight.params`) and its autopilot's names (:mod:`bridge.autopilots`):

- the link-loss failsafe's action and timeout (ArduPilot ``FS_GCS_ENABLE`` / ``FS_GCS_TIMEOUT``,
  PX4 ``NAV_DLL_ACT`` / ``COM_DL_LOSS_T``); any action but return to launch (off, a hold, a landing
  where it is, SmartRTL, a mission's landing) is refused, naming the vehicle and the parameter, unless
  ``set_failsafe``: then it is set to return to launch and read back (the return is the one failsafe
  flight the guard keeps apart from the others, :mod:`uav_swarm.world.guard.failsafe`);
- which ground station the failsafe watches: ArduPilot watches only the heartbeat of
  ``SYSID_MYGCS``, so it must be this bridge's own system id (another ground station's heartbeat
  would keep the vehicle in guided flight after the bridge died); PX4 watches any;
- its geofence switch (``FENCE_ENABLE``, ``GF_ACTION``): reported (:func:`warn_fences_off` warns once
  for every vehicle whose fence is off);
- its return flight, set and read back (:func:`set_return_altitude`, :func:`pin_return_path`): the
  return altitude (``RTL_ALT`` in centimetres, ``RTL_RETURN_ALT`` in metres) to ``rtl_alt_m`` (this
  vehicle's return layer), no cone (``RTL_CONE_SLOPE`` / ``RTL_CONE_ANG`` = 0: a cone would lower the
  return near home below the layer), the altitude above home (``RTL_ALT_TYPE`` = 0) and straight home
  (``RTL_TYPE`` = 0), PX4's ``RTL_DESCEND_ALT`` at most the return altitude, and no "continue" bit in
  ArduPilot's ``FS_OPTIONS`` (a mission, a landing or a pilot's mode flown on through a lost link), and
  no hold before the failsafe's action (PX4's ``COM_FAIL_ACT_T`` = 0: by default PX4 holds 5 s after
  ``COM_DL_LOSS_T`` before it returns, so its return would start 5 s after its timeout). A
  parameter that cannot be set is refused, naming it: nothing is armed.
"""

from __future__ import annotations

import logging
from dataclasses import asdict, dataclass
from typing import Any

from bridge.autopilots import Conventions
from bridge.config import ProtocolConfig
from bridge.errors import RefusedError
from bridge.flight.params import ParamError, ParamValue, read_param, set_param
from bridge.link.mavlink import MavlinkLink

__all__ = ["PreflightError", "PreflightReport", "preflight", "pin_return_path", "set_return_altitude",
           "warn_fences_off", "DEFAULT_FAILSAFE_TIMEOUT_S"]

log = logging.getLogger(__name__)

DEFAULT_FAILSAFE_TIMEOUT_S = 5.0
"""The link-loss timeout set when a vehicle has none (0) and the user asked to set the failsafe."""


class PreflightError(RefusedError, ValueError):
    """A vehicle is not safe to arm (its message names the vehicle, the parameter and the fix)."""

    def __init__(self, system_id: int, message: str) -> None:
        self.system_id = system_id
        super().__init__(f"vehicle {system_id}: {message}")


@dataclass(frozen=True)
class PreflightReport:
    """What :func:`preflight` found and set on one vehicle (JSON-ready with :meth:`to_dict`)."""

    system_id: int
    autopilot: str
    failsafe: str
    failsafe_action: int
    failsafe_timeout_s: float
    failsafe_set: bool
    fence_enabled: bool
    rtl_alt_m: float
    return_path: dict[str, float]
    """Each parameter of the return path as read back after it was set."""

    def to_dict(self) -> dict[str, Any]:
        """The report as a dict."""
        return asdict(self)


def preflight(link: MavlinkLink, system_id: int, conventions: Conventions, *, gcs_system_id: int,
              rtl_alt_m: float, set_failsafe: bool = False,
              protocol: ProtocolConfig | None = None) -> PreflightReport:
    """Read the vehicle's failsafe and fence, set its return altitude (module docstring).

    Args:
        link: The connection reaching the vehicle.
        system_id: The vehicle.
        conventions: Its autopilot's (parameter names and encoding).
        gcs_system_id: This bridge's own system id (the heartbeat the failsafe must watch).
        rtl_alt_m: Its return altitude above home, metres.
        set_failsafe: Set a missing failsafe (return to launch) instead of refusing the vehicle.
        protocol: Timeouts and retries.

    Raises:
        PreflightError: The failsafe is off (or a hold), has no timeout, or watches another ground
            station, and ``set_failsafe`` is False.
        ParamError: A parameter could not be read or set.
    """
    protocol = protocol or ProtocolConfig()
    bytewise = conventions.param_bytewise

    def read(name: str) -> ParamValue:
        return read_param(link, system_id, name, bytewise=bytewise, protocol=protocol)

    def ensure(current: ParamValue, wanted: float, why: str) -> ParamValue:
        if not set_failsafe:
            raise PreflightError(system_id, f"{current.name} = {current.value:g}: {why}; nothing was armed. "
                                            f"Set {current.name} = {wanted:g} on the vehicle, or run fly "
                                            "with --set-failsafe")
        done = set_param(link, system_id, current.name, wanted, current.param_type, bytewise=bytewise,
                         protocol=protocol)
        log.warning("vehicle %d: %s was %g (%s): set to %g", system_id, current.name, current.value, why,
                    wanted)
        return done

    action = read(conventions.failsafe_param)
    changed = False
    if int(action.value) != int(conventions.failsafe_rtl):
        action = ensure(action, conventions.failsafe_rtl,
                        f"its link-loss failsafe is not return to launch ({conventions.name}: "
                        f"{conventions.failsafe_param} = {conventions.failsafe_rtl:g})")
        changed = True
    timeout = read(conventions.failsafe_timeout_param)
    if timeout.value <= 0:
        timeout = ensure(timeout, DEFAULT_FAILSAFE_TIMEOUT_S, "its link-loss failsafe has no timeout")
        changed = True
    if conventions.gcs_id_param:
        watched = read(conventions.gcs_id_param)
        if int(watched.value) != gcs_system_id:
            ensure(watched, float(gcs_system_id),
                   f"its failsafe watches ground station {int(watched.value)}'s heartbeat, not this "
                   f"bridge's (source_system = {gcs_system_id})")
            changed = True
    fence = read(conventions.fence_param)
    if fence.value == 0:  # reported (fence_enabled); the caller warns once for every such vehicle
        log.debug("vehicle %d: its own geofence is off (%s = 0)", system_id, conventions.fence_param)
    held_m = set_return_altitude(link, system_id, conventions, rtl_alt_m, protocol)
    path = pin_return_path(link, system_id, conventions, rtl_alt_m, protocol)
    return PreflightReport(
        system_id=system_id, autopilot=conventions.name,
        failsafe=f"{action.name} = {action.value:g}, {timeout.name} = {timeout.value:g} s",
        failsafe_action=int(action.value), failsafe_timeout_s=float(timeout.value), failsafe_set=changed,
        fence_enabled=fence.value != 0, rtl_alt_m=held_m, return_path=path)


def _settle(link: MavlinkLink, system_id: int, conventions: Conventions, name: str, wanted: float,
            protocol: ProtocolConfig, why: str, *, at_most: bool = False) -> float:
    """Read ``name``; set it to ``wanted`` unless it holds it (or less, ``at_most``); the value read back.

    Raises:
        PreflightError: It cannot be read or set (naming it, its wanted value and ``why``).
    """
    bytewise = conventions.param_bytewise
    try:
        current = read_param(link, system_id, name, bytewise=bytewise, protocol=protocol)
        if current.value <= wanted + 1e-3 and (at_most or current.value >= wanted - 1e-3):
            return current.value
        log.info("vehicle %d: %s was %g: set to %g (%s)", system_id, name, current.value, wanted, why)
        return set_param(link, system_id, name, wanted, current.param_type, bytewise=bytewise,
                         protocol=protocol).value
    except ParamError as exc:
        raise PreflightError(system_id, f"{name} cannot be set to {wanted:g} ({exc.args[0]}): {why}; "
                                        "nothing was armed") from None


def set_return_altitude(link: MavlinkLink, system_id: int, conventions: Conventions, rtl_alt_m: float,
                        protocol: ProtocolConfig | None = None) -> float:
    """Set the vehicle's return altitude above home to ``rtl_alt_m`` and read it back; the altitude it holds.

    Before arming, and in flight when the return layers are ordered anew (metres).

    Raises:
        PreflightError: Naming the parameter, when it cannot be set.
    """
    wanted = round(rtl_alt_m * conventions.rtl_alt_per_m, 3)
    held = _settle(link, system_id, conventions, conventions.rtl_alt_param, wanted,
                   protocol or ProtocolConfig(), "its return layer")
    return held / conventions.rtl_alt_per_m


def pin_return_path(link: MavlinkLink, system_id: int, conventions: Conventions, rtl_alt_m: float,
                    protocol: ProtocolConfig | None = None) -> dict[str, float]:
    """Pin the return path (no cone, above home, straight home, no "continue" failsafe option); read back.

    Raises:
        PreflightError: Naming the parameter that cannot be set.
    """
    protocol = protocol or ProtocolConfig()
    held: dict[str, float] = {}
    for name, wanted in conventions.rtl_pinned:
        held[name] = _settle(link, system_id, conventions, name, wanted, protocol,
                             "its return must climb where it is to its layer and fly straight home")
    if conventions.rtl_descend_param:
        held[conventions.rtl_descend_param] = _settle(
            link, system_id, conventions, conventions.rtl_descend_param, rtl_alt_m, protocol,
            "it must not descend over home from above its return layer", at_most=True)
    if conventions.failsafe_delay_param:
        held[conventions.failsafe_delay_param] = _settle(
            link, system_id, conventions, conventions.failsafe_delay_param, 0.0, protocol,
            "a lost link must start its return at the link-loss timeout, not hold first")
    if conventions.failsafe_options_param:
        name, bits = conventions.failsafe_options_param, conventions.failsafe_continue_bits
        try:
            options = read_param(link, system_id, name, bytewise=conventions.param_bytewise,
                                 protocol=protocol)
        except ParamError as exc:
            raise PreflightError(system_id, f"{name} cannot be read ({exc.args[0]}); nothing was armed"
                                 ) from None
        wanted = float(int(options.value) & ~bits)
        held[name] = _settle(link, system_id, conventions, name, wanted, protocol,
                             "a lost link must start its return, not continue a mission, a landing or a "
                             "pilot's mode")
    return held


def warn_fences_off(reports: list[PreflightReport], fence_params: dict[int, str]) -> None:
    """One warning naming every vehicle whose own geofence is off (none: nothing said).

    Args:
        reports: The vehicles' pre-flight reports.
        fence_params: Each vehicle's geofence switch (``FENCE_ENABLE``, ``GF_ACTION``), by system id.
    """
    off = sorted(r.system_id for r in reports if not r.fence_enabled)
    if not off:
        return
    names = " / ".join(sorted({fence_params[sid] for sid in off}))
    who = f"vehicle {off[0]}: its" if len(off) == 1 else f"vehicles {', '.join(map(str, off))}: their"
    log.warning("%s own geofence is off (%s = 0): only the bridge's fence checks the targets", who, names)
