"""One convention table per autopilot, chosen from the vehicle's HEARTBEAT ``autopilot`` field.

ArduPilot and PX4 answer the same MAVLink messages differently. Every choice the bridge makes
by autopilot reads one row of :class:`Conventions`, taken with :func:`conventions_for` from what
the vehicle itself says in its HEARTBEAT, never guessed from a config:

=========================  =====================================  =========================================
what                       ArduPilot (Copter 4.6)                  PX4 (v1.16)
=========================  =====================================  =========================================
custom mode (HEARTBEAT,    the mode number                         ``px4_custom_mode``: main mode in bits
``DO_SET_MODE`` param2/3)                                          16-23, sub mode in bits 24-31
guided flight and hold     GUIDED (4)                              AUTO.LOITER (main 4, sub 3)
flying the mission         AUTO (3)                                AUTO.MISSION (main 4, sub 4)
take-off                   ``NAV_TAKEOFF`` in GUIDED, param7        ``NAV_TAKEOFF`` (AUTO.TAKEOFF, then
                           above home                              AUTO.LOITER), param7 above sea level
``DO_REPOSITION``          ``GLOBAL_RELATIVE_ALT_INT``, z above     z read above sea level whatever the
(``COMMAND_INT``)          home                                    frame: ``GLOBAL_INT``, z = its
                                                                   HOME_POSITION altitude + height
mission item 0             its home (the vehicle overwrites it)     the first real item (the take-off)
home                       HOME_POSITION only (a fix comes long     HOME_POSITION, or its first fix
                           before the home)
pre-arm messages           ``PreArm: ...``                         ``Preflight Fail: ...``,
                                                                   ``Arming denied: ...``
clearing a flown mission   refused (``MAV_MISSION_ERROR``)         accepted: the bridge must refuse it
end of a flight            RTL (6) or LAND (9), by command          AUTO.RTL (4, 5) or AUTO.LAND (4, 6),
                                                                   by command
parameters (PARAM_VALUE)   integers cast to the float              integers' bytes in the float (bytewise)
link-loss failsafe         ``FS_GCS_ENABLE`` (0 off, 1 RTL, 7       ``NAV_DLL_ACT`` (0 off, 1 hold, 2 Return,
                           brake or land),                         3 land),
                           ``FS_GCS_TIMEOUT`` (s); it watches      ``COM_DL_LOSS_T`` (s); any ground
                           only ``SYSID_MYGCS``'s heartbeat        station's heartbeat keeps the link
return altitude            ``RTL_ALT``, centimetres above home     ``RTL_RETURN_ALT``, metres above home
return path (pinned        ``RTL_CONE_SLOPE`` 0 (no cone),         ``RTL_CONE_ANG`` 0 (no cone),
before arming)             ``RTL_ALT_TYPE`` 0 (above home),        ``RTL_TYPE`` 0 (straight home),
                           ``FS_OPTIONS`` without the bits that    ``RTL_DESCEND_ALT`` at most the return
                           continue a mission, a landing or a      altitude
                           pilot's mode on a GCS failsafe          ``COM_FAIL_ACT_T`` 0 (no hold before
                                                                   the failsafe's action)
geofence                   ``FENCE_ENABLE`` (0 off)                ``GF_ACTION`` (0 none)
=========================  =====================================  =========================================

"Flying its mission" is the same rule for both: armed, in the mission mode, at any item (the
take-off item included). Any other autopilot gets :data:`GENERIC`: the MAVLink common
conventions (altitude frames honoured, item 0 a real item) with ArduPilot's mode numbers, as
the bridge flew test vehicles before this table existed.
"""

from __future__ import annotations

from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink

__all__ = ["Conventions", "ARDUPILOT", "PX4", "GENERIC", "conventions_for", "px4_custom_mode"]


def px4_custom_mode(main_mode: int, sub_mode: int = 0) -> int:
    """HEARTBEAT ``custom_mode`` of a PX4 main and sub mode (``union px4_custom_mode``).

    >>> hex(px4_custom_mode(4, 3))  # AUTO.LOITER
    '0x3040000'
    """
    return (main_mode & 0xFF) << 16 | (sub_mode & 0xFF) << 24


