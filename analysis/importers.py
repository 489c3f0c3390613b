"""Import other benches' logs as run samples: RCbenchmark CSV, AutoQuad ESC32, any CSV.

Each importer returns a DataFrame whose columns carry the run's names and SI units
(``t_s``, ``throttle_us``, ``thrust_n``, ``torque_nm``, ``current_a``, ``voltage_v``,
``rpm``, ``acc_x_m_s2``, ``vibration_m_s2``, ...) and the metadata to put in
``run.json``; ``rotorbench import`` writes them into a run folder. Units are taken from
the column names: a header ``Thrust (gf)`` or ``thrust [kgf]`` is converted to newtons by
its unit, and a column already named like a run column (``thrust_n``) is taken as it is. An
acceleration in ``(g)`` is standard gravity, not gram-force: the unit is read for the
quantity of the run column it fills.
``detect_format`` names the format from the header, so ``import`` needs no ``--format``.

Rows are put in time order: a real stand's log can step back in time by a fraction of a
sample period where two boards interleave their rows. A step back of at most
``JITTER_MAX_PERIODS`` (5) median sample periods is reordered (stable sort) and counted in
the metadata (``time_order``: rows moved, places, largest step back, the bound); a larger
jump back is refused naming the row. Cells are read as text, so an error quotes the cell
as written ('inf', 'NaN', 'abc'); an empty cell is "no value".
"""

from __future__ import annotations

import csv
import math
import re
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from analysis.csv_dialect import Dialect, sniff
from analysis.csv_tail import cut_last_line
from analysis.errors import LogError, excerpt

__all__ = ["FORMATS", "RUN_COLUMNS", "detect_format", "import_csv", "import_esc32",
           "import_log", "import_rcbenchmark", "parse_header"]

G0 = 9.80665  # standard gravity (gram-force -> newton)

# run column -> (quantity, SI unit)
RUN_COLUMNS: dict[str, str] = {
    "t_s": "time",
    "throttle_us": "pulse",
    "thrust_setpoint_n": "force",
    "thrust_n": "force",
    "torque_nm": "torque",
    "current_a": "current",
    "voltage_v": "voltage",
    "rpm": "speed",
    "rpm_optical": "speed",
    "motor_voltage_v": "voltage",
    "duty_pct": "percent",
    "power_w": "power",
    "temperature_c": "temperature",
    "acc_x_m_s2": "acceleration",
    "acc_y_m_s2": "acceleration",
    "acc_z_m_s2": "acceleration",
    "vibration_m_s2": "acceleration",
}

# unit spelling (lower case, spaces removed) -> (quantity, factor to the run column's unit)
_UNITS: dict[str, tuple[str, float]] = {
    "s": ("time", 1.0), "sec": ("time", 1.0), "ms": ("time", 1e-3), "us": ("time", 1e-6),
    "µs": ("pulse", 1.0), "μs": ("pulse", 1.0),
    "n": ("force", 1.0), "gf": ("force", G0 * 1e-3), "g": ("force", G0 * 1e-3),
    "kgf": ("force", G0), "kg": ("force", G0), "lbf": ("force", 4.4482216152605),
    "lb": ("force", 4.4482216152605), "ozf": ("force", 0.27801385095378),
    "oz": ("force", 0.27801385095378), "mn": ("force", 1e-3),
    "n·m": ("torque", 1.0), "nm": ("torque", 1.0), "n·mm": ("torque", 1e-3),
    "nmm": ("torque", 1e-3), "kgf·m": ("torque", G0), "kgf·cm": ("torque", G0 * 1e-2),
    "gf·cm": ("torque", G0 * 1e-5), "g·cm": ("torque", G0 * 1e-5),
    "ozf·in": ("torque", 0.00706155181), "lbf·in": ("torque", 0.112984829),
    "lbf·ft": ("torque", 1.35581795),
    "a": ("current", 1.0), "ma": ("current", 1e-3),
    "v": ("voltage", 1.0), "mv": ("voltage", 1e-3),
    "rpm": ("speed", 1.0), "rad/s": ("speed", 60.0 / (2.0 * math.pi)), "hz": ("speed", 60.0),
    "rps": ("speed", 60.0), "%": ("percent", 1.0), "w": ("power", 1.0),
    "ºc": ("temperature", 1.0), "°c": ("temperature", 1.0), "c": ("temperature", 1.0),
}
# acceleration units: the same spellings as force units ('g', 'mg'), so looked up apart
_ACC_UNITS: dict[str, float] = {"g": G0, "mg": G0 * 1e-3, "m/s²": 1.0, "m/s^2": 1.0,
                                "m/s2": 1.0, "m·s-2": 1.0, "m/s/s": 1.0}
