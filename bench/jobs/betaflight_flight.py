"""Fly a design with Betaflight's firmware in the loop (its 4.6.0 SITL), in real time.

The pieces, each in its own home: the plant is the design's 6-DOF model and rotors
(``optimizer.flight.plant``); the firmware process, its CLI, its UDP interface and its MSP
receiver are drivers (``drivers.backends.betaflight_sitl``, ``betaflight_cli``,
``sitl_fdm_link``, ``msp_rc_sticks``); the pilot's sticks are ``betaflight_program``. This
module runs them together:

1. configure: launch the firmware in a fresh folder, apply the bench's preamble and the
   user's CLI lines, ``save`` (the firmware exits; ``blackbox_device`` is read at boot);
2. launch it again in the same folder (it reads the saved settings), up to ``LAUNCHES``
   times until its control loop runs (some 4.6.0 launches never start their gyro task);
3. a thread steps the plant at ``DT_S`` in wall-clock time, one FDM packet per tick, and
   drives the rotors with the firmware's answer to the previous packet; the firmware's
   clock follows the host's, so the plant cannot run faster or slower than real time.
   Where the host stalls past ``CATCH_UP_S`` the plant skips the lost time, and while the
   firmware has not answered for ``SILENT_S`` (a firmware process the loaded host did not
   run: 0.5 s was seen) the plant waits for it rather than fly on its frozen motor
   outputs; both are time the plant did not fly, which the real-time factor reports;
4. arm on the MSP receiver (the FC's failsafe stops it if this process dies), spin up held,
   release, and fly the program with the pilot holding the height;
5. whatever happened: disarm (and wait, FDM still flowing, for the blackbox's LOG_END),
   stop the plant, stop the firmware, copy its log out (4.6.0 names it ``LOG00001.BF``
   and overwrites it at every launch), remove the folder.
"""

from __future__ import annotations

import contextlib
import math
import shutil
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from analysis.stick_steps import unit_step_figures
from bench.engine.host_priority import HostPriority
from bench.jobs.betaflight_program import (
    RATE_HOLD_S,
    RATE_STEP_DPS,
    RATE_TOP_DPS,
    SPIN_UP_S,
    STICK_HALF_US,
    HeightPilot,
    Segment,
    program,
)
from bench.jobs.betaflight_tune import pid_scale, tune_lines
from drivers.backends.betaflight_cli import apply_and_save
from drivers.backends.betaflight_sitl import SitlProcess, await_control_loop, find_binary
from drivers.backends.msp_fc import MspClient
from drivers.backends.msp_rc_sticks import MspRcSticks
from drivers.backends.msp_tcp import open_port
from drivers.backends.sitl_fdm_link import FdmLink
from drivers.codecs import msp
from drivers.codecs.msp_rc import ThrottleMap
from drivers.codecs.sitl import MSP_PORT
from drivers.errors import DeviceError
from optimizer.errors import RequestError
from optimizer.flight.maneuvers import STEP_TIME_S, gust_load, gust_tilt, response_figures
from optimizer.flight.plant import ExternalPlant
from optimizer.flight.vehicle import euler_angles

__all__ = ["DT_S", "PREAMBLE", "BetaflightFlight", "fly_betaflight"]

DT_S = 1e-3  # the plant's tick, as the thesis cascade's (1 kHz)
CATCH_UP_S = 0.02  # later than this, the plant skips the time instead of catching up
#: no answer from the firmware for this long: the plant waits for it (module doc); a
#: shorter silence the plant lives through on the last outputs, as the firmware's clock does
SILENT_S = 0.03
LAUNCHES = 3
CONTROL_LOOP_TIMEOUT_S = 2.0
ARM_READY_TIMEOUT_S = 15.0  # gyro calibration + valid RC (0.5 s) on a loaded host
PILOT_PERIOD_S = 0.01
LOG_END_WAIT_S = 0.4  # disarm to the blackbox's LOG_END and fclose (reference: >= 0.3 s)
LOG_NAME = "LOG00001.BF"  # 4.6.0's truncated name, the same at every launch
HOST = "127.0.0.1"
#: the bench's settings, before the user's (docs/flight.md): the log, linear roll and
#: pitch rates (a stick's setpoint is known), no runaway-takeoff trip on a crude spin-up,
#: no 5 s power-on grace before arming (the plant holds the vehicle; 4 s less per flight)
PREAMBLE = (
    "set blackbox_device = VIRTUAL",
    "set runaway_takeoff_prevention = OFF",
    "set pid_process_denom = 2",
    "set pwr_on_arm_grace = 0",
    "set roll_rc_rate = 67",
    "set roll_srate = 67",
    "set roll_expo = 0",
    "set pitch_rc_rate = 67",
    "set pitch_srate = 67",
    "set pitch_expo = 0",
)
#: a flight this far from where it started has gone wrong (not a maneuver of the program)
DIVERGED_M = 30.0
DIVERGED_TILT_RAD = math.radians(100.0)