@dataclass(frozen=True)
class Conventions:
    """How one autopilot wants to be flown and given missions (see the module's table).

    Attributes:
        name: The autopilot's name in messages.
        autopilot: Its ``MAV_AUTOPILOT_*``.
        guided_mode: ``MAV_CMD_DO_SET_MODE`` param2[, param3] of guided flight (and hold).
        mission_mode: The same for flying the uploaded mission.
        mission_mode_names: :attr:`VehicleState.mode` names (pymavlink's decoding) of flying the mission.
        home_item: Mission item 0 is the vehicle's home (ArduPilot), not a real item.
        takeoff_amsl: ``MAV_CMD_NAV_TAKEOFF`` param7 is above mean sea level (else above home).
        reposition_frame: ``MAV_FRAME_*`` of a ``MAV_CMD_DO_REPOSITION`` COMMAND_INT.
        reposition_amsl: Its z is above mean sea level (the vehicle's home altitude + the height).
        fix_stands_in: The first position fix may stand in for a home not reported.
        prearm_prefixes: How its STATUSTEXT begins when it refuses to arm.
        clear_hint: What to do when it refuses to clear the mission it flies ("" if it never does).
        param_bytewise: Integer parameters travel as their bytes in PARAM_VALUE's float (else cast).
        failsafe_param: The link-loss (ground station) failsafe's action; 0 is off.
        failsafe_rtl: Its value for "return to launch", the only action accepted (the return is the
            failsafe flight the guard separates; SmartRTL, a landing where it is or a hold are not).
        failsafe_timeout_param: Seconds without the ground station's heartbeat before the action.
        gcs_id_param: The one ground station system id whose heartbeat it watches ("" if any GCS's).
        rtl_alt_param: The return altitude above home.
        rtl_alt_per_m: Units of ``rtl_alt_param`` per metre (100: centimetres).
        fence_param: The geofence's switch (0 is off).
        rtl_pinned: Parameters of its return path set to these values before arming (no cone, the
            return altitude above home, straight home).
        failsafe_options_param: Its failsafe options bitmask ("" if none).
        failsafe_continue_bits: The bits of it that keep the vehicle flying on instead of returning.
        rtl_descend_param: The altitude it descends to over home before landing ("" if none); kept at most
            the return altitude.
        failsafe_delay_param: Seconds it holds before a failsafe's action ("" if none); set to 0, so that
            its return starts at ``failsafe_timeout_param``.
    """

    name: str
    autopilot: int
    guided_mode: tuple[float, ...]
    mission_mode: tuple[float, ...]
    mission_mode_names: frozenset[str]
    home_item: bool
    takeoff_amsl: bool
    reposition_frame: int
    reposition_amsl: bool
    fix_stands_in: bool
    prearm_prefixes: tuple[str, ...]
    clear_hint: str = ""
    param_bytewise: bool = False
    failsafe_param: str = "FS_GCS_ENABLE"
    failsafe_rtl: float = 1.0
    failsafe_timeout_param: str = "FS_GCS_TIMEOUT"
    gcs_id_param: str = "SYSID_MYGCS"
    rtl_alt_param: str = "RTL_ALT"
    rtl_alt_per_m: float = 100.0
    fence_param: str = "FENCE_ENABLE"
    rtl_pinned: tuple[tuple[str, float], ...] = (("RTL_CONE_SLOPE", 0.0), ("RTL_ALT_TYPE", 0.0))
    failsafe_options_param: str = "FS_OPTIONS"
    failsafe_continue_bits: int = 0b11010  # continue in AUTO (2), landing (8), pilot-controlled modes (16)
    rtl_descend_param: str = ""
    failsafe_delay_param: str = ""

    def first_item(self) -> int:
        """The seq of the mission's first real item (1 after ArduPilot's home, else 0)."""
        return int(self.home_item)


ARDUPILOT = Conventions(
    name="ArduPilot",
    autopilot=mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
    guided_mode=(4.0,),
    mission_mode=(3.0,),
    mission_mode_names=frozenset({"AUTO"}),
    home_item=True,
    takeoff_amsl=False,
    reposition_frame=mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
    reposition_amsl=False,
    fix_stands_in=False,
    prearm_prefixes=("PreArm:", "Arm:"),
    clear_hint=("ArduPilot refuses (MAV_MISSION_ERROR) to clear the mission it is flying in AUTO: switch "
                "the vehicle to another mode (e.g. LOITER or GUIDED) first"),
)
"""ArduPilot (Copter): its custom modes, home at item 0, altitudes above home."""

PX4 = Conventions(
    name="PX4",
    autopilot=mavlink.MAV_AUTOPILOT_PX4,
    guided_mode=(4.0, 3.0),
    mission_mode=(4.0, 4.0),
    mission_mode_names=frozenset({"MISSION"}),
    home_item=False,
    takeoff_amsl=True,
    reposition_frame=mavlink.MAV_FRAME_GLOBAL_INT,
    reposition_amsl=True,
    fix_stands_in=True,
    prearm_prefixes=("Preflight Fail:", "Arming denied", "Preflight"),
    param_bytewise=True,
    failsafe_param="NAV_DLL_ACT",
    failsafe_rtl=2.0,
    failsafe_timeout_param="COM_DL_LOSS_T",
    gcs_id_param="",
    rtl_alt_param="RTL_RETURN_ALT",
    rtl_alt_per_m=1.0,
    fence_param="GF_ACTION",
    rtl_pinned=(("RTL_CONE_ANG", 0.0), ("RTL_TYPE", 0.0)),
    failsafe_options_param="",
    failsafe_continue_bits=0,
    rtl_descend_param="RTL_DESCEND_ALT",
    failsafe_delay_param="COM_FAIL_ACT_T",
)
"""PX4: main and sub modes, item 0 a real item, take-off and reposition altitudes above sea level."""

GENERIC = Conventions(
    name="generic MAVLink",
    autopilot=mavlink.MAV_AUTOPILOT_GENERIC,
    guided_mode=ARDUPILOT.guided_mode,
    mission_mode=ARDUPILOT.mission_mode,
    mission_mode_names=frozenset({"AUTO", "MISSION"}),
    home_item=False,
    takeoff_amsl=False,
    reposition_frame=mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
    reposition_amsl=False,
    fix_stands_in=True,
    prearm_prefixes=("PreArm:",),
)
"""Any other autopilot: MAVLink's common conventions, ArduPilot's mode numbers and parameters."""

_BY_AUTOPILOT = {ARDUPILOT.autopilot: ARDUPILOT, PX4.autopilot: PX4}


def conventions_for(autopilot: int | None) -> Conventions:
    """The table of the vehicle whose HEARTBEAT says ``autopilot`` (:data:`GENERIC` for others and None).

    >>> conventions_for(mavlink.MAV_AUTOPILOT_PX4).name
    'PX4'
    """
    return _BY_AUTOPILOT.get(autopilot, GENERIC) if autopilot is not None else GENERIC
