"""Load and validate IMU logs (hexapod calibration logs, attitude logs) from CSV or Parquet.

Every problem is a :class:`~analysis.errors.LogError` naming the file, the row (1-based data
row; the CSV line is one more because of the header) and the column.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from analysis.errors import LogError

__all__ = [
    "ACC_COLUMNS",
    "CALIBRATION_COLUMNS",
    "DEVICE_QUAT_COLUMNS",
    "GYRO_COLUMNS",
    "MAG_COLUMNS",
    "MOVEMENT_COLUMN",
    "PHASES",
    "REF_QUAT_COLUMNS",
    "imu_columns",
    "load_attitude_log",
    "load_calibration_log",
    "load_imu_log",
    "read_table",
    "write_table",
]

XYZ = ("x", "y", "z")
PHASES = ("bias", "gyro", "acc", "lever_x", "lever_y", "lever_z", "verify")
REQUIRED_PHASES = ("bias", "gyro", "acc", "lever_x", "lever_y", "lever_z")
REF_OMEGA = tuple(f"ref_omega_{a}_rad_s" for a in XYZ)
REF_ALPHA = tuple(f"ref_alpha_{a}_rad_s2" for a in XYZ)
REF_ACC = tuple(f"ref_acc_{a}_m_s2" for a in XYZ)
IMU_GYRO = tuple(f"imu_gyro_{a}_rad_s" for a in XYZ)
IMU_ACC = tuple(f"imu_acc_{a}_m_s2" for a in XYZ)
GYRO_COLUMNS = tuple(f"gyro_{a}_rad_s" for a in XYZ)
ACC_COLUMNS = tuple(f"acc_{a}_m_s2" for a in XYZ)
REF_QUAT_COLUMNS = ("ref_qw", "ref_qx", "ref_qy", "ref_qz")
#: the IMU under test's own attitude where it estimates one (a flight controller's
#: MSP_ATTITUDE), body to earth, ENU, scalar first
DEVICE_QUAT_COLUMNS = ("imu_qw", "imu_qx", "imu_qy", "imu_qz")
MAG_COLUMNS = tuple(f"mag_{a}_ut" for a in XYZ)
MOVEMENT_COLUMN = "movement"
CALIBRATION_COLUMNS = ("t_s", "phase", *REF_OMEGA, *REF_ALPHA, *REF_ACC, *IMU_GYRO, *IMU_ACC)


def _where(path: Path, row: int) -> str:
    line = f", line {row + 1}" if path.suffix.lower() == ".csv" else ""
    return f"{path}: row {row}{line}"


def read_table(path: str | Path) -> pd.DataFrame:
    """Read a CSV or Parquet file into a DataFrame (no validation beyond readability)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".csv", ".parquet"):
        raise LogError(f"{path}: expected a .csv or .parquet log, got {suffix or 'no suffix'!r}")
    if not path.is_file():
        raise LogError(f"{path}: file not found")
    header: list[Any] = []  # the CSV's first row as written
    try:
        if suffix == ".csv":
            df = pd.read_csv(path, dtype={"phase": str})
            header = pd.read_csv(path, header=None, nrows=1, dtype=str).iloc[0].tolist()
        else:
            df = pd.read_parquet(path)
    except Exception as exc:  # the reader's own message (on one line), with the file name
        reason = " ".join(str(exc).split())
        raise LogError(f"{path}: cannot be read as {suffix[1:]}: {reason}") from exc
    if suffix == ".csv" and len(df.columns) == 1 and any(c in str(df.columns[0]) for c in ";\t"):
        raise LogError(f"{path}: the header is one field ({str(df.columns[0])[:40]!r}...): "
                       "columns must be separated by commas")
    if suffix == ".csv":  # pandas renamed a repeated name 'X.1': which one is meant?
        names = [str(c).strip() for c in header]
        if twice := sorted({n for n in names if n and n != "nan" and names.count(n) > 1}):
            raise LogError(f"{path}: the header names column {twice[0]!r} twice; rename one")
    df.attrs["path"] = str(path)
    return df


def _require(df: pd.DataFrame, path: Path, columns: tuple[str, ...]) -> None:
    missing = [c for c in columns if c not in df.columns]
    if missing:
        raise LogError(f"{path}: missing column(s) {', '.join(missing)}")
    if len(df) == 0:
        raise LogError(f"{path}: no data rows")


def _numeric(df: pd.DataFrame, path: Path, columns: tuple[str, ...],
             allow_nan: bool = False) -> None:
    """Convert columns to float in place; the first bad cell is reported."""
    for c in columns:
        raw = df[c]
        values = np.asarray(pd.to_numeric(raw, errors="coerce"), dtype=float)
        bad = ~np.isfinite(values)
        if allow_nan:  # empty cells are allowed, text and infinities are not
            bad = np.isinf(values) | (np.isnan(values) & ~pd.isna(raw).to_numpy())
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise LogError(
                f"{_where(path, i + 1)}, column {c}: expected a finite number, got {raw.iloc[i]!r}"
            )
        df[c] = values


def _increasing(t: np.ndarray, path: Path, offset: int = 0) -> None:
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        i = int(bad[0]) + 1 + offset
        j = i - offset
        raise LogError(f"{_where(path, i + 1)}, column t_s: time must increase, "
                       f"got {float(t[j]):g} after {float(t[j - 1]):g}")


