"""Betaflight / INAV blackbox logs (``.bbl``, ``.bfl``, ``.BF``, ``.txt``), decoded here.

Written from the documented format (Betaflight's "Blackbox logging internals" and the
firmware's field definitions), not from a GPL decoder (orangebox, blackbox-tools and the
log viewer are GPL-3; none is imported or copied). The file is read in windows
(``WINDOW`` bytes), never whole: frames are delimited by one regular expression
(``blackbox_frames``), decoded field by field across all frames of a window
(``blackbox_encodings``), then predicted segment-wise (``blackbox_predict``).

A file may hold several logs, each from an ``H Product:Blackbox flight data recorder``
line to the next (bytes between logs are ignored). Kept per log, SI units: ``time`` (µs,
unwrapped) -> ``t_s``; ``gyroADC`` -> rad/s; ``setpoint[0..2]`` -> rad/s, ``setpoint[3]``
-> throttle 0..1; ``motor[]`` -> normalised 0..1 over ``motorOutput`` and the raw value
(DShot command, or µs for analog outputs); ``eRPM[]`` -> rpm over ``motor_poles``;
``vbatLatest`` -> V, ``amperageLatest`` -> A.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import BinaryIO

import numpy as np

from analysis.errors import LogError
from analysis.flightlogs.blackbox_encodings import ENCODING_NAMES, decode_group
from analysis.flightlogs.blackbox_frames import (
    EVENTS,
    UnsupportedEncodingError,
    frame_body,
    frame_regex,
    groups,
)
from analysis.flightlogs.blackbox_header import HEADER_MAX, Header, parse_header
from analysis.flightlogs.blackbox_predict import Predictor
from analysis.flightlogs.flight_log import AXES, MAX_ROWS, FlightLog

__all__ = ["MARKER", "MAX_ROWS", "WINDOW", "find_logs", "read_blackbox"]

MARKER = b"H Product:Blackbox flight data recorder by Nicholas Sherlock\n"
WINDOW = 8 << 20  # bytes read and decoded at a time
_TAIL = 1024  # frames are < 256 bytes: a frame starting this far from a window's end is whole
_GARBAGE, _I, _P, _E, _OTHER = 0, 1, 2, 3, 4
_FLAGS = ("_is_i", "_resumes")
_MAX_JUMP_US = 10_000_000  # a main frame this far ahead of the last is corrupt
_MAX_JUMP_ITERATIONS = 5000
_MARKER_BYTES = [bytes([c]) for c in b"IPSGHE"]  # every frame and event starts with one


def find_logs(fh: BinaryIO, size: int) -> list[tuple[int, int]]:
    """(start, end) byte offsets of every log in the file, found in windows. A marker
    across two windows is found in their seam (the last bytes of one and the first of the
    next), not by copying each window behind the last one's tail."""
    starts: list[int] = []
    offset, keep = 0, len(MARKER) - 1
    prev = b""
    while offset < size:
        fh.seek(offset)
        window = fh.read(WINDOW)
        for base, chunk in ((offset - len(prev), prev + window[:keep]), (offset, window)):
            i = chunk.find(MARKER)
            while i >= 0:
                starts.append(base + i)
                i = chunk.find(MARKER, i + 1)
        offset += WINDOW
        prev = window[-keep:]
    starts = sorted(set(starts))
    return list(zip(starts, [*starts[1:], size], strict=False))