# the product dot of a unit is written many ways: 'N·m', 'N⋅m', 'N.m', 'N*m', 'N-m', 'N•m'
_PRODUCT = re.compile(r"(?<=[a-zµμ])[·⋅•×*.\-](?=[a-z])")


def _unit_key(unit: str) -> str:
    """A unit's lookup key: lower case, no spaces, one spelling of the product dot."""
    return _PRODUCT.sub("·", unit.lower().replace(" ", ""))


# "us" is ambiguous: microseconds of a pulse when the column is a pulse/throttle
_PULSE_WORDS = ("esc", "throttle", "pulse", "pwm", "servo", "signal")

_HEADER = re.compile(r"^\s*(?P<name>.*?)\s*[\(\[](?P<unit>[^\)\]]*)[\)\]]\s*$")


def parse_header(header: str) -> tuple[str, str | None]:
    """``'Thrust (gf)'`` -> ``('Thrust', 'gf')``; a header without a unit -> (name, None)."""
    m = _HEADER.match(header)
    if not m:
        return header.strip(), None
    return m.group("name"), m.group("unit").strip()


def _unit_factor(header: str, target: str, source: str) -> float:
    """Factor from the file column's unit (from its header) to the run column's unit."""
    quantity = RUN_COLUMNS.get(target)
    if quantity is None:
        return 1.0
    name, unit = parse_header(header)
    if unit is None:
        if header == target:
            return 1.0
        # a bare name in run style ("thrust_n", "t_ms"): take the unit from the suffix
        suffix = header.rsplit("_", 1)[-1].lower() if "_" in header else ""
        unit = {"ms": "ms", "us": "µs" if quantity == "pulse" else "us", "s": "s",
                "s2": "m/s2", "n": "N", "g": "g", "gf": "gf", "kgf": "kgf", "a": "A",
                "ma": "mA", "v": "V", "mv": "mV", "rpm": "rpm", "nm": "Nm", "w": "W",
                "pct": "%"}.get(suffix)
        if unit is None:
            return 1.0  # no unit stated: assume the run column's own unit
    key = _unit_key(unit)
    if key in ("us", "µs", "μs"):
        if quantity == "pulse" or any(w in name.lower() for w in _PULSE_WORDS):
            return 1.0
        if quantity == "time":
            return 1e-6
    found = ((quantity, _ACC_UNITS[key]) if key in _ACC_UNITS else None) \
        if quantity == "acceleration" else _UNITS.get(key)
    if found is None or found[0] != quantity:
        raise LogError(f"{source}: column {excerpt(header)}: unit {excerpt(unit)} is not a "
                       f"{quantity} unit for {target}")
    return found[1]


def _names(names: Any, limit: int) -> str:
    """The first ``limit`` column names of a header for a message, each cut short."""
    names = [str(n) for n in names]
    shown = [n if len(n) <= 40 else excerpt(n) for n in names[:limit]]
    return ", ".join(shown) + (f", ... ({len(names)} columns)" if len(names) > limit else "")


def _check_file(path: Path) -> None:
    """A missing path or a folder is the user's input error, not a crash."""
    if not path.exists():
        raise LogError(f"{path}: file not found")
    if not path.is_file():
        raise LogError(f"{path}: not a file (expected a CSV log)")


