"""Real autopilots for the opt-in ``sitl`` tests: PX4 and ArduCopter SITL instances, and an observer.

The builds are made from source outside the repository (the workspace's SITL build scripts):
``PX4_SITL_DIR`` is the PX4 build root (``PX4-Autopilot/build/px4_sitl_default/bin/px4`` and
``run/loopback_bind.so`` under it), ``ARDUPILOT_SITL_DIR`` the ArduPilot one
(``ardupilot/build/sitl/bin/arducopter``).
Every instance is started through the loopback shim (its sockets bind to 127.0.0.1 only) and
ended by its own PID (:meth:`Instances.close`).

Instance ``i`` of PX4 is system ``i + 1`` with its offboard link sending to UDP ``14540 + i`` (the
bridge listens there) and its GCS link sending to UDP 14550 (the :class:`Observer` listens there).
Instance ``i`` of ArduCopter is system ``i + 1`` with SERIAL0 on TCP ``5760 + 10 i`` (it boots only
once a client connects there: the observer does) and SERIAL1 on TCP ``5762 + 10 i`` (the bridge).
"""

from __future__ import annotations

import os
import signal
import subprocess
import threading
import time
from pathlib import Path

import numpy as np

from bridge.geo import Home, enu_to_geodetic, geodetic_to_enu
from bridge.simulated.peer import m, mavutil

__all__ = ["Instances", "Observer", "px4_paths", "ardupilot_paths", "PX4_GCS_URL", "CMAC_HOME", "home_apart",
           "reported_closest", "reported_at"]

PX4_GCS_URL = "udpin:127.0.0.1:14550"
CMAC_HOME = (-35.3633, 149.165, 584.0)
"""Where the ArduCopter instances start (``--home``)."""


def home_apart(base: tuple[float, float, float], index: int,
               spacing_m: float = 10.0) -> tuple[float, float, float]:
    """Instance ``index``'s home: ``spacing_m`` East of the previous one's from ``base`` (lat, lon, alt)."""
    lat_deg, lon_deg, _ = enu_to_geodetic(Home(lat_deg=base[0], lon_deg=base[1], alt_m=base[2]),
                                          index * spacing_m, 0.0, 0.0)
    return (round(lat_deg, 7), round(lon_deg, 7), base[2])


def reported_closest(observers: dict, origin: tuple[float, float, float],
                     step_s: float = 0.05) -> tuple[float, tuple[int, int], float]:
    """The closest two vehicles came on their own reported positions (what the observers recorded).

    Each vehicle's GLOBAL_POSITION_INT (latitude, longitude, height above its home; the homes at one
    altitude) in the East-North-Up frame of ``origin``, interpolated on a common clock: the distance
    (3-D, metres), the pair of system ids, the clock (monotonic s).
    """
    home = Home(lat_deg=origin[0], lon_deg=origin[1], alt_m=origin[2])
    tracks = {}
    for sid, observer in observers.items():
        rows = observer.positions.get(sid, [])
        if len(rows) < 2:
            continue
        tracks[sid] = np.array([(t, *geodetic_to_enu(home, lat, lon, origin[2])[:2], z)
                                for t, z, lat, lon in rows])
    best = (float("inf"), (-1, -1), float("nan"))
    if len(tracks) < 2:
        return best
    clock = np.arange(max(t[0, 0] for t in tracks.values()), min(t[-1, 0] for t in tracks.values()), step_s)
    points = {sid: np.column_stack([np.interp(clock, t[:, 0], t[:, c]) for c in (1, 2, 3)])
              for sid, t in tracks.items()}
    ids = sorted(points)
    for a, first in enumerate(ids):
        for second in ids[a + 1:]:
            gaps = np.linalg.norm(points[first] - points[second], axis=1)
            k = int(np.argmin(gaps))
            if gaps[k] < best[0]:
                best = (float(gaps[k]), (first, second), float(clock[k]))
    return best


def reported_at(observers: dict, origin: tuple[float, float, float], sid: int,
                clock_s: float) -> tuple[float, float, float]:
    """Vehicle ``sid``'s reported position (East, North, Up of ``origin``, metres) at ``clock_s``."""
    home = Home(lat_deg=origin[0], lon_deg=origin[1], alt_m=origin[2])
    rows = np.array([(t, *geodetic_to_enu(home, lat, lon, origin[2])[:2], z)
                     for t, z, lat, lon in observers[sid].positions[sid]])
    return tuple(round(float(np.interp(clock_s, rows[:, 0], rows[:, c])), 2) for c in (1, 2, 3))