def load_calibration_log(path: str | Path, require_phases: tuple[str, ...] = REQUIRED_PHASES
                         ) -> pd.DataFrame:
    """Load a hexapod calibration log and check columns, numbers, phases and time order."""
    df = read_table(path)
    p = Path(path)
    _require(df, p, CALIBRATION_COLUMNS)
    _numeric(df, p, tuple(c for c in CALIBRATION_COLUMNS if c != "phase"))
    phase = df["phase"].astype(str).str.strip()
    bad = ~phase.isin(PHASES).to_numpy()
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise LogError(f"{_where(p, i + 1)}, column phase: expected one of {', '.join(PHASES)}, "
                       f"got {df['phase'].iloc[i]!r}")
    df["phase"] = phase
    missing = [ph for ph in require_phases if not (phase == ph).any()]
    if missing:
        raise LogError(f"{p}: column phase: no rows for phase(s) {', '.join(missing)}")
    t = df["t_s"].to_numpy()
    blocks = np.flatnonzero(phase.to_numpy()[1:] != phase.to_numpy()[:-1]) + 1
    starts = np.r_[0, blocks]
    ends = np.r_[blocks, len(df)]
    for s, e in zip(starts, ends, strict=True):
        _increasing(t[s:e], p, offset=int(s))
    return df


def imu_columns(df: pd.DataFrame) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The gyro and accelerometer column names a log uses (``imu_*`` or plain names)."""
    if all(c in df.columns for c in IMU_GYRO + IMU_ACC):
        return IMU_GYRO, IMU_ACC
    return GYRO_COLUMNS, ACC_COLUMNS


def load_imu_log(path: str | Path) -> pd.DataFrame:
    """Load any IMU log with ``t_s`` and gyro/acc columns (``imu_gyro_*`` or ``gyro_*``)."""
    df = read_table(path)
    p = Path(path)
    gyro, acc = imu_columns(df)
    _require(df, p, ("t_s", *gyro, *acc))
    _numeric(df, p, ("t_s", *gyro, *acc))
    if "phase" not in df.columns:
        _increasing(df["t_s"].to_numpy(), p)
    return df


def load_attitude_log(path: str | Path) -> pd.DataFrame:
    """Load ``t_s`` with gyro/acc columns and, if present, a reference, magnetometer, mask.

    Gyro/acc are ``gyro_*_rad_s, acc_*_m_s2`` (calibrated) or ``imu_gyro_*, imu_acc_*``
    (raw). Optional: ``ref_qw..ref_qz`` (scalar-first, sensor to earth; empty where the
    reference lost track, such rows are left out of the scores), ``mag_{x,y,z}_ut`` and a
    0/1 ``movement`` column (the samples the scores use).
    """
    df = read_table(path)
    p = Path(path)
    gyro, acc = imu_columns(df)
    _require(df, p, ("t_s", *gyro, *acc))
    _numeric(df, p, ("t_s", *gyro, *acc))
    for group, label in ((REF_QUAT_COLUMNS, "reference quaternion"), (MAG_COLUMNS, "magnetometer"),
                         (DEVICE_QUAT_COLUMNS, "device quaternion")):
        present = [c for c in group if c in df.columns]
        if present and len(present) != len(group):
            missing = [c for c in group if c not in df.columns]
            raise LogError(f"{p}: {label} needs all of {', '.join(group)}; "
                           f"missing {', '.join(missing)}")
    if REF_QUAT_COLUMNS[0] in df.columns:
        _numeric(df, p, REF_QUAT_COLUMNS, allow_nan=True)
    if MAG_COLUMNS[0] in df.columns:
        _numeric(df, p, MAG_COLUMNS)
    if DEVICE_QUAT_COLUMNS[0] in df.columns:
        _numeric(df, p, DEVICE_QUAT_COLUMNS)
    if MOVEMENT_COLUMN in df.columns:
        _numeric(df, p, (MOVEMENT_COLUMN,))
        bad = ~np.isin(df[MOVEMENT_COLUMN].to_numpy(), (0.0, 1.0))
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise LogError(f"{_where(p, i + 1)}, column {MOVEMENT_COLUMN}: expected 0 or 1, "
                           f"got {float(df[MOVEMENT_COLUMN].iloc[i]):g}")
    _increasing(df["t_s"].to_numpy(), p)
    return df


def write_table(df: pd.DataFrame, path: str | Path, float_format: str | None = None) -> Path:
    """Write a DataFrame to ``.csv`` or ``.parquet`` atomically (temp file, then rename);
    ``float_format``: the CSV's number format (default: every digit)."""
    from analysis.atomic_files import write_atomically

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".csv", ".parquet"):
        raise LogError(f"{path}: output must end in .csv or .parquet")
    if not path.parent.is_dir():
        raise LogError(f"{path}: folder {path.parent} does not exist")
    if path.is_dir():
        raise LogError(f"{path}: is a folder; expected the name of the file to write")

    def write(tmp: Path) -> None:
        if suffix == ".csv":
            df.to_csv(tmp, index=False, float_format=float_format)
        else:
            df.to_parquet(tmp, index=False)

    write_atomically(path, write)
    return path