def _read_csv(path: Path, *, logger: bool = False, **kwargs: Any) -> pd.DataFrame:
    """The cells as text; a last line cut mid-write is dropped and noted in
    ``attrs["cut_last_line"]`` (``logger``: the file is a logging program's own format,
    see ``analysis.csv_tail``)."""
    _check_file(path)
    try:
        dialect = sniff(path, int(kwargs.get("skiprows", 0) or 0))  # ';' and '0,5' too
        # every cell as written: errors quote the file's text ('inf', not np.float64(inf)),
        # and only an empty cell means "no value"
        df = pd.read_csv(path, encoding="utf-8-sig", dtype=str, keep_default_na=False,
                         skipinitialspace=True, sep=dialect.sep, **kwargs)
        # the header as written: pandas renames a repeated name to 'X.1' silently
        raw = pd.read_csv(path, encoding="utf-8-sig", dtype=str, keep_default_na=False,
                          skipinitialspace=True, header=None, nrows=1, sep=dialect.sep,
                          **kwargs).iloc[0].tolist()
    except (UnicodeDecodeError, pd.errors.ParserError, csv.Error) as exc:
        reason = " ".join(str(exc).split())  # pandas' messages span lines; one line here
        raise LogError(f"{path}: not a readable CSV ({reason})") from None
    except pd.errors.EmptyDataError:
        raise LogError(f"{path}: empty file") from None
    except OSError as exc:
        raise LogError(f"{path}: cannot read ({exc.strerror or exc})") from None
    if len(df.columns) == 1 and any(c in str(df.columns[0]) for c in ";\t"):
        raise LogError(f"{path}: the header is one field ({str(df.columns[0])[:40]!r}...): "
                       "columns must be separated by commas")
    first_line = 2 + int(kwargs.get("skiprows", 0) or 0)  # file line of row 0
    cut = None if df.empty else cut_last_line(path, len(df.columns), logger=logger)
    if cut is not None:
        line = first_line + len(df) - 1
        df = df.iloc[:-1]
        if df.empty:
            raise LogError(f"{path}: no data rows (the only one, line {line}, is cut: no "
                           "line break at its end)")
        df.attrs["cut_last_line"] = {"line": line, "text": cut[:80]}
    if df.empty:
        raise LogError(f"{path}: no data rows (only a header)")
    _check_unique([str(c).strip() for c in raw], path, lambda h: h)
    df.columns = [str(c).strip() for c in df.columns]  # 'Time (s), Amps' -> 'Amps'
    df.attrs["first_line"] = first_line
    df.attrs["dialect"] = dialect
    return df


def _check_unique(headers: list[str], path: Path, key: Callable[[str], str]) -> None:
    """Refuse a header naming one column twice (by ``key``): which one is meant is a guess,
    and taking either silently puts the wrong channel in a run column."""
    seen: dict[str, int] = {}
    for i, h in enumerate(headers):
        k = key(h)
        if not k:  # unnamed (a trailing comma): nothing is taken from it by name
            continue
        if k in seen:
            raise LogError(f"{path}: the header names column {h!r} twice (columns "
                           f"{seen[k] + 1} and {i + 1}); rename one")
        seen[k] = i


def _by_name(df: pd.DataFrame, path: Path) -> dict[str, str]:
    """Stand-log headers by name without unit, lower case ('Thrust (gf)' and 'thrust (N)'
    are one channel twice)."""
    _check_unique(list(df.columns), path, lambda h: parse_header(h)[0].lower())
    return {parse_header(h)[0].lower(): h for h in df.columns}


def _numeric(df: pd.DataFrame, header: str, path: Path) -> np.ndarray:
    """A column as floats: an empty cell is NaN (no value); text, NaN and inf are refused
    naming row and column with the cell as written in the file."""
    raw = df[header].astype(str).str.strip()
    if df.attrs.get("dialect", Dialect()).decimal == ",":
        raw = raw.str.replace(",", ".", regex=False)
    empty = raw.to_numpy() == ""
    values = np.asarray(pd.to_numeric(raw.where(~empty, "nan"), errors="coerce"), dtype=float)
    bad = ~np.isfinite(values) & ~empty
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        what = "a number" if math.isnan(values[row]) and raw.iloc[row].lower() != "nan" \
            else "a finite number (leave the cell empty for no value)"
        raise LogError(f"{path}: row {row + _first_line(df)}, column {excerpt(header)}: "
                       f"expected {what}, got {excerpt(raw.iloc[row])}")
    return values


