"""Connect to every device of an IMU-bench rig and report what answers (``rotorbench check``).

The IMU bench (``[rig] kind = "imu"``: hexapod, IMU under test, reference IMU) is opened
through :mod:`drivers.imu_factory`, as the calibration opens it. The hexapod must identify
itself and say whether it moves; it is then stopped (never moved). The IMUs must deliver
samples within the timeout. A simulated bench is opened as a whole (its devices share one
plant and clock); on a real bench each device is opened, checked and closed on its own, so
one failure does not hide the others.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any
from urllib.parse import urlsplit

from drivers.contracts import Clock, MonotonicClock, Sensor
from drivers.errors import DeviceError
from drivers.imu_factory import ROLES, _open_pi_hexapod, _serial_imu, _simulated, open_imu_rig
from drivers.rig_check import DeviceReport, _sensor_answer

__all__ = ["check_imu_rig"]


def _hexapod_answer(hexapod: Any) -> str:
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


def _check_simulated(rig: Any, roles: list[str], timeout_s: float) -> list[DeviceReport]:
    try:
        bench = open_imu_rig(rig)
    except DeviceError as exc:
        return [DeviceReport(r, rig.devices[r].url, False, f"bench did not open: {exc}")
                for r in roles]
    sensors: dict[str, Sensor] = bench.sensors
    try:
        out = [_report("hexapod", rig.devices["hexapod"].url,
                       lambda: _hexapod_answer(bench.hexapod) + " (simulated)")]
        out += [_report(r, rig.devices[r].url,
                        lambda s=sensors[r]: _sensor_answer(s, bench.clock, timeout_s))
                for r in roles if r != "hexapod"]
    finally:
        errors = bench.close()
    if errors:
        out[0] = DeviceReport("hexapod", out[0].url, False,
                              f"{out[0].detail}; closing the bench: {'; '.join(errors)}")
    return out


def _check_one_real(rig: Any, role: str, clock: Clock, timeout_s: float) -> str:
    dev = rig.devices[role]
    scheme = urlsplit(dev.url).scheme
    if role == "hexapod":
        if scheme != "tcp":
            raise DeviceError("expected a PI GCS controller at tcp://host[:port]")
        hexapod = _open_pi_hexapod(rig, dev.url, dev.options, clock,
                                   default_timeout_s=timeout_s)
        try:
            return _hexapod_answer(hexapod)
        finally:
            try:
                hexapod.stop()
            finally:
                hexapod.close()
    if scheme != "serial":
        raise DeviceError("expected serial://<port>")
    sensor = _serial_imu(rig, role, clock, None, 1.0)
    try:
        return _sensor_answer(sensor, clock, timeout_s)
    finally:
        sensor.close()


def check_imu_rig(rig: Any, timeout_s: float = 2.0) -> list[DeviceReport]:
    """One report per device (hexapod, imu, reference_imu), in that order."""
    roles = [r for r in ROLES if r in rig.devices]
    simulated = [r for r in roles if _simulated(rig.devices[r].url)]
    if simulated and len(simulated) < len(roles):
        open_imu_rig(rig).close()  # raises the factory's one-line refusal of the mix
    if simulated:
        return _check_simulated(rig, roles, timeout_s)
    clock = MonotonicClock()
    return [_report(r, rig.devices[r].url, lambda r=r: _check_one_real(rig, r, clock, timeout_s))
            for r in roles]