class _Columns:
    """The run columns of one log, gathered window by window: only these main-frame
    fields (and motor[0], which other motors' I frames predict from) are predicted."""

    def __init__(self, head: Header, where: str) -> None:
        names = head.frames["I"].names
        if names[:2] != ["loopIteration", "time"]:
            raise LogError(f"{where}: main frames start with {names[:2]}, not loopIteration, "
                           "time (not a Betaflight/INAV flight log?)")
        wanted = ["loopIteration", "time"]
        wanted += [f"gyroADC[{k}]" for k in range(3)] + [f"setpoint[{k}]" for k in range(4)]
        wanted += [f"motor[{k}]" for k in range(8)] + [f"eRPM[{k}]" for k in range(8)]
        wanted += ["vbatLatest", "vbat", "amperageLatest", "amperage"]
        self.keep = [n for n in wanted if n in names]
        self.fields = [names.index(n) for n in self.keep]
        self.index = {n: k for k, n in enumerate(self.keep)}  # name -> column of m
        self.parts: dict[str, list[np.ndarray]] = {n: [] for n in [*self.keep, *_FLAGS]}

    def add(self, m: np.ndarray, is_i: np.ndarray, resumes: np.ndarray) -> None:
        """Rows of main frames, with which are I frames and how many LOGGING_RESUME
        events came before each."""
        for n, k in self.index.items():
            self.parts[n].append(m[:, k].copy())
        self.parts["_is_i"].append(is_i.astype(np.int64))
        self.parts["_resumes"].append(resumes.astype(np.int64))

    def get(self, name: str) -> np.ndarray:
        parts = self.parts[name]
        return np.concatenate(parts) if parts else np.zeros(0, np.int64)


def _decode(buf: np.ndarray, starts: np.ndarray, encodings: list[int], column: np.ndarray
            ) -> np.ndarray:
    """Decode every field of these frames (to find where each ends), keeping the fields
    that have a ``column`` (>= 0) in the returned values."""
    out = np.zeros((len(starts), int(column.max()) + 1), np.int64)
    pos = starts + 1
    for enc, idx in groups(encodings):
        values, pos = decode_group(buf, pos, enc, len(idx))
        for j, f in enumerate(idx):
            if column[f] >= 0:
                out[:, column[f]] = values[:, j]
    return out


