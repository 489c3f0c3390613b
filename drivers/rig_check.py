"""Connect to every device of a rig and report what answers (``rotorbench check``).

Each device is opened on its own (one failure does not hide the others) and asked for a
sign of life without moving anything: sensors must deliver samples within the timeout;
ESCs must identify themselves (MSP), be heard on the bus (VESC status broadcasts, a
DroneCAN node) or have their output task running (NI-DAQmx). Nothing is armed.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any
from urllib.parse import urlsplit

import numpy as np

from drivers.contracts import MonotonicClock, Sensor
from drivers.errors import DeviceError
from drivers.factory import ROLES, device_specs, open_rig

__all__ = ["DeviceReport", "check_rig"]


@dataclass(frozen=True)
class DeviceReport:
    role: str
    url: str
    ok: bool
    detail: str


def _sensor_answer(sensor: Sensor, clock: Any, timeout_s: float) -> str:
    """Read until samples arrive (or the timeout): rate and the latest values."""
    sensor.read_block()  # drop what came before (e.g. while other devices were checked)
    t0 = clock.now()
    n, last = 0, None
    deadline = time.monotonic() + timeout_s
    while True:
        clock.sleep(0.02)
        b = sensor.read_block()
        if len(b):
            n += len(b)
            last = b
        if (n >= 3 and clock.now() - t0 >= 0.1) or time.monotonic() > deadline \
                or clock.now() - t0 > timeout_s:
            break
    if last is None:
        raise DeviceError(f"no samples within {timeout_s:g} s")
    dt = max(clock.now() - t0, 1e-9)
    values = ", ".join(f"{k}={float(v[-1]):.4g}" for k, v in last.values.items()
                       if np.size(v))
    return f"{n / dt:.0f} samples/s; {values}"


def _check_sim(rig: Any, timeout_s: float) -> list[DeviceReport]:
    out = []
    with open_rig(rig) as r:
        info = r.esc.describe()
        out.append(DeviceReport("esc", info.url, True, f"{info.model} (simulated)"))
        for role, sensor in r.sensors.items():
            try:
                detail = _sensor_answer(sensor, r.clock, timeout_s)
                out.append(DeviceReport(role, rig.devices[role].url, True, detail))
            except DeviceError as exc:
                out.append(DeviceReport(role, rig.devices[role].url, False, str(exc)))
    return out


def check_rig(rig: Any, timeout_s: float = 2.0) -> list[DeviceReport]:
    """One report per device role, in rig order (esc, load_cell, power, rpm)."""
    schemes = {urlsplit(d.url).scheme for d in rig.devices.values()}
    if schemes <= {"sim", "replay"}:
        return _check_sim(rig, timeout_s)
    from drivers.device_openers import DeviceOpener

    specs = device_specs(rig)
    for spec in specs.values():  # as the runner refuses it: one line, not a FAIL per device
        if spec.scheme == "sim":
            raise spec.fail("", "sim:// devices run on the simulated clock and cannot be "
                                "mixed with hardware; use the wire-level simulated devices "
                                "(serial://sim/..., can://sim/...) instead")
    clock = MonotonicClock()
    opener = DeviceOpener(rig, clock)
    opener.plan_nidaq(list(specs.values()))
    reports: list[DeviceReport] = []
    opened: list[Any] = []
    try:
        for role in ROLES:
            spec = specs[role]
            try:
                if role == "esc":
                    esc = opener.open_esc(spec)
                    opened.append(esc)
                    detail = opener.probe_esc(role, timeout_s)
                elif spec.scheme == "replay":
                    from drivers.replay import ReplaySensor

                    rep = ReplaySensor.from_url(spec.url, clock)
                    detail = f"recording of {rep.t_s.size} samples ({', '.join(rep.values)})"
                else:
                    sensor = opener.open_sensor(spec)
                    opened.append(sensor)
                    detail = _sensor_answer(sensor, clock, timeout_s)
                reports.append(DeviceReport(role, spec.url, True, detail))
            except DeviceError as exc:
                reports.append(DeviceReport(role, spec.url, False, str(exc)))
    finally:
        for dev in reversed(opened):
            try:
                dev.close()
            except Exception:  # closing after a check: keep going
                pass
        try:
            opener.close()
        except DeviceError:
            pass
    return reports