def _dialect_meta(df: pd.DataFrame) -> dict[str, str]:
    """``{"csv_dialect": "';'-separated, decimal comma"}`` for a file read not as plain CSV."""
    dialect = df.attrs.get("dialect", Dialect())
    return {} if dialect.plain else {"csv_dialect": dialect.describe()}


def _first_line(df: pd.DataFrame) -> int:
    return int(df.attrs.get("first_line", 2))


# Two boards of a stand can interleave their rows, so the time column of a real log may
# step back by a fraction of a sample period. Rows are put in time order (stably) when
# the step back is at most this many median sample periods; a larger jump back (two logs
# concatenated, a clock reset) is refused.
JITTER_MAX_PERIODS = 5.0


def _order_time(t: np.ndarray, path: Path, time_col: str, raw: pd.Series | None,
                first_line: int, allow_repeats: bool) -> tuple[np.ndarray, dict[str, Any]]:
    """Stable time order of the rows and what it changed; ``LogError`` for a far jump
    back or (``allow_repeats`` False) for a repeated timestamp."""

    def cell(i: int) -> str:
        return excerpt(str(raw.iloc[i]).strip()) if raw is not None else repr(f"{t[i]:g}")

    dt = np.diff(t)
    pos = dt[dt > 0]
    period = float(np.median(pos)) if pos.size else 0.0
    bound = JITTER_MAX_PERIODS * period
    back = np.maximum.accumulate(t)[:-1] - t[1:]  # how far each row lies behind the latest
    far = np.flatnonzero(back > bound)
    if far.size:
        i = int(far[0]) + 1
        raise LogError(f"{path}: row {i + first_line}, column {excerpt(time_col)}: time "
                       f"jumps back {back[i - 1]:.6g} s (to {cell(i)}), more than the jitter "
                       f"bound of {JITTER_MAX_PERIODS:g} sample periods ({bound:.3g} s): two "
                       "logs in one file? split it")
    order = np.argsort(t, kind="stable")
    if not allow_repeats:
        ts = t[order]
        rep = np.flatnonzero(ts[1:] == ts[:-1])
        if rep.size:
            i = int(np.min(order[rep + 1]))
            raise LogError(f"{path}: row {i + first_line}, column {excerpt(time_col)}: "
                           f"repeated timestamp {cell(i)} (each row needs its own time)")
    moved = int(np.count_nonzero(order != np.arange(t.size)))
    info: dict[str, Any] = {"reordered_rows": moved, "time_steps_back": int(np.sum(dt < 0)),
                            "max_step_back_s": float(np.max(back, initial=0.0)),
                            "jitter_bound_s": bound, "median_period_s": period}
    return order, info


def _series(df: pd.DataFrame, name: str) -> pd.Series:
    """The column ``name`` (the readers rename a repeated name, so one label, one column)."""
    column = df[name]
    if not isinstance(column, pd.Series):
        raise TypeError(f"column {name!r} is not one column")
    return column


def _frame(columns: Mapping[str, np.ndarray], path: Path, *, time_col: str = "t_s",
           raw_time: pd.Series | None = None, first_line: int = 2,
           allow_repeats: bool = True) -> tuple[pd.DataFrame, dict[str, Any]]:
    """The run columns in time order, with the reordering summary for the metadata."""
    out = pd.DataFrame({k: np.asarray(v, float) for k, v in columns.items()})
    if "t_s" not in out.columns:
        raise LogError(f"{path}: no time column (t_s)")
    t = out["t_s"].to_numpy()
    if not np.isfinite(t).all():
        row = int(np.flatnonzero(~np.isfinite(t))[0])
        got = (f", got {excerpt(str(raw_time.iloc[row]).strip())}" if raw_time is not None
               else "")
        raise LogError(f"{path}: row {row + first_line}, column {excerpt(time_col)}: time is "
                       f"empty or not a number{got}")
    order, info = _order_time(t, path, time_col, raw_time, first_line, allow_repeats)
    if info["reordered_rows"]:
        out = out.iloc[order].reset_index(drop=True)
    return out, info


# --- RCbenchmark --------------------------------------------------------------------------