def _read_log(fh: BinaryIO, start: int, end: int, where: str, max_rows: int
              ) -> FlightLog:
    fh.seek(start)
    head = parse_header(fh.read(min(HEADER_MAX, end - start)), where)
    if "I" not in head.frames or "P" not in head.frames:
        raise LogError(f"{where}: the header defines no I and P frame fields "
                       "(no main frames to decode)")
    version = head.int("Data version", 2)
    bodies: dict[bytes, bytes] = {}
    for letter, fdef in head.frames.items():
        if version < 2 and 8 in fdef.encoding:
            raise LogError(f"{where}: Data version {version} packs tag8_4s16 the old way, "
                           "which this decoder does not read")
        try:
            bodies[letter.encode()] = frame_body(fdef.encoding)
        except UnsupportedEncodingError as exc:
            enc = int(exc.args[0])
            raise LogError(f"{where}: {letter} frames use encoding {enc} "
                           f"({ENCODING_NAMES.get(enc, 'unknown')}), which this decoder does "
                           "not read") from None
    rx = frame_regex(bodies)
    cols = _Columns(head, where)
    predictor = Predictor(head, where, cols.fields)
    i_def, p_def = head.frames["I"], head.frames["P"]
    column = np.full(len(i_def.names), -1)
    column[cols.fields] = np.arange(len(cols.fields))
    nf = len(cols.fields)
    offset, carry = start + head.length, b""
    rows = garbage_bytes = garbage_runs = dropped_p = resumes = 0
    events: dict[str, int] = {}
    ended = truncated_rows = False
    markers = np.frombuffer(b"IPSGHE", np.uint8)
    while True:
        fh.seek(offset)
        fresh = fh.read(min(WINDOW, end - offset))
        offset += len(fresh)
        chunk = carry + fresh
        last = offset >= end
        if not chunk:
            break
        if not any(m in chunk for m in _MARKER_BYTES):
            # no frame starts in this window (erased flash, a zero-filled tail): all of it
            # is one garbage run, found by memchr at memory speed, not by the regex engine
            garbage_runs, garbage_bytes, carry = garbage_runs + 1, garbage_bytes + len(chunk), b""
            if last:
                break
            continue
        items = rx.findall(chunk)
        lengths = np.fromiter(map(len, items), np.int64, len(items))
        starts = np.cumsum(lengths) - lengths
        buf = np.frombuffer(chunk + bytes(16), np.uint8)
        first = buf[starts]
        kind = np.full(len(items), _OTHER, np.int8)
        kind[first == ord("I")] = _I
        kind[first == ord("P")] = _P
        kind[first == ord("E")] = _E
        # a one-byte item is a marker whose frame did not decode; a run that does not
        # start with a marker is bytes between frames: both are garbage
        kind[(lengths == 1) | ~np.isin(first, markers)] = _GARBAGE
        end_at = len(items)
        log_end = [k for k in np.flatnonzero(kind == _E) if items[k][1] == 255]
        if log_end:
            end_at, ended = int(log_end[0]) + 1, True
        elif not last:
            # the next window starts at the last I frame that is surely whole here (a
            # segment never spans two windows); with none, at the last whole item, and
            # P frames there wait for an I frame
            near = starts < len(chunk) - _TAIL
            i_near = np.flatnonzero((kind == _I) & near)
            if len(i_near) and i_near[-1] > 0:
                end_at = int(i_near[-1])
            elif near.any():
                end_at = int(np.flatnonzero(near)[-1]) + 1
        k, st = kind[:end_at], starts[:end_at]
        bad = k == _GARBAGE
        garbage_runs += int(bad.sum())
        garbage_bytes += int(lengths[:end_at][bad].sum())
        resume = np.zeros(len(k), np.int64)
        for e in np.flatnonzero(k == _E):
            name = EVENTS.get(items[e][1], str(items[e][1]))
            events[name] = events.get(name, 0) + 1
            resume[e] = name == "LOGGING_RESUME"
        resume = np.cumsum(resume) + resumes
        resumes = int(resume[-1]) if len(resume) else resumes
        idx = np.arange(len(k))
        last_i = np.maximum.accumulate(np.where(k == _I, idx, -1)) if len(k) else idx
        last_bad = np.maximum.accumulate(np.where(bad, idx, -1)) if len(k) else idx
        p_ok = (k == _P) & (last_i > last_bad)
        dropped_p += int(((k == _P) & ~p_ok).sum())
        m_idx = np.flatnonzero((k == _I) | p_ok)
        is_i = k[m_idx] == _I
        m = np.zeros((len(m_idx), nf), np.int64)
        m[is_i] = _decode(buf, st[m_idx[is_i]], i_def.encoding, column)
        m[~is_i] = _decode(buf, st[m_idx[~is_i]], p_def.encoding, column)
        seg = np.maximum.accumulate(np.where(is_i, np.arange(len(m_idx)), 0)) if len(
            m_idx) else np.zeros(0, np.int64)
        predictor.apply(m, is_i, np.arange(len(m_idx)) - seg)
        take = min(len(m), max_rows - rows)
        cols.add(m[:take], is_i[:take], resume[m_idx[:take]])
        rows += take
        if take < len(m):
            truncated_rows = True
            break
        carry = chunk[int(starts[end_at]):] if end_at < len(items) else b""
        if ended or last:
            break
    return _flight_log(head, cols, where, rows=rows, ended=ended, truncated=truncated_rows,
                       garbage=(garbage_runs, garbage_bytes), dropped_p=dropped_p,
                       events=events, max_rows=max_rows)