@dataclass
class BetaflightFlight:
    """What a Betaflight flight gave: figures per maneuver, the hover, how real-time it
    ran, the firmware's identity, the copied log, and the plant's trace."""

    maneuvers: dict[str, dict[str, Any]]
    hover: dict[str, Any]
    realtime: dict[str, Any]
    firmware: dict[str, Any]
    log_path: Path | None
    trace: dict[str, np.ndarray] = field(repr=False, default_factory=dict)
    rate_steps: dict[str, dict[str, Any]] = field(default_factory=dict)


class PlantLoop(threading.Thread):
    """The plant in wall-clock time, one FDM exchange per tick (module doc, step 3)."""

    def __init__(self, plant: ExternalPlant, link: FdmLink) -> None:
        super().__init__(name="betaflight-plant", daemon=True)
        self.plant, self.link = plant, link
        self.gust_start: float | None = None
        self.latest: tuple[float, list[float]] = (0.0, list(plant.state))
        self.error: BaseException | None = None
        self.stalls = 0
        self.lost_s = 0.0
        self.waited_s = 0.0  # the plant waited for a silent firmware
        self.waits: list[float] = []  # each wait's length (s)
        self.wall_s = 0.0
        self.rows: list[tuple[float, ...]] = []
        self._halt = threading.Event()

    def run(self) -> None:
        try:
            self._run()
        except BaseException as exc:  # the main thread raises it at its next look
            self.error = exc

    def _disturbance(self, t: float) -> tuple[tuple[float, float, float],
                                                tuple[float, float, float]]:
        start = self.gust_start
        if start is None:
            return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
        force, torque = gust_load(self.plant.vehicle, t - start)
        return (0.0, force, 0.0), (torque, torque, 0.0)

    def _run(self) -> None:
        plant, link, dt = self.plant, self.link, self.plant.dt
        motors = [0.0] * 4
        motor_us = (1000.0,) * 4
        t0 = start = heard = time.monotonic()
        k = 0
        was_waiting = False
        while not self._halt.is_set():
            waiting = time.monotonic() - heard > SILENT_S
            if not waiting:
                force, moment = self._disturbance(plant.t_s)
                plant.step(motors, force, moment)
            k += 1
            late = time.monotonic() - (t0 + k * dt)
            if late < 0:
                time.sleep(-late)
            elif late > CATCH_UP_S:  # the host stalled: the plant skips the lost time
                self.stalls += 1
                self.lost_s += late
                t0 += late
            s = plant.sensors()
            out = link.exchange(s.gyro_rad_s, s.specific_force_m_s2, s.attitude,
                                t0 + (k + 1) * dt - 2e-4)
            if out is not None and len(out.motor_us) >= 4:
                heard = time.monotonic()
                motor_us = out.motor_us[:4]
                motors = [(u - 1000.0) / 1000.0 for u in motor_us]
            if waiting:
                if not was_waiting:
                    self.waits.append(0.0)
                self.waits[-1] += dt
                self.waited_s += dt
                was_waiting = True
                continue
            was_waiting = False
            state = plant.state
            self.latest = (plant.t_s, state)
            # the wall clock beside the plant's: the log's eRPM is put on it (betaflight_erpm)
            self.rows.append((plant.t_s, *state, *plant.omega, *motor_us, time.monotonic()))
        self.wall_s = time.monotonic() - start

    def stop(self) -> None:
        self._halt.set()
        if self.is_alive() and self is not threading.current_thread():
            self.join(2.0)

    def check(self) -> None:
        if self.error is not None:
            raise self.error