_RCB_MAP = (  # (header name, run column); the unit comes from the header. Names of the
    # same quantity in other RCbenchmark / Flight Stand versions follow the first spelling;
    # the first one with data wins
    ("Time", "t_s"),
    ("ESC signal", "throttle_us"),
    ("ESC", "throttle_us"),
    ("Thrust", "thrust_n"),
    ("Torque", "torque_nm"),
    ("Voltage", "voltage_v"),
    ("Current", "current_a"),
    ("Motor Current", "current_a"),
    ("Motor Electrical Speed", "rpm"),
    ("Motor Speed", "rpm"),
    ("Rotation Speed", "rpm"),
    ("RPM", "rpm"),
    ("Motor Optical Speed", "rpm_optical"),
    ("Electrical Power", "power_w"),
    # the stand's accelerometer (1585/1780 boards): three axes and the board's vibration
    # level, all in g; taken in m/s^2
    ("AccX", "acc_x_m_s2"),
    ("AccY", "acc_y_m_s2"),
    ("AccZ", "acc_z_m_s2"),
    ("Vibration", "vibration_m_s2"),
)


def import_rcbenchmark(path: str | Path) -> tuple[pd.DataFrame, dict[str, Any]]:
    """A Tyto RCbenchmark log (1580-era or later headers, units from the header).

    The stand fills thrust and torque only on some rows (the load cells update slower than
    the other channels); those cells stay NaN, nothing is forward-filled. When the
    electrical speed column is all zero and the optical one has data, the optical speed
    becomes ``rpm``.
    """
    path = Path(path)
    _check_file(path)
    first = path.read_bytes()[:200].decode("utf-8-sig", errors="replace").splitlines()
    skip = 1 if first and first[0].lower().startswith("control protocol") else 0
    df = _read_csv(path, logger=True, skiprows=skip)
    by_name = _by_name(df, path)
    if "time" not in by_name:
        raise LogError(f"{path}: no 'Time (s)' column: not an RCbenchmark log "
                       f"(columns: {_names(df.columns, 6)})")
    cols: dict[str, np.ndarray] = {}
    used: dict[str, str] = {}
    for name, target in _RCB_MAP:
        header = by_name.get(name.lower())
        if header is None or target in cols:
            continue
        values = _numeric(df, header, path) * _unit_factor(header, target, str(path))
        if target != "t_s" and not np.isfinite(values).any():
            continue  # an empty column (e.g. no ESC signal logged)
        cols[target] = values
        used[target] = header
    if "rpm" not in cols and "rpm_optical" in cols:  # a stand with the optical probe only
        cols["rpm"], used["rpm"] = cols.pop("rpm_optical"), used.pop("rpm_optical")
    if "rpm" in cols and "rpm_optical" in cols:
        if not np.any(cols["rpm"] > 0) and np.any(cols["rpm_optical"] > 0):
            cols["rpm"], cols["rpm_optical"] = cols["rpm_optical"], cols["rpm"]
            used["rpm"], used["rpm_optical"] = used["rpm_optical"], used["rpm"]
    if not np.any(np.nan_to_num(cols.get("rpm_optical", np.zeros(1))) > 0):
        cols.pop("rpm_optical", None)
        used.pop("rpm_optical", None)
    frame, order = _frame(cols, path, time_col=used["t_s"], raw_time=_series(df, used["t_s"]),
                          first_line=_first_line(df))
    meta = {"format": "rcbenchmark", "source_file": str(path), "columns": used,
            "control_protocol": first[0].strip() if skip else None, "time_order": order,
            "cut_last_line": df.attrs.get("cut_last_line"), **_dialect_meta(df)}
    return frame, meta


# --- AutoQuad ESC32 -----------------------------------------------------------------------

_ESC32_MAP = (
    ("Amps", "current_a"),
    ("Batt. Volts", "voltage_v"),
    ("Motor Volts", "motor_voltage_v"),
    ("RPM", "rpm"),
    ("Duty", "duty_pct"),
)


# the utility writes milliseconds after a colon; a log re-saved elsewhere may use a dot
_ESC32_STAMP = "%Y-%m-%d %H:%M:%S:%f"
_DOT_MS = re.compile(r"(\d:\d\d)\.(\d+)$")