def _accepted(it: np.ndarray, t: np.ndarray, is_i: np.ndarray, resumes: np.ndarray
              ) -> np.ndarray:
    """Which main frames to keep: a frame whose iteration or time (uint32 µs, compared
    modulo 2^32 so a wrap is no jump) steps back, or ahead by the format's bounds, is
    corrupt; a P frame is kept only after a kept I frame of its segment. A LOGGING_RESUME
    event excuses the jump after it. One Python step per segment (an I frame every
    ~32 ms), vectorised within."""
    n = len(t)
    wrap = 1 << 32
    # within a segment: each step forward by less than the bound; a bad step drops the
    # rest of the segment (its predictions came from the bad frame)
    step = np.diff(t) % wrap
    bad = np.concatenate([[False], (step == 0) | (step >= _MAX_JUMP_US)]) & ~is_i
    seg = np.cumsum(is_i) - 1  # segment of each row (-1: before the first I frame)
    cum_bad = np.cumsum(bad)
    starts = np.flatnonzero(is_i)
    good = (seg >= 0) & (cum_bad == cum_bad[starts][np.maximum(seg, 0)])
    idx = np.where(good, np.arange(n), -1)
    last_good = np.maximum.accumulate(idx)[[*(starts[1:] - 1).tolist(), n - 1]].tolist()
    # across segments: an I frame is checked against the last frame kept before it
    keep_seg = np.zeros(len(starts), bool)
    tl, il, rl = t.tolist(), it.tolist(), resumes.tolist()
    last = -1
    for s_, a in enumerate(starts.tolist()):
        if last >= 0 and rl[a] == rl[last]:
            if not ((tl[a] - tl[last]) % wrap < _MAX_JUMP_US
                    and 0 <= il[a] - il[last] < _MAX_JUMP_ITERATIONS):
                continue
        keep_seg[s_] = True
        last = last_good[s_]
    return good & keep_seg[np.maximum(seg, 0)]


def _vbat_scale(firmware: str) -> tuple[float, str]:
    """Volts per ``vbatLatest`` unit: 0.01 V from Betaflight 4 and INAV 2, 0.1 V before."""
    m = re.search(r"(Betaflight|INAV|Cleanflight)\s+(\d+)\.(\d+)", firmware)
    if m and m.group(1) == "Betaflight" and int(m.group(2)) < 4:
        return 0.1, "0.1 V (Betaflight 3)"
    return 0.01, "0.01 V"


