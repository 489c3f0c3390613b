"""Connect to every device of a rig, whatever the bench, and report what answers.

``rotorbench check`` and the console's Devices panel call :func:`check_rig`. Each device
is asked for a sign of life without moving anything: sensors must deliver samples within
the timeout; ESCs must identify themselves (MSP, VESC UART), be heard on the bus (VESC
status broadcasts, a DroneCAN node) or have their output task running (NI-DAQmx); a
hexapod must identify itself and say whether it moves, and is then stopped. Nothing is
armed. Real devices are opened one by one (one failure does not hide the others); a rig
whose devices share one simulated world on its own clock is opened as a whole.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from drivers.contracts import Clock, Esc, Hexapod, Sensor
from drivers.errors import DeviceError
from drivers.factory import IMU_ROLES, ROLES, open_context, open_devices
from drivers.rig_view import RigView

__all__ = ["DeviceReport", "check_rig"]


@dataclass(frozen=True)
class DeviceReport:
    role: str
    url: str
    ok: bool
    detail: str


RATE_WINDOW_S = 0.5  # rig time (and wall time, on a paced rig) over which a rate is measured
RATE_MIN_SAMPLES = 10  # a rate from fewer samples is mostly the host's scheduling


def sensor_answer(sensor: Sensor, clock: Clock, timeout_s: float) -> str:
    """Read until samples arrive (or the timeout): rate and the latest values.

    The rate is taken from the samples' own stamps over at least ``RATE_WINDOW_S`` of rig
    time and ``RATE_MIN_SAMPLES`` samples: a short window counted on the host clock said
    27 samples/s for a 100 Hz IMU whose poller had just started on a busy machine. A rig
    whose clock runs ``time_scale`` times the wall clock (a paced simulated rig) is read
    for ``RATE_WINDOW_S`` of wall time too: its 0.5 s of rig time at 6x are 0.08 s of wall
    time, which one scheduling hiccup of a busy machine took 60 % of (39 of 100 Hz read).
    """
    sensor.read_block()  # drop what came before (e.g. while other devices were checked)
    wall_window = RATE_WINDOW_S if getattr(clock, "time_scale", None) else 0.0
    t0, w0 = clock.now(), time.monotonic()
    n, last, first_t, last_t = 0, None, None, None
    deadline = w0 + timeout_s
    while True:
        clock.sleep(0.02)
        b = sensor.read_block()
        if len(b):
            n += len(b)
            last = b
            first_t = float(b.t_s[0]) if first_t is None else first_t
            last_t = float(b.t_s[-1])
        rig_s, wall_s = clock.now() - t0, time.monotonic() - w0
        enough = (n >= RATE_MIN_SAMPLES and rig_s >= RATE_WINDOW_S) or rig_s > timeout_s
        if (enough and wall_s >= wall_window) or time.monotonic() > deadline:
            break
    if last is None:
        raise DeviceError(f"no samples within {timeout_s:g} s")
    span = (last_t or 0.0) - (first_t or 0.0)
    rate = (n - 1) / span if n >= 2 and span > 0 else n / max(clock.now() - t0, 1e-9)
    values = ", ".join(f"{k}={float(v[-1]):.4g}" for k, v in last.values.items()
                       if np.size(v))
    return f"{rate:.0f} samples/s; {values}"


def hexapod_answer(hexapod: Hexapod) -> str:
    """Identification and motion state, then a stop (the platform must end still)."""
    info = hexapod.describe()
    moving = hexapod.is_moving()
    hexapod.stop()
    return f"{info.model}; {'was moving' if moving else 'at rest'}; stopped"


def _report(role: str, url: str, answer: Callable[[], str]) -> DeviceReport:
    try:
        return DeviceReport(role, url, True, answer())
    except DeviceError as exc:
        return DeviceReport(role, url, False, str(exc))


def _answer(dev: Any, clock: Clock, timeout_s: float, probe: Callable[[], str]) -> str:
    """A device's sign of life, by what it is (its contract)."""
    if isinstance(dev, Hexapod):
        return hexapod_answer(dev)
    if isinstance(dev, Esc):
        return probe()
    return sensor_answer(dev, clock, timeout_s)


def _check_world(ctx: Any, roles: list[str], timeout_s: float) -> list[DeviceReport]:
    """Devices that share one simulated world and clock: opened (and closed) together; a
    world that does not open is the rig file's error (raised, one line)."""
    r = open_devices(ctx)

    def answer(dev: Any) -> str:
        if isinstance(dev, Sensor):
            return sensor_answer(dev, r.clock, timeout_s)
        what = hexapod_answer(dev) if isinstance(dev, Hexapod) else dev.describe().model
        return f"{what} (simulated)"

    try:
        out = [_report(role, ctx.specs[role].url, lambda d=r.devices[role]: answer(d))
               for role in roles]
    finally:
        r.raise_close_errors = False
        errors = r.close()
    if errors:
        out[0] = DeviceReport(out[0].role, out[0].url, False,
                              f"{out[0].detail}; closing the rig: {'; '.join(errors)}")
    return out


def check_rig(rig: RigView, timeout_s: float = 2.0) -> list[DeviceReport]:
    """One report per device role, in the bench's order (esc, load_cell, power, rpm;
    hexapod, imu, reference_imu)."""
    ctx = open_context(rig)  # a rig that mixes what cannot mix is refused in one line
    roles = [r for r in (*ROLES, *IMU_ROLES) if r in ctx.specs]
    roles += [r for r in ctx.specs if r not in roles]
    if ctx.one_world:
        return _check_world(ctx, roles, timeout_s)
    ctx.open_timeout_s = timeout_s
    reports: list[DeviceReport] = []
    opened: list[Any] = []

    def one(role: str) -> str:
        spec = ctx.specs[role]
        if spec.scheme == "replay":
            from drivers.replay import ReplaySensor

            rep = ReplaySensor.from_url(spec.url, ctx.clock)
            return f"recording of {rep.t_s.size} samples ({', '.join(rep.values)})"
        dev = ctx.open(spec)
        opened.append(dev)
        return _answer(dev, ctx.clock, timeout_s, lambda: ctx.probe(role, timeout_s))

    try:
        reports = [_report(role, ctx.specs[role].url, lambda r=role: one(r)) for role in roles]
    finally:
        for dev in reversed(opened):
            try:
                if isinstance(dev, Hexapod):
                    dev.stop()
                dev.close()
            except Exception:  # closing after a check: keep going
                pass
        try:
            ctx.close()
        except DeviceError:
            pass
    return reports
