"""PX4 ULog (``.ulg``) through pyulog (BSD-3, the ``flightlogs`` extra).

Topics read (PX4 ``msg/`` units, FRD body axes): ``sensor_combined.gyro_rad`` (every
sample, the time base; ``vehicle_angular_velocity.xyz`` when absent),
``vehicle_rates_setpoint`` roll/pitch/yaw (rad/s), ``actuator_motors.control`` (normalised
-1..1, NaN = stopped), ``actuator_outputs.output`` (the output driver's units, PWM µs on
a PWM/DShot multirotor), ``esc_status.esc[i].esc_rpm`` (rpm), ``battery_status``
``voltage_v`` and ``current_a`` (-1 = unknown, kept as NaN). Only these topics are
parsed (pyulog's name filter), so memory follows them, not the file.
"""

from __future__ import annotations

import contextlib
import io
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from analysis.errors import LogError
from analysis.extras import import_extra
from analysis.flightlogs.flight_log import AXES, FlightLog, holder

__all__ = ["MAGIC", "MAX_BYTES", "TOPICS", "read_ulog"]

MAGIC = b"ULog\x01\x12\x35"
TOPICS = ("sensor_combined", "vehicle_angular_velocity", "vehicle_rates_setpoint",
          "actuator_motors", "actuator_outputs", "esc_status", "battery_status")
MAX_BYTES = 1 << 31  # pyulog holds the chosen topics in memory: refuse beyond 2 GiB
_PWM_RANGE = (500.0, 2500.0)  # an output channel wholly inside is a pulse width in µs


def _topic(ulog: Any, name: str) -> Any | None:
    """Instance 0 of a topic, or None if the log lacks it."""
    for d in ulog.data_list:
        if d.name == name and d.multi_id == 0 and len(d.data.get("timestamp", ())):
            return d
    return None


def _increasing(t: np.ndarray) -> np.ndarray:
    """Rows whose time is past every time before them."""
    if len(t) < 2:
        return np.ones(len(t), bool)
    return np.concatenate([[True], t[1:] > np.maximum.accumulate(t)[:-1]])