def _configure(binary: Path, workdir: Path, lines: list[tuple[str, str]]) -> None:
    """Launch, apply the CLI lines, ``save``: the firmware exits with them saved (a launch
    whose CLI never answered is launched again: ``SitlProcess.configure_in``)."""

    def apply(sitl: SitlProcess) -> None:
        apply_and_save(HOST, MSP_PORT, lines, "betaflight cli")
        with contextlib.suppress(Exception):
            sitl.proc.wait(3.0)

    SitlProcess.configure_in(binary, workdir, apply)


def _launch_running(binary: Path, workdir: Path) -> tuple[SitlProcess, Any, MspClient]:
    """The saved firmware launched again, its control loop running (module doc, step 2)."""
    why = ""
    for _ in range(LAUNCHES):
        sitl = SitlProcess.launch(binary, workdir=workdir)
        port = None
        try:
            port = open_port(HOST, MSP_PORT, "betaflight", connect_timeout_s=2.0)
            client = MspClient(port, "betaflight", timeout_s=0.5)
            await_control_loop(client, "betaflight", CONTROL_LOOP_TIMEOUT_S)
            return sitl, port, client
        except DeviceError as exc:
            why = str(exc)
            if port is not None:
                port.close()
            sitl.stop(keep=True)
        except BaseException:
            if port is not None:
                port.close()
            sitl.stop(keep=True)
            raise
    raise DeviceError(f"the Betaflight SITL: {LAUNCHES} launches, none ran its control loop "
                      f"({why})")


def fly_betaflight(plant: ExternalPlant, maneuvers: list[str], cli_lines: list[tuple[str, str]],
                   *, rate_steps_s: float, log_to: Path, binary: str | None = None,
                   on_phase: Callable[[str], None] | None = None) -> BetaflightFlight:
    """Fly ``plant`` through ``maneuvers`` (``betaflight_program.BETAFLIGHT_MANEUVERS``)
    and ``rate_steps_s`` of rate steps; the firmware's log is copied to ``log_to``."""
    path = find_binary(binary)
    vehicle = plant.vehicle
    u_hover = vehicle.hover_speed_rad_s / vehicle.omega_max_rad_s
    if u_hover > 0.9:
        raise RequestError(f"{vehicle.label}: hovers at {100 * u_hover:.0f} % of full speed; "
                           "the pilot needs a margin to hold the height (at most 90 %)")
    tell = on_phase or (lambda _text: None)
    workdir = Path(tempfile.mkdtemp(prefix="rotorbench-betaflight-"))
    # the design's scaled PIDs before the user's lines, which may override them
    lines = [("preamble", line) for line in PREAMBLE] + tune_lines(vehicle) + cli_lines
    # the plant and the sticks keep time with the firmware's wall clock: ahead of the
    # machine's other work, as a run on the wall clock is (bench.engine.host_priority)
    with HostPriority(True):
        return _fly_firmware(path, workdir, lines, plant, maneuvers, rate_steps_s, log_to,
                             tell, u_hover)