def px4_paths(root: Path) -> tuple[Path, Path]:
    """``(px4 binary, loopback shim)`` of a PX4 build root."""
    return root / "PX4-Autopilot/build/px4_sitl_default/bin/px4", root / "run/loopback_bind.so"


def ardupilot_paths(root: Path) -> tuple[Path, Path]:
    """``(arducopter binary, loopback shim)`` of an ArduPilot build root."""
    return root / "ardupilot/build/sitl/bin/arducopter", root / "run/loopback_bind.so"


class Instances:
    """SITL processes started by this test, each ended by its own PID.

    Args:
        log_dir: Each instance's stdout and stderr go to a file here.
    """

    def __init__(self, log_dir: Path) -> None:
        self.log_dir = log_dir
        self.processes: list[subprocess.Popen] = []
        log_dir.mkdir(parents=True, exist_ok=True)

    def __enter__(self) -> Instances:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _start(self, name: str, argv: list[str], cwd: Path, env: dict[str, str]) -> subprocess.Popen:
        log = (self.log_dir / f"{name}.log").open("wb")
        process = subprocess.Popen(argv, cwd=cwd, env={**os.environ, **env}, stdout=log,
                                   stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
        log.close()
        self.processes.append(process)
        return process

    def start_px4(self, root: Path, instance: int,
                  home: tuple[float, float, float] | None = None) -> subprocess.Popen:
        """PX4 SIH quadrotor instance ``instance`` (fresh parameters: its ``rootfs/<i>`` is removed first),
        at ``home`` (lat, lon, alt; ``None``: PX4's default)."""
        binary, shim = px4_paths(root)
        build = binary.parent.parent
        rootfs = build / "rootfs" / str(instance)
        if rootfs.exists():
            subprocess.run(["rm", "-rf", str(rootfs)], check=True)
        env = {"PX4_SIM_MODEL": "sihsim_quadx", "PX4_SIMULATOR": "sihsim", "PX4_SYS_AUTOSTART": "10040",
               "LD_PRELOAD": str(shim)}
        if home is not None:
            env |= {"PX4_HOME_LAT": str(home[0]), "PX4_HOME_LON": str(home[1]), "PX4_HOME_ALT": str(home[2])}
        return self._start(f"px4-{instance}", [str(binary), "-i", str(instance), "-d"], build, env)

    def start_arducopter(self, root: Path, instance: int, home: tuple[float, float, float] = CMAC_HOME,
                         params: dict[str, float] | None = None) -> subprocess.Popen:
        """ArduCopter instance ``instance`` at ``home`` (lat, lon, alt), in its own working folder.

        ``params`` are set at boot beside its system id (e.g. the simulator's weather: ``SIM_WIND_SPD``,
        ``SIM_WIND_TURB``, and its late GPS: ``SIM_GPS_LAG_MS``).
        """
        binary, shim = ardupilot_paths(root)
        work = self.log_dir / f"arducopter-{instance}"
        work.mkdir(exist_ok=True)
        extra = "".join(f"{name} {value:g}\n" for name, value in (params or {}).items())
        (work / "sysid.parm").write_text(f"SYSID_THISMAV {instance + 1}\n{extra}")
        defaults = root / "ardupilot/Tools/autotest/default_params/copter.parm"
        argv = [str(binary), "--model", "+", "--speedup", "1", f"-I{instance}", "--wipe",
                "--defaults", f"{defaults},{work / 'sysid.parm'}", "--home", ",".join(map(str, home)) + ",0"]
        return self._start(f"arducopter-{instance}", argv, work, {"LD_PRELOAD": str(shim)})

    def close(self) -> None:
        """End every instance by its own PID: SIGTERM, then SIGKILL after 10 s."""
        for process in self.processes:
            if process.poll() is None:
                os.kill(process.pid, signal.SIGTERM)
        for process in self.processes:
            try:
                process.wait(timeout=10.0)
            except subprocess.TimeoutExpired:
                os.kill(process.pid, signal.SIGKILL)
                process.wait(timeout=10.0)


class Observer:
    """An independent ground station that records what the vehicles say (pymavlink, its own link).

    Per system id: GLOBAL_POSITION_INT as ``(monotonic s, relative_alt_m, lat_deg, lon_deg)`` and its own
    clock (``time_boot_ms``), the HEARTBEAT mode (and when it changed) and armed flag, the HOME_POSITION
    altitude, MISSION_CURRENT and STATUSTEXT.

    Args:
        url: Its link (PX4's GCS port, or an ArduCopter's SERIAL1).
        ask: System ids to ask for GLOBAL_POSITION_INT (5 Hz), HOME_POSITION and MISSION_CURRENT.
    """

    def __init__(self, url: str, ask: tuple[int, ...] = ()) -> None:
        self.positions: dict[int, list[tuple[float, float, float, float]]] = {}
        self.modes: dict[int, str] = {}
        self.modes_seen: dict[int, set[str]] = {}
        self.mode_changes: dict[int, list[tuple[float, str]]] = {}
        self.boot_s: dict[int, list[tuple[float, float]]] = {}
        self.armed: dict[int, bool] = {}
        self.home_alt_m: dict[int, float] = {}
        self.mission_seq: dict[int, int] = {}
        self.texts: dict[int, list[str]] = {}
        self._conn = mavutil.mavlink_connection(url, source_system=250, source_component=190)
        self._ask, self._asked_s = ask, 0.0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name=f"observer {url}", daemon=True)
        self._thread.start()

    def close(self) -> None:
        """Stop listening and close the link."""
        self._stop.set()
        self._thread.join(timeout=2.0)
        self._conn.close()

    def _request(self) -> None:
        for sid in self._ask:
            for message_id, period_us in ((m.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 200_000),
                                          (m.MAVLINK_MSG_ID_HOME_POSITION, 1_000_000),
                                          (m.MAVLINK_MSG_ID_MISSION_CURRENT, 500_000)):
                self._conn.mav.command_long_send(sid, 1, m.MAV_CMD_SET_MESSAGE_INTERVAL, 0, message_id,
                                                 period_us, 0, 0, 0, 0, 0)

    def _loop(self) -> None:
        while not self._stop.is_set():
            if self._ask and time.monotonic() - self._asked_s > 5.0:
                self._asked_s = time.monotonic()
                try:
                    self._request()
                except OSError:
                    pass
            try:
                msg = self._conn.recv_match(blocking=True, timeout=0.1)
            except OSError:
                time.sleep(0.1)
                continue
            if msg is None or msg.get_srcComponent() != 1:
                continue
            sid, kind = msg.get_srcSystem(), msg.get_type()
            if kind == "GLOBAL_POSITION_INT" and (msg.lat or msg.lon):  # 0, 0: no fix yet, no position
                self.positions.setdefault(sid, []).append(
                    (time.monotonic(), msg.relative_alt / 1000.0, msg.lat / 1e7, msg.lon / 1e7))
                self.boot_s.setdefault(sid, []).append((time.monotonic(), msg.time_boot_ms / 1000.0))
            elif kind == "HEARTBEAT" and msg.type != m.MAV_TYPE_GCS:
                mode = mavutil.mode_string_v10(msg)
                if self.modes.get(sid) != mode:
                    self.mode_changes.setdefault(sid, []).append((time.monotonic(), mode))
                self.modes[sid] = mode
                self.modes_seen.setdefault(sid, set()).add(self.modes[sid])
                self.armed[sid] = bool(msg.base_mode & m.MAV_MODE_FLAG_SAFETY_ARMED)
            elif kind == "HOME_POSITION":
                self.home_alt_m[sid] = msg.altitude / 1000.0
            elif kind == "MISSION_CURRENT":
                self.mission_seq[sid] = msg.seq
            elif kind == "STATUSTEXT":
                self.texts.setdefault(sid, []).append(msg.text)

    def entered(self, sid: int, mode: str, after_s: float) -> float | None:
        """When (monotonic s) ``sid``'s HEARTBEAT first said ``mode`` after ``after_s`` (None: not yet)."""
        return next((t for t, seen in self.mode_changes.get(sid, []) if t > after_s and seen == mode), None)

    def vehicle_s(self, sid: int, clock_s: float) -> float:
        """``sid``'s own clock (``time_boot_ms``, seconds) at monotonic ``clock_s``, from its positions.

        A loaded machine slows SITL's clock (lockstep): timeouts are the autopilot's, on its clock.
        """
        rows = np.array(self.boot_s[sid])
        return float(np.interp(clock_s, rows[:, 0], rows[:, 1]))

    def wait(self, condition, timeout_s: float) -> bool:  # noqa: ANN001 - a callable of the observer
        """Poll ``condition(self)`` until true or ``timeout_s`` passed; whether it held."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if condition(self):
                return True
            time.sleep(0.1)
        return condition(self)
