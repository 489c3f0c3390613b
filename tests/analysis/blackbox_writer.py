"""Test helper: a blackbox *encoder*, written from the format's documentation, so the
decoder can be checked by round trip (values in -> bytes -> values out).

It writes what Betaflight 4.x writes for a quad with DShot, bidirectional DShot and a
battery monitor: the header lines, I frames (predictors none, minmotor, motor[0],
vbatref; unsigned/signed VB, neg 14-bit), P frames (increment, straight line, previous,
average 2; tag2_3s32, tag8_4s16, a tag8_8svb group), an S frame, a SYNC_BEEP event and
LOG_END. Each encoding picks the shortest layout, as the firmware does.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MARKER = b"H Product:Blackbox flight data recorder by Nicholas Sherlock\n"


def uvb(v: int) -> bytes:
    v &= 0xFFFFFFFF
    out = bytearray()
    while v >= 0x80:
        out.append((v & 0x7F) | 0x80)
        v >>= 7
    out.append(v)
    return bytes(out)


def svb(v: int) -> bytes:
    return uvb(((v << 1) ^ (v >> 31)) & 0xFFFFFFFF)


def neg14(v: int) -> bytes:
    return uvb((-v) & 0x3FFF)


def _fits(v: int, bits: int) -> bool:
    return -(1 << (bits - 1)) <= v < (1 << (bits - 1))


def tag8_8svb(values: list[int]) -> bytes:
    if len(values) == 1:
        return svb(values[0])
    head = sum(1 << k for k, v in enumerate(values) if v)
    return bytes([head]) + b"".join(svb(v) for v in values if v)


def tag2_3s32(v: list[int]) -> bytes:
    if all(_fits(x, 2) for x in v):
        return bytes([((v[0] & 3) << 4) | ((v[1] & 3) << 2) | (v[2] & 3)])
    if all(_fits(x, 4) for x in v):
        return bytes([0x40 | (v[0] & 0xF), ((v[1] & 0xF) << 4) | (v[2] & 0xF)])
    if all(_fits(x, 6) for x in v):
        return bytes([0x80 | (v[0] & 0x3F), v[1] & 0x3F, v[2] & 0x3F])
    sizes = [next(n for n in (1, 2, 3, 4) if _fits(x, 8 * n)) for x in v]
    lead = 0xC0 | sum((n - 1) << (2 * k) for k, n in enumerate(sizes))
    return bytes([lead]) + b"".join((x & ((1 << (8 * n)) - 1)).to_bytes(n, "little")
                                    for x, n in zip(v, sizes, strict=True))


def tag2_3svariable(v: list[int]) -> bytes:
    if all(_fits(x, 2) for x in v):
        return bytes([((v[0] & 3) << 4) | ((v[1] & 3) << 2) | (v[2] & 3)])
    if _fits(v[0], 5) and _fits(v[1], 5) and _fits(v[2], 4):
        return bytes([0x40 | ((v[0] & 0x1F) << 1) | ((v[1] & 0x1F) >> 4),
                      ((v[1] & 0xF) << 4) | (v[2] & 0xF)])
    if _fits(v[0], 8) and _fits(v[1], 7) and _fits(v[2], 7):
        return bytes([0x80 | ((v[0] & 0xFF) >> 2), ((v[0] & 3) << 6) | ((v[1] & 0x7F) >> 1),
                      ((v[1] & 1) << 7) | (v[2] & 0x7F)])
    return tag2_3s32(v)


def tag8_4s16(v: list[int]) -> bytes:
    sel, nibbles = 0, []
    for k, x in enumerate(v):
        if x == 0:
            code, n = 0, 0
        elif _fits(x, 4):
            code, n = 1, 1
        elif _fits(x, 8):
            code, n = 2, 2
        else:
            code, n = 3, 4
        sel |= code << (2 * k)
        u = x & ((1 << (4 * n)) - 1)
        nibbles += [(u >> (4 * (n - 1 - j))) & 0xF for j in range(n)]
    if len(nibbles) % 2:
        nibbles.append(0)
    return bytes([sel]) + bytes((nibbles[j] << 4) | nibbles[j + 1]
                                for j in range(0, len(nibbles), 2))


@dataclass
class Layout:
    """A Betaflight-like field set: names, signedness, predictors and encodings."""

    names: list[str]
    signed: list[int]
    i_pred: list[int]
    i_enc: list[int]
    p_pred: list[int]
    p_enc: list[int]


def quad_layout(motors: int = 4, *, full: bool = False) -> Layout:
    """Betaflight's main fields for a quad; ``full`` adds the rest a 4.5/4.6 log carries by
    default (axisD, axisF, baroAlt and rssi in the tag8_8svb group, gyroUnfilt, accSmooth,
    debug[0..7])."""
    rows: list[tuple[str, int, int, int, int, int]] = [  # name, signed, Ipred, Ienc, Ppred, Penc
        ("loopIteration", 0, 0, 1, 6, 9), ("time", 0, 0, 1, 2, 0)]
    rows += [(f"axisP[{k}]", 1, 0, 0, 1, 0) for k in range(3)]
    rows += [(f"axisI[{k}]", 1, 0, 0, 1, 7) for k in range(3)]
    if full:
        rows += [(f"axisD[{k}]", 1, 0, 0, 1, 0) for k in range(2)]
        rows += [(f"axisF[{k}]", 1, 0, 0, 1, 0) for k in range(3)]
    rows += [(f"rcCommand[{k}]", int(k < 3), 0, 0 if k < 3 else 1, 1, 8) for k in range(4)]
    rows += [(f"setpoint[{k}]", 1, 0, 0, 1, 8) for k in range(4)]
    rows += [("vbatLatest", 0, 9, 3, 1, 6), ("amperageLatest", 1, 0, 0, 1, 6)]
    if full:
        rows += [("baroAlt", 1, 0, 0, 1, 6), ("rssi", 0, 0, 1, 1, 6)]
    rows += [(f"gyroADC[{k}]", 1, 0, 0, 3, 0) for k in range(3)]
    if full:
        rows += [(f"gyroUnfilt[{k}]", 1, 0, 0, 3, 0) for k in range(3)]
        rows += [(f"accSmooth[{k}]", 1, 0, 0, 3, 0) for k in range(3)]
        rows += [(f"debug[{k}]", 1, 0, 0, 3, 0) for k in range(8)]
    rows += [(f"motor[{k}]", 0, 11 if k == 0 else 5, 1 if k == 0 else 0, 3, 0)
             for k in range(motors)]
    rows += [(f"eRPM[{k}]", 0, 0, 1, 1, 0) for k in range(motors)]
    cols = list(zip(*rows, strict=True))
    return Layout(*[list(c) for c in cols])  # type: ignore[arg-type]


ENCODERS = {0: lambda v: svb(v[0]), 1: lambda v: uvb(v[0]), 3: lambda v: neg14(v[0]),
            6: tag8_8svb, 7: tag2_3s32, 8: tag8_4s16, 9: lambda v: b"", 10: tag2_3svariable}
SIZES = {7: 3, 8: 4, 10: 3}


def encode_fields(values: list[int], encodings: list[int]) -> bytes:
    out, i = bytearray(), 0
    while i < len(values):
        enc = encodings[i]
        n = SIZES.get(enc, 1)
        if enc == 6:
            while i + n < len(values) and n < 8 and encodings[i + n] == 6:
                n += 1
        out += ENCODERS[enc](values[i:i + n])
        i += n
    return bytes(out)


@dataclass
class Settings:
    i_interval: int = 32
    p_interval: int = 2  # Betaflight 4.x writes it bare: every 2nd iteration
    vbatref: int = 1620
    motor_output: tuple[int, int] = (158, 2047)
    motor_poles: int = 14
    firmware: str = "Betaflight 4.5.1 (77d01ba3b) STM32F7X2"
    high_resolution: int = 0


def header(layout: Layout, s: Settings) -> bytes:
    def line(name: str, value: object) -> bytes:
        return f"H {name}:{value}\n".encode()

    def csv(v: list[int] | list[str]) -> str:
        return ",".join(map(str, v))

    return b"".join([
        MARKER, line("Data version", 2), line("I interval", s.i_interval),
        line("P interval", s.p_interval), line("P ratio", s.i_interval // s.p_interval),
        line("Field I name", csv(layout.names)), line("Field I signed", csv(layout.signed)),
        line("Field I predictor", csv(layout.i_pred)), line("Field I encoding",
                                                            csv(layout.i_enc)),
        line("Field P predictor", csv(layout.p_pred)), line("Field P encoding",
                                                            csv(layout.p_enc)),
        line("Field S name", "flightModeFlags,stateFlags,failsafePhase,rxSignalReceived,"
                             "rxFlightChannelsValid"),
        line("Field S signed", "0,0,0,0,0"), line("Field S predictor", "0,0,0,0,0"),
        line("Field S encoding", "1,1,1,1,1"),
        line("Firmware type", "Cleanflight"), line("Firmware revision", s.firmware),
        line("minthrottle", 1070), line("maxthrottle", 2000), line("vbatref", s.vbatref),
        line("motorOutput", f"{s.motor_output[0]},{s.motor_output[1]}"),
        line("gyro_scale", "0x3f800000"), line("motor_poles", s.motor_poles),
        line("blackbox_high_resolution", s.high_resolution), line("looptime", 125)])


def _trunc_half(s: int) -> int:
    return int(s / 2) if abs(s) < (1 << 52) else (abs(s) // 2) * (1 if s >= 0 else -1)


def _predict(pred: int, k: int, layout: Layout, s: Settings, cur: list[int],
             p1: list[int] | None, p2: list[int] | None) -> int:
    if pred == 0:
        return 0
    if pred == 1:
        return p1[k] if p1 else 0
    if pred == 2:
        return 2 * p1[k] - p2[k] if p1 and p2 else 0
    if pred == 3:
        return _trunc_half(p1[k] + p2[k]) if p1 and p2 else 0
    if pred == 4:
        return 1070  # the header's minthrottle
    if pred == 5:
        return cur[layout.names.index("motor[0]")]
    if pred == 9:
        return s.vbatref
    if pred == 11:
        return s.motor_output[0]
    raise ValueError(pred)


def main_frames(rows: np.ndarray, layout: Layout, s: Settings) -> list[bytes]:
    """Each row (one main frame's values, the layout's order) as I or P frame bytes; an
    I frame where ``loopIteration`` is a multiple of the I interval."""
    out: list[bytes] = []
    p1: list[int] | None = None
    p2: list[int] | None = None
    for row in rows.tolist():
        is_i = row[0] % s.i_interval == 0 or p1 is None
        preds, encs = (layout.i_pred, layout.i_enc) if is_i else (layout.p_pred, layout.p_enc)
        deltas = []
        for k, v in enumerate(row):
            if preds[k] == 6:  # increment: nothing written
                deltas.append(0)
                continue
            deltas.append(v - _predict(preds[k], k, layout, s, row, p1, p2))
        out.append((b"I" if is_i else b"P") + encode_fields(deltas, encs))
        if is_i:
            p1 = p2 = row
        else:
            p1, p2 = row, p1
    return out


def flight_rows(n: int, layout: Layout, s: Settings, seed: int = 0) -> np.ndarray:
    """Plausible values: time in µs at 2 kHz logging with jitter, noisy gyro and
    setpoint, motors between idle and full, eRPM, battery sag."""
    rng = np.random.default_rng(seed)
    period_us = 125 * s.p_interval
    it = np.arange(n, dtype=np.int64) * s.p_interval
    t = 1_000_000 + it * 125 + rng.integers(-3, 4, n)
    t[0] = 1_000_000
    rows = np.zeros((n, len(layout.names)), np.int64)
    col = {name: k for k, name in enumerate(layout.names)}
    rows[:, col["loopIteration"]] = it
    rows[:, col["time"]] = t
    ph = np.arange(n) * period_us * 1e-6
    for k in range(3):
        sp = (300 * np.sin(2 * np.pi * (0.5 + k) * ph)).astype(np.int64)
        rows[:, col[f"setpoint[{k}]"]] = sp
        rows[:, col[f"gyroADC[{k}]"]] = sp + rng.integers(-40, 41, n)
        rows[:, col[f"axisP[{k}]"]] = rng.integers(-200, 200, n)
        rows[:, col[f"axisI[{k}]"]] = np.cumsum(rng.integers(-3, 4, n))
        rows[:, col[f"rcCommand[{k}]"]] = sp // 2
    rows[:, col["setpoint[3]"]] = 400 + (200 * np.sin(ph)).astype(np.int64)
    rows[:, col["rcCommand[3]"]] = 1400
    rows[:, col["vbatLatest"]] = 1650 - np.arange(n) // 5000
    rows[:, col["amperageLatest"]] = 1500 + rng.integers(-50, 50, n)
    for name, k in col.items():  # the full layout's other fields: noise of their size
        if name.startswith(("axisD", "axisF", "gyroUnfilt", "accSmooth", "debug", "baroAlt")):
            rows[:, k] = rng.integers(-2000, 2000, n)
        elif name == "rssi":
            rows[:, k] = rng.integers(0, 1024, n)
    m = 0
    while f"motor[{m}]" in col:
        rows[:, col[f"motor[{m}]"]] = 900 + (600 * np.sin(ph + m)).astype(np.int64) + \
            rng.integers(-20, 21, n)
        rows[:, col[f"eRPM[{m}]"]] = 250 + (150 * np.sin(ph + m)).astype(np.int64)
        m += 1
    return rows


def blackbox_log(rows: np.ndarray, layout: Layout | None = None, s: Settings | None = None,
                 *, end: bool = True) -> bytes:
    layout = layout or quad_layout()
    s = s or Settings()
    body = main_frames(rows, layout, s)
    slow = b"S" + b"".join(uvb(v) for v in (0, 0, 0, 1, 1))
    beep = b"E\x00" + uvb(1_000_000)
    tail = b"E\xffEnd of log\x00" if end else b""
    return header(layout, s) + beep + slow + b"".join(body) + tail
