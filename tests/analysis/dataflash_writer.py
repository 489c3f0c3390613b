"""Test helper: an ArduPilot DataFlash (.bin) *writer* from the format (LogStructure.h):
FMT messages, then IMU (two instances), RATE, RCOU, ESC (its FMT written lazily, just
before its first message, as ArduPilot does) and BAT messages with known values."""

from __future__ import annotations

import struct

import numpy as np

HEAD = b"\xa3\x95"
STRUCT = {"a": "64s", "b": "b", "B": "B", "h": "h", "H": "H", "i": "i", "I": "I", "f": "f",
          "d": "d", "n": "4s", "N": "16s", "Z": "64s", "c": "h", "C": "H", "e": "i",
          "E": "I", "L": "i", "M": "B", "q": "q", "Q": "Q"}
TYPES = {  # name: (type id, format, columns)
    "FMT": (128, "BBnNZ", "Type,Length,Name,Format,Columns"),
    "IMU": (129, "QBffffffIIfBBHH", "TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ,EG,EA,T,GH,AH,"
                                    "GHz,AHz"),
    "RATE": (130, "Qfffffffffffff", "TimeUS,RDes,R,ROut,PDes,P,POut,YDes,Y,YOut,ADes,A,AOut,"
                                    "AOutSlew"),
    "RCOU": (131, "QHHHHHHHHHHHHHH", "TimeUS," + ",".join(f"C{k}" for k in range(1, 15))),
    "ESC": (132, "QBffffcfcf", "TimeUS,Instance,RPM,RawRPM,Volt,Curr,Temp,CTot,MotTemp,Err"),
    "BAT": (133, "QBfffffcf", "TimeUS,Instance,Volt,VoltR,Curr,CurrTot,EnrgTot,Temp,Res"),
}


def _struct(fmt: str) -> struct.Struct:
    return struct.Struct("<" + "".join(STRUCT[c] for c in fmt))


def fmt_message(name: str) -> bytes:
    tid, fmt, cols = TYPES[name]
    length = 3 + _struct(fmt).size
    return HEAD + bytes([128]) + _struct("BBnNZ").pack(
        tid, length, name.encode(), fmt.encode(), cols.encode())


def message(name: str, *values: object) -> bytes:
    tid, fmt, _ = TYPES[name]
    return HEAD + bytes([tid]) + _struct(fmt).pack(*values)


def flight(n_imu: int = 4000, seed: int = 0) -> tuple[bytes, dict[str, np.ndarray]]:
    """A log at 400 Hz IMU (instance 0 and 1), RATE at 400 Hz, RCOU at 50 Hz, ESC at
    10 Hz for 4 motors, BAT at 10 Hz; returns the bytes and the values written."""
    rng = np.random.default_rng(seed)
    t = 5_000_000 + np.arange(n_imu, dtype=np.int64) * 2500
    gyro = rng.normal(0, 0.5, (n_imu, 3)).astype(np.float32)
    sp = rng.normal(0, 30, (n_imu, 3)).astype(np.float32)
    out = [fmt_message(k) for k in ("FMT", "IMU", "RATE", "RCOU", "BAT")]
    esc_rpm, bat_v, rcou = [], [], []
    for k in range(n_imu):
        out.append(message("IMU", int(t[k]), 0, *gyro[k].tolist(), 0, 0, -9.8, 0, 0, 40.0, 0,
                           0, 400, 400))
        out.append(message("IMU", int(t[k]) + 100, 1, 9.0, 9.0, 9.0, 0, 0, -9.8, 0, 0, 40.0,
                           0, 0, 400, 400))
        out.append(message("RATE", int(t[k]) + 50, sp[k, 0], 0, 0, sp[k, 1], 0, 0, sp[k, 2],
                           0, 0, 0, 0, 0, 0))
        if k % 8 == 0:
            ch = [1100 + (k // 8) % 800 + m for m in range(4)] + [0] * 10
            rcou.append((t[k] + 60, ch[:4]))
            out.append(message("RCOU", int(t[k]) + 60, *ch))
        if k % 40 == 0:
            if k == 0:
                out.append(fmt_message("ESC"))  # lazily, before its first message
            for m in range(4):
                rpm = float(5000 + k + 100 * m)
                esc_rpm.append((t[k] + 70, m, rpm))
                out.append(message("ESC", int(t[k]) + 70, m, rpm, rpm, 16.0, 10.0, 4000, 0.0,
                                   0, 0.0))
            v = 16.8 - k * 1e-4
            bat_v.append((t[k] + 80, v))
            out.append(message("BAT", int(t[k]) + 80, 0, v, v, 12.5, 100.0, 1.0, 2500, 0.01))
            out.append(message("BAT", int(t[k]) + 80, 1, 5.0, 5.0, 1.0, 0.0, 0.0, 2500, 0.0))
    return b"".join(out), {"t_us": t, "gyro": gyro, "sp": sp,
                           "esc": np.array(esc_rpm, dtype=float),
                           "bat": np.array(bat_v, dtype=float),
                           "rcou_t": np.array([r[0] for r in rcou], dtype=float),
                           "rcou": np.array([r[1] for r in rcou], dtype=float)}