def _fly_firmware(path: Path, workdir: Path, lines: list[tuple[str, str]],
                  plant: ExternalPlant, maneuvers: list[str], rate_steps_s: float,
                  log_to: Path, tell: Callable[[str], None], u_hover: float
                  ) -> BetaflightFlight:
    """The flight itself: launch, arm, fly, and the firmware stopped whatever happens; its
    directory removed, unless its launch failed (the error names the log there)."""
    vehicle = plant.vehicle
    sitl = port = link = loop = rc = client = None
    firmware: dict[str, Any] = {}
    marks: list[tuple[Segment, float]] = []
    release = [math.nan]
    keep = False  # the firmware's directory, with its log, when its launch failed
    try:
        tell("configuring the firmware")
        try:
            _configure(path, workdir, lines)
            sitl, port, client = _launch_running(path, workdir)
        except DeviceError:
            keep = True  # the error names its log there
            raise
        firmware = client.firmware()
        link = FdmLink(HOST)
        loop = PlantLoop(plant, link)
        loop.start()
        tell("waiting for the firmware to allow arming")
        rc = MspRcSticks(client, rate_hz=50.0, host_timeout_s=1.0, failsafe_delay_s=1.0,
                         arm_timeout_s=ARM_READY_TIMEOUT_S)
        loop.check()
        rc.arm()
        tell("armed: flying")
        _fly(plant, loop, rc, u_hover, maneuvers, rate_steps_s, marks, release)
        status = client.request(msp.Request(msp.MSP_STATUS_EX))
        firmware["cycle_time_us"] = getattr(status, "cycle_time_us", None)
    finally:
        try:
            disarmed = _safe_end(rc, loop, client)
        finally:
            for thing in (link, port):
                if thing is not None:
                    with contextlib.suppress(Exception):
                        thing.close()
            if sitl is not None:
                sitl.stop(keep=True)
            copied = _copy_log(workdir / LOG_NAME, log_to)
            if not keep:
                shutil.rmtree(workdir, ignore_errors=True)
    firmware["disarmed_at_end"] = disarmed
    firmware["simplified_master_multiplier"] = pid_scale(vehicle)
    assert loop is not None
    return _result(plant, loop, link, marks, release[0], firmware, copied)


def _safe_end(rc: MspRcSticks | None, loop: PlantLoop | None, client: Any) -> bool | None:
    """Disarm, let the blackbox end its log with FDM still flowing, stop the plant; never
    raises. Returns whether the firmware said it was disarmed (None: never armed)."""
    disarmed = None
    try:
        if rc is not None:
            with contextlib.suppress(Exception):
                rc.close()
            with contextlib.suppress(Exception):
                status = client.request(msp.Request(msp.MSP_STATUS_EX))
                disarmed = not getattr(status, "armed", True)
            time.sleep(LOG_END_WAIT_S)
    finally:
        if loop is not None:
            loop.stop()
    return disarmed


def _copy_log(log: Path, to: Path) -> Path | None:
    """The firmware's blackbox log copied to ``to`` (None when it wrote none)."""
    try:
        if not (log.is_file() and log.stat().st_size):
            return None
        to.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(log, to)
    except OSError:
        return None
    return to


def _fly(plant: ExternalPlant, loop: PlantLoop, rc: MspRcSticks, u_hover: float,
         maneuvers: list[str], rate_steps_s: float, marks: list[tuple[Segment, float]],
         release: list[float]) -> None:
    """Spin up held, release, then each segment's sticks with the pilot on the throttle."""
    throttle = ThrottleMap()
    pilot = HeightPilot(u_hover, plant.vehicle.gravity_m_s2)

    def stick(u: float) -> int:
        return throttle.rc_for(1000.0 + 1000.0 * min(1.0, max(0.0, u)))

    t_arm = loop.latest[0]
    while loop.latest[0] < t_arm + SPIN_UP_S:  # the rotors reach the hover command
        loop.check()
        rc.set_sticks(1500, 1500, 1500, stick(u_hover), angle=True)
        time.sleep(PILOT_PERIOD_S)
    release[0] = loop.latest[0]
    plant.held = False
    last_t = release[0]
    for seg in program(maneuvers, rate_steps_s, release[0]):
        first = True
        while True:
            loop.check()
            t, s = loop.latest
            if t >= seg.end_s:
                break
            tilt = _tilt(s)
            if abs(s[2]) > DIVERGED_M or tilt > DIVERGED_TILT_RAD:
                raise DeviceError(f"the flight diverged at t = {t - release[0]:.2f} s after "
                                  f"release ({seg.label}): height {s[2]:.1f} m, tilt "
                                  f"{math.degrees(tilt):.0f} deg")
            u = pilot.command(s[2], s[5], math.cos(tilt), max(0.0, t - last_t))
            last_t = t
            rc.set_sticks(seg.roll_us, seg.pitch_us, 1500, stick(u), angle=seg.angle)
            if first:
                marks.append((seg, t))
                if seg.gust:
                    loop.gust_start = t
                first = False
            time.sleep(PILOT_PERIOD_S)