def _flight_log(head: Header, cols: _Columns, where: str, *, rows: int, ended: bool,
                truncated: bool, garbage: tuple[int, int], dropped_p: int,
                events: dict[str, int], max_rows: int) -> FlightLog:
    # random bytes decode as the odd frame between many broken ones; a real log's
    # damage is a few places among many frames (a zero-filled tail is one place)
    if rows == 0 or garbage[0] > rows:
        raise LogError(f"{where}: no main frame decodes (header read; "
                       f"{garbage[1]} bytes of data did not parse as frames"
                       + (f" in {garbage[0]} places, {rows} frames did: random data or "
                          "another format?)" if rows else ")"))
    t = cols.get("time")
    ok = _accepted(cols.get("loopIteration"), t, cols.get("_is_i") == 1, cols.get("_resumes"))
    notes: list[str] = []
    if not ok.all():
        notes.append(f"dropped {int((~ok).sum())} frames whose time or iteration jumped "
                     f"back, or ahead by {_MAX_JUMP_US / 1e6:g} s or {_MAX_JUMP_ITERATIONS} "
                     "iterations or more (a damaged I frame and its P frames)")
    t = t[ok]
    d = np.diff(t)
    t = t + np.concatenate([[0], np.cumsum(np.where(d < -(1 << 31), 1 << 32, 0))])
    hires = head.int("blackbox_high_resolution", 0) == 1
    res = 10.0 if hires else 1.0
    deg = math.pi / 180.0
    log = FlightLog({}, {"format": "blackbox", "firmware": head.firmware,
                         "data_version": head.int("Data version", 2),
                         "looptime_us": head.int("looptime", 0),
                         "events": events, "log_end": ended, "notes": notes,
                         "high_resolution": hires})
    log.add("t_s", (t - t[0]) * 1e-6, "s", "time (µs)")
    scale = head.float_bits("gyro_scale", 1.0) / res * deg
    for k, axis in enumerate(AXES):
        if f"gyroADC[{k}]" in cols.index:
            log.add(f"gyro_{axis}_rad_s", cols.get(f"gyroADC[{k}]")[ok] * scale, "rad/s",
                    f"gyroADC[{k}] (deg/s{' x10' if hires else ''})")
        if f"setpoint[{k}]" in cols.index:
            log.add(f"rate_sp_{axis}_rad_s", cols.get(f"setpoint[{k}]")[ok] * deg / res,
                    "rad/s", f"setpoint[{k}] (deg/s{' x10' if hires else ''})")
    if "setpoint[3]" in cols.index:
        log.add("throttle_norm", cols.get("setpoint[3]")[ok] / 1000.0, "normalised 0..1",
                "setpoint[3] (mixer throttle x1000)")
    out = head.ints("motorOutput") or [head.int("minthrottle", 1000),
                                       head.int("maxthrottle", 2000)]
    low, high = [*out, 2000][:2]
    dshot = high > 2000  # DShot commands run to 2047; an analog output tops at 2000 µs
    for k in range(8):
        if f"motor[{k}]" not in cols.index:
            continue
        v = cols.get(f"motor[{k}]")[ok].astype(float)
        log.add(f"motor{k + 1}_norm", (v - low) / max(high - low, 1), "normalised 0..1",
                f"motor[{k}] over motorOutput {low}..{high}")
        if dshot:
            log.add(f"motor{k + 1}_dshot", v, "DShot command", f"motor[{k}]")
        else:
            log.add(f"motor{k + 1}_us", v, "µs", f"motor[{k}]")
    poles = head.int("motor_poles", 14)
    for k in range(8):
        if f"eRPM[{k}]" in cols.index:
            log.add(f"motor{k + 1}_rpm", cols.get(f"eRPM[{k}]")[ok] * 200.0 / poles, "rpm",
                    f"eRPM[{k}] (eRPM/100, motor_poles {poles})")
    vscale, vunit = _vbat_scale(head.firmware)
    for name in ("vbatLatest", "vbat"):
        if name in cols.index:
            log.add("voltage_v", cols.get(name)[ok] * vscale, "V", f"{name} ({vunit})")
            break
    for name in ("amperageLatest", "amperage"):
        if name in cols.index:
            log.add("current_a", cols.get(name)[ok] * 0.01, "A", f"{name} (0.01 A)")
            break
    if not ended:
        notes.append("no LOG_END: the log stops where the file does (logger cut off?); "
                     f"kept the {rows} frames that decode")
    if truncated:
        notes.append(f"kept the first {max_rows} frames (--max-rows); the rest of the log "
                     "was not read")
    if garbage[0]:
        notes.append(f"skipped {garbage[1]} bytes that are no frame, in {garbage[0]} places")
    if dropped_p:
        notes.append(f"dropped {dropped_p} P frames that followed a broken frame (waiting for "
                     "the next I frame)")
    return log


def read_blackbox(path: str | Path, *, max_rows: int | None = None) -> list[FlightLog]:
    """Every log in the file; ``LogError`` (one line) if none decodes."""
    path = Path(path)
    max_rows = MAX_ROWS if max_rows is None else max_rows
    if max_rows < 1:
        raise LogError(f"--max-rows {max_rows}: expected at least 1")
    try:
        with open(path, "rb") as fh:
            size = fh.seek(0, 2)
            spans = find_logs(fh, size)
            if not spans:
                raise LogError(f"{path}: no blackbox log in it (no 'H Product:Blackbox flight "
                               "data recorder' line)")
            return [_read_log(fh, a, b, f"{path} (log {k} of {len(spans)})" if len(spans) > 1
                              else str(path), max_rows)
                    for k, (a, b) in enumerate(spans, start=1)]
    except OSError as exc:
        raise LogError(f"{path}: cannot read ({exc.strerror or exc})") from None