def import_esc32(path: str | Path) -> tuple[pd.DataFrame, dict[str, Any]]:
    """The AutoQuad ESC32 configuration utility's telemetry log.

    Timestamps are ``YYYY-MM-DD HH:MM:SS:mmm`` (milliseconds after a colon; a dot is
    accepted too); ``t_s`` counts from the first row, the absolute start goes into the
    metadata. The utility logs the telemetry values the user ticked, in any order: the
    known ones present (``Amps``, ``Batt. Volts``, ``Motor Volts``, ``RPM``, ``Duty``; names
    matched without case or a unit in brackets) are imported, at least one is needed.
    """
    path = Path(path)
    df = _read_csv(path, logger=True)
    by_name = _by_name(df, path)
    stamp_col = by_name.get("timestamp")
    if stamp_col is None:
        raise LogError(f"{path}: no 'Timestamp' column: not an ESC32 telemetry log")
    raw = df[stamp_col].astype(str).str.strip()
    stamp = pd.to_datetime(raw.str.replace(_DOT_MS, r"\1:\2", regex=True),
                           format=_ESC32_STAMP, errors="coerce")
    if stamp.isna().any():
        row = int(np.flatnonzero(stamp.isna().to_numpy())[0])
        raise LogError(f"{path}: row {row + _first_line(df)}, column {excerpt(stamp_col)}: "
                       f"expected 'YYYY-MM-DD HH:MM:SS:mmm', got {excerpt(raw.iloc[row])}")
    start = stamp.min()  # the first row may lie a little behind a later one (jitter)
    t = (stamp - start).dt.total_seconds().to_numpy()
    cols: dict[str, np.ndarray] = {"t_s": t}
    used: dict[str, str] = {"t_s": stamp_col}
    for name, target in _ESC32_MAP:
        header = by_name.get(name.lower())
        if header is not None:
            cols[target] = _numeric(df, header, path) * _unit_factor(header, target, str(path))
            used[target] = header
    if len(cols) == 1:
        raise LogError(f"{path}: none of the ESC32 telemetry columns "
                       f"{[h for h, _ in _ESC32_MAP]} (columns: {_names(df.columns, 8)})")
    frame, order = _frame(cols, path, time_col=stamp_col, raw_time=_series(df, stamp_col),
                          first_line=_first_line(df))
    meta = {"format": "esc32", "source_file": str(path), "columns": used,
            "start_time": str(start), "time_order": order,
            "cut_last_line": df.attrs.get("cut_last_line"), **_dialect_meta(df)}
    return frame, meta


# --- any CSV ------------------------------------------------------------------------------


def import_csv(path: str | Path, mapping: Mapping[str, str] | None = None
               ) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Any CSV: ``mapping`` gives RUNCOL -> FILECOL; columns already named like run
    columns are taken without a mapping. Units come from the file header (``(gf)``) or
    the name suffix (``thrust_g``); a file column without a unit is taken in the run
    column's unit."""
    path = Path(path)
    df = _read_csv(path)
    mapping = dict(mapping or {})
    for run_col, file_col in mapping.items():
        if run_col not in RUN_COLUMNS:
            raise LogError(f"--map {run_col}={file_col}: unknown run column {run_col!r} "
                           f"(one of {', '.join(RUN_COLUMNS)})")
        if file_col not in df.columns:
            raise LogError(f"{path}: --map {run_col}={file_col}: no column {file_col!r} in the "
                           f"file (columns: {_names(df.columns, 20)})")
    for name in df.columns:
        if name in RUN_COLUMNS and name not in mapping and name not in mapping.values():
            mapping[name] = name
    if "t_s" not in mapping:
        raise LogError(f"{path}: no time column: name one t_s or pass --map t_s=COLUMN")
    cols = {run_col: _numeric(df, file_col, path) * _unit_factor(file_col, run_col, str(path))
            for run_col, file_col in mapping.items()}
    # a CSV of run columns has one row per instant: a repeated time is refused
    frame, order = _frame(cols, path, time_col=mapping["t_s"], raw_time=_series(df, mapping["t_s"]),
                          first_line=_first_line(df), allow_repeats=False)
    meta = {"format": "csv", "source_file": str(path), "columns": dict(mapping),
            "time_order": order, "cut_last_line": df.attrs.get("cut_last_line"),
            **_dialect_meta(df)}
    return frame, meta