def read_ulog(path: str | Path) -> FlightLog:
    """The log's flight columns; ``LogError`` if it is no readable ULog or has no gyro."""
    path = Path(path)
    size = path.stat().st_size
    if size > MAX_BYTES:
        raise LogError(f"{path}: {size / 2**30:.1f} GiB is more than the {MAX_BYTES >> 30} GiB "
                       "this reader takes (pyulog reads a whole topic into memory); cut the "
                       "log with PX4's tools first")
    pyulog = import_extra("pyulog", "flightlogs", "reading PX4 ULog files")
    said = io.StringIO()  # pyulog prints its warnings: keep them for one note
    try:  # an open file: pyulog leaves its own handle open when it raises
        with open(path, "rb") as fh, contextlib.redirect_stdout(said):
            ulog = pyulog.ULog(fh, list(TOPICS), True)
    except OSError as exc:
        raise LogError(f"{path}: cannot read ({exc.strerror or exc})") from None
    except Exception as exc:  # pyulog raises bare exceptions on bad files
        raise LogError(f"{path}: not a readable ULog ({type(exc).__name__}: "
                       f"{str(exc)[:120]})") from None
    gyro = _topic(ulog, "sensor_combined")
    gyro_fields, gyro_src = ["gyro_rad[0]", "gyro_rad[1]", "gyro_rad[2]"], "sensor_combined"
    if gyro is None:
        gyro = _topic(ulog, "vehicle_angular_velocity")
        gyro_fields, gyro_src = ["xyz[0]", "xyz[1]", "xyz[2]"], "vehicle_angular_velocity"
    if gyro is None:
        raise LogError(f"{path}: the ULog has neither sensor_combined nor "
                       "vehicle_angular_velocity (no gyro to take the time from)")
    lacks = [f for f in gyro_fields if f not in gyro.data]
    if lacks:
        raise LogError(f"{path}: {gyro_src} has no {', '.join(lacks)} (another PX4 version's "
                       "layout, or a damaged format definition)")
    t_us = gyro.data["timestamp"].astype(np.int64)
    rows = _increasing(t_us)  # a damaged log can step back: keep the rows that go forward
    t_us = t_us[rows]
    t0 = int(t_us[0])
    base = (t_us - t0) * 1e-6
    info = ulog.msg_info_dict
    log = FlightLog({}, {
        "format": "ulog", "firmware": "PX4",
        "ver_sw": str(info.get("ver_sw", "")), "sys_name": str(info.get("sys_name", "")),
        "time_base": f"{gyro_src}.timestamp, 0 = {t0} µs after the log's clock origin",
        "hold": "slower topics held at their last value (NaN before their first)",
        "dropouts": len(ulog.dropouts),
        "file_corruption": bool(getattr(ulog, "file_corruption", False)),
    })
    log.add("t_s", base, "s", f"{gyro_src}.timestamp")
    for axis, f in zip(AXES, gyro_fields, strict=True):
        log.add(f"gyro_{axis}_rad_s", gyro.data[f][rows], "rad/s", f"{gyro_src}.{f}")
    problems = [line for line in said.getvalue().splitlines() if line.strip()]
    if problems:
        log.meta["notes"] = [f"pyulog reported {len(problems)} problems reading the file "
                             f"(a damaged log?), the first: {problems[0][:100]}"]
    if not rows.all():
        log.meta.setdefault("notes", []).append(
            f"dropped {int((~rows).sum())} gyro samples whose time did not go forward")

    def held(topic: Any) -> Callable[[np.ndarray], np.ndarray]:
        """Hold any field of this topic onto the gyro times (sorted once per topic)."""
        t = (topic.data["timestamp"].astype(np.int64) - t0) * 1e-6
        order = np.argsort(t, kind="stable")
        h = holder(base, t[order])
        return lambda values: h(np.asarray(values)[order])

    sp = _topic(ulog, "vehicle_rates_setpoint")
    if sp is not None:
        h = held(sp)
        for axis, f in zip(AXES, ("roll", "pitch", "yaw"), strict=True):
            if f in sp.data:
                log.add(f"rate_sp_{axis}_rad_s", h(sp.data[f]), "rad/s",
                        f"vehicle_rates_setpoint.{f}")
    motors = _topic(ulog, "actuator_motors")
    if motors is not None:
        h = held(motors)
        for i in range(12):
            f = f"control[{i}]"
            if f in motors.data and np.isfinite(motors.data[f]).any():
                log.add(f"motor{i + 1}_norm", h(motors.data[f]), "normalised -1..1 (NaN = stopped)",
                        f"actuator_motors.{f}")
    outputs = _topic(ulog, "actuator_outputs")
    if outputs is not None:  # noutputs from the log; fields another version lacks are skipped
        n = int(np.max(outputs.data.get("noutputs", [16])))
        h = held(outputs)
        for i in range(min(n, 16)):
            if f"output[{i}]" not in outputs.data:
                continue
            v = outputs.data[f"output[{i}]"]
            pwm = bool(np.all((v >= _PWM_RANGE[0]) & (v <= _PWM_RANGE[1])))
            log.add(f"output{i + 1}_us" if pwm else f"output{i + 1}", h(v),
                    "µs" if pwm else "output driver's units", f"actuator_outputs.output[{i}]")
    esc = _topic(ulog, "esc_status")
    if esc is not None:
        h = held(esc)
        for i in range(min(int(np.max(esc.data.get("esc_count", [0]))), 8)):
            if f"esc[{i}].esc_rpm" in esc.data:
                log.add(f"motor{i + 1}_rpm", h(esc.data[f"esc[{i}].esc_rpm"]), "rpm",
                        f"esc_status.esc[{i}].esc_rpm")
    bat = _topic(ulog, "battery_status")
    if bat is not None:
        h = held(bat)
        if "voltage_v" in bat.data:
            log.add("voltage_v", h(bat.data["voltage_v"]), "V", "battery_status.voltage_v")
        if "current_a" in bat.data:
            cur = bat.data["current_a"].astype(float)
            cur = np.where(cur == -1.0, np.nan, cur)  # -1: unknown
            log.add("current_a", h(cur), "A", "battery_status.current_a")
    return log