def _tilt(s: list[float]) -> float:
    """The angle between body up and navigation up, of the state's quaternion."""
    qx, qy = s[7], s[8]
    return math.acos(max(-1.0, min(1.0, 1.0 - 2.0 * (qx * qx + qy * qy))))


def _result(plant: ExternalPlant, loop: PlantLoop, link: FdmLink | None,
            marks: list[tuple[Segment, float]], release_s: float, firmware: dict[str, Any],
            log_path: Path | None) -> BetaflightFlight:
    rows = np.array(loop.rows) if loop.rows else np.empty((0, 23))
    t = rows[:, 0]
    euler = euler_angles(rows[:, 7:11]) if rows.size else np.empty((0, 3))
    omega = rows[:, 14:18]
    motor_us = rows[:, 18:22]
    sat = np.any((motor_us <= 1055.5) | (motor_us >= 1999.5), axis=1)
    figures: dict[str, dict[str, Any]] = {}
    for seg, t_mark in marks:
        if seg.maneuver is None:
            continue
        t_lead = t_mark - STEP_TIME_S
        keep = (t >= t_lead) & (t < seg.end_s)
        signal = (euler[keep, 0] if seg.maneuver.axis == "roll" else
                  euler[keep, 1] if seg.maneuver.axis == "pitch" else
                  gust_tilt(euler[keep, 0], euler[keep, 1]))
        out = response_figures(seg.maneuver, t[keep] - t_lead, signal, sat[keep])
        out["commanded_deg"] = math.degrees(seg.maneuver.amplitude)
        figures[seg.label] = out
    hover = _hover(plant, t, omega, motor_us, rows, marks)
    sim_s = float(t[-1] - t[0]) if t.size > 1 else 0.0
    realtime = {"tick_ms": plant.dt * 1e3, "sim_s": sim_s, "wall_s": loop.wall_s,
                "real_time_factor": sim_s / loop.wall_s if loop.wall_s > 0 else None,
                "stalls": loop.stalls, "skipped_s": loop.lost_s,
                "waited_for_firmware_s": loop.waited_s,
                "waits": len(loop.waits),
                "longest_wait_s": max(loop.waits, default=0.0),
                "fdm_sent": link.sent if link else 0,
                "answered_pct": 100.0 * link.answered / link.sent if link and link.sent else None,
                "flown_s": float(t[-1] - release_s) if t.size and math.isfinite(release_s)
                else 0.0}
    trace = {"t_s": t, "euler_rad": euler, "position_m": rows[:, 1:4], "omega_rad_s": omega,
             "motor_us": motor_us, "wall_s": rows[:, 22]}
    return BetaflightFlight(figures, hover, realtime, firmware, log_path, trace,
                            _rate_steps(rows, marks))