FORMATS = ("rcbenchmark", "esc32", "csv")

# Header names (without unit, lower case) only an RCbenchmark / Flight Stand log carries:
# 'Time (s)' and 'Thrust (N)' alone could be anyone's CSV.
_RCB_MARKERS = frozenset({
    "esc signal", "esc", "servo 1", "servo 2", "servo 3", "servo", "accx", "accy", "accz",
    "vibration", "app message", "motor electrical speed", "motor optical speed",
    "electrical power", "mechanical power", "motor efficiency",
    "propeller mech. efficiency", "overall efficiency"})
# the ESC32 utility's telemetry names beside its 'Timestamp'
_ESC32_MARKERS = frozenset({h.lower() for h, _ in _ESC32_MAP} | {
    "comm. period", "bad detects", "adc window", "idle time", "state", "phase a avg.",
    "phase b avg.", "phase c avg.", "composite avg.", "fet step"})
_HEADER_BYTES = 1 << 16  # a header longer than this is no log of these formats


def _header_cells(path: Path) -> tuple[list[str], bool]:
    """The header's cells as written, and whether a 'Control protocol' line precedes it
    (RCbenchmark control-board logs)."""
    _check_file(path)
    try:
        with open(path, "rb") as fh:
            head = fh.read(_HEADER_BYTES)
    except OSError as exc:
        raise LogError(f"{path}: cannot read ({exc.strerror or exc})") from None
    lines = head.decode("utf-8-sig", errors="replace").splitlines()
    protocol = bool(lines) and lines[0].lower().startswith("control protocol")
    line = lines[1 if protocol else 0] if len(lines) > int(protocol) else ""
    cells = next(csv.reader([line], skipinitialspace=True), [])
    return [c.strip() for c in cells], protocol


def detect_format(path: str | Path) -> str:
    """The log format its header shows: ``rcbenchmark`` ('Time (s)' with the stand's own
    columns, or a 'Control protocol' line first), ``esc32`` ('Timestamp' with the
    utility's telemetry names) or ``csv`` (run column names: ``t_s`` ...). ``LogError``
    naming the file and the formats tried when none, or more than one, fits."""
    path = Path(path)
    cells, protocol = _header_cells(path)
    found = {parse_header(c)[0].strip().lower() for c in cells}
    fits = [fmt for fmt, ok in (
        ("rcbenchmark", protocol or ("time" in found and bool(found & _RCB_MARKERS))),
        ("esc32", "timestamp" in found and bool(found & _ESC32_MARKERS)),
        ("csv", "t_s" in found)) if ok]
    if len(fits) == 1:
        return fits[0]
    shown = ", ".join(c[:40] for c in cells[:6] if c) + (" ..." if len(cells) > 6 else "")
    if fits:
        raise LogError(f"{path}: the header fits {' and '.join(fits)} (columns: {shown}); "
                       "choose with --format")
    raise LogError(f"{path}: no known log format in its header (columns: {shown or 'none'}); "
                   "tried rcbenchmark ('Time (s)' with the stand's columns), esc32 "
                   "('Timestamp' with the utility's telemetry) and csv (run column names, "
                   "t_s ...); pass --format csv --map RUNCOL=FILECOL for another layout")


def import_log(path: str | Path, fmt: str, mapping: Mapping[str, str] | None = None
               ) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Dispatch on ``fmt``; a mapping applies to the ``csv`` format only."""
    if fmt == "rcbenchmark":
        df, meta = import_rcbenchmark(path)
    elif fmt == "esc32":
        df, meta = import_esc32(path)
    elif fmt == "csv":
        df, meta = import_csv(path, mapping)
    else:
        raise LogError(f"--format {fmt!r}: expected one of {', '.join(FORMATS)}")
    if mapping and fmt != "csv":
        raise LogError(f"--map applies to --format csv only (the {fmt} columns are known)")
    return df, meta