def _rate_steps(rows: np.ndarray, marks: list[tuple[Segment, float]]) -> dict[str, Any]:
    """The acro rate steps read on the plant's body rate, per axis: each step's (and each
    return to zero's, as a log's steps count both) 10-90 % rise and overshoot over the rate
    its stick asks, from the level before it, and their medians. The clock starts at the
    stick, so the rise takes in what the firmware's RC smoothing does to the stick; a step
    over which the host stalled (wall clock jumped past ``CATCH_UP_S``) is left out, as
    ``analysis.stick_steps`` leaves out a log's gaps."""
    if not rows.size:
        return {}
    t, wall = rows[:, 0], rows[:, 22]
    # Betaflight's roll (right side down) and pitch (nose down) rates of the model's
    # forward-left-up body rates: p and q
    rate = {"roll": rows[:, 11], "pitch": rows[:, 12]}
    steps: dict[str, list[tuple[float, float]]] = {"roll": [], "pitch": []}
    axis = ""
    for seg, t_mark in marks:
        if seg.label == "rate step":
            axis, stick = ("roll", seg.roll_us) if seg.roll_us != 1500 else \
                ("pitch", seg.pitch_us)
            asked = math.radians((stick - 1500) / STICK_HALF_US * RATE_TOP_DPS)
        elif seg.label == "rate pause" and axis:
            asked = 0.0
        else:
            continue
        keep = (t >= t_mark) & (t < min(seg.end_s, t_mark + RATE_HOLD_S))
        before = (t >= t_mark - 0.02) & (t < t_mark)
        if keep.sum() < 10 or not before.any() or \
                np.max(np.diff(wall[before | keep])) > CATCH_UP_S:
            continue
        start = float(np.mean(rate[axis][before]))
        if abs(asked - start) < math.radians(RATE_STEP_DPS) / 2:
            continue
        steps[axis].append(unit_step_figures(t[keep] - t_mark,
                                             (rate[axis][keep] - start) / (asked - start)))
    out: dict[str, Any] = {}
    for axis, got in steps.items():
        ok = [(r, o) for r, o in got if math.isfinite(r)]
        out[axis] = {"steps": len(ok),
                     "rise_ms": float(np.median([r for r, _ in ok])) * 1e3 if ok else None,
                     "overshoot_pct": float(np.median([o for _, o in ok])) if ok else None,
                     "rises_ms": [1e3 * r for r, _ in ok]}
    return out


def _hover(plant: ExternalPlant, t: np.ndarray, omega: np.ndarray, motor_us: np.ndarray,
           rows: np.ndarray, marks: list[tuple[Segment, float]]) -> dict[str, Any]:
    """The hover's last second: rotor speed, throttle as the flight model reads it
    (between idle and full speed), the firmware's motor output, the height error."""
    hov = [(seg, tm) for seg, tm in marks if seg.label == "hover"]
    if not hov:
        return {}
    seg, _ = hov[0]
    keep = (t >= seg.end_s - 1.0) & (t < seg.end_s)
    if not keep.any():
        return {}
    w = float(np.mean(omega[keep]))
    lo, hi = plant.rotors.omega_min, plant.rotors.omega_max
    return {"rpm": w * 60.0 / (2.0 * math.pi), "throttle": (w - lo) / (hi - lo),
            "motor_us": float(np.mean(motor_us[keep])),
            "altitude_error_m": float(np.mean(np.abs(rows[keep, 3])))}


#: CLI commands that end the session or the process (a ``save`` line, as ``diff`` output
#: ends, is left out: the bench saves, once, itself)
REFUSED_CLI = ("exit", "defaults", "reboot", "bl", "dfu", "msc")
CLI_FILE_MAX_BYTES = 256 * 1024


def read_cli_file(path: Path) -> list[tuple[str, str]]:
    """The lines of a Betaflight CLI file (``diff``/``dump`` output works): blank lines and
    ``#`` comments left out; each kept line with ``file:line`` to name it in a refusal.
    Refuses (``RequestError``, one line) an unreadable or non-ASCII file and the commands
    that would end the session or the process (``REFUSED_CLI``)."""
    try:
        data = path.read_bytes()[: CLI_FILE_MAX_BYTES + 1]
    except OSError as exc:
        raise RequestError(f"--betaflight-cli {path}: cannot read it "
                           f"({exc.strerror or exc})") from None
    if len(data) > CLI_FILE_MAX_BYTES:
        raise RequestError(f"--betaflight-cli {path}: larger than "
                           f"{CLI_FILE_MAX_BYTES // 1024} kB: not a CLI file")
    try:
        text = data.decode("ascii")
    except UnicodeDecodeError as exc:
        raise RequestError(f"--betaflight-cli {path}: not ASCII text (byte {exc.start}): "
                           "the firmware's CLI reads ASCII lines") from None
    out = []
    for n, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        if not line.isprintable():
            raise RequestError(f"--betaflight-cli {path}:{n}: a control character in "
                               f"{line!r}")
        word = line.split()[0].lower()
        if word == "save":
            continue
        if word in REFUSED_CLI:
            raise RequestError(f"--betaflight-cli {path}:{n}: {word!r} is not taken (the bench "
                               "saves the settings itself, then restarts the firmware)")
        out.append((f"{path}:{n}", line))
    return out
