"""One IMU recording in SI units, read from a BROAD HDF5 trial or from a project log.

BROAD (Laidig, Caruso, Cereatti, Seel, Data 6(7), 2021, doi:10.3390/data6070072) stores
per trial ``imu_acc`` (m/s²), ``imu_gyr`` (rad/s), ``imu_mag`` (µT), ``opt_quat`` (optical
ground truth, scalar-first, sensor to an ENU earth frame, NaN during marker loss),
``movement`` (the samples the benchmark scores) and the attribute ``sampling_rate`` (Hz).
The project's own logs (CSV/Parquet) carry the same content under the column names of
:mod:`analysis.imu_log`. Either way the estimators get one :class:`ImuRecording`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from analysis.errors import LogError
from analysis.extras import import_extra
from analysis.imu_log import (
    DEVICE_QUAT_COLUMNS,
    MAG_COLUMNS,
    MOVEMENT_COLUMN,
    REF_QUAT_COLUMNS,
    imu_columns,
    load_attitude_log,
)

__all__ = ["HDF5_SUFFIXES", "UNIFORM_JITTER", "ImuRecording", "UniformGrid", "load_recording",
           "read_broad", "uniform_grid"]

Array = NDArray[np.float64]
HDF5_SUFFIXES = (".hdf5", ".h5")
# fixed-rate filters (VQF, ahrs) take a recording as it is while every sample interval is
# within this fraction of the median; otherwise they run on a uniform grid
UNIFORM_JITTER = 0.1


@dataclass(frozen=True)
class ImuRecording:
    """Samples of one IMU; optional parts are ``None`` when the file has none.

    ``ref_quat`` maps sensor to earth frame (ENU, z up), scalar-first, NaN rows where the
    reference lost track. ``movement`` marks the samples to score (all, if ``None``).
    ``device_quat``: the attitude the IMU under test reported itself (a flight
    controller's), same convention, scored as one more peer.
    """

    source: str
    t_s: Array
    gyro_rad_s: Array
    acc_m_s2: Array
    mag_ut: Array | None = None
    ref_quat: Array | None = None
    movement: NDArray[np.bool_] | None = None
    device_quat: Array | None = None

    @property
    def rate_hz(self) -> float:
        """Mean sampling rate over the recording."""
        t = self.t_s
        return float((len(t) - 1) / (t[-1] - t[0])) if len(t) > 1 else float("nan")

    def with_imu(self, t_s: Array, gyro: Array, acc: Array, keep: NDArray[np.bool_],
                 mag_ut: Array | None = None) -> ImuRecording:
        """Copy with corrected IMU samples on the rows ``keep`` (e.g. after a calibration).

        ``mag_ut``: corrected magnetometer samples of those rows (default: the rows kept).
        """
        def sub(a: NDArray[Any] | None) -> NDArray[Any] | None:
            return None if a is None else a[keep]
        return replace(self, t_s=t_s, gyro_rad_s=gyro, acc_m_s2=acc,
                       mag_ut=sub(self.mag_ut) if mag_ut is None else mag_ut,
                       ref_quat=sub(self.ref_quat), movement=sub(self.movement),
                       device_quat=sub(self.device_quat))


@dataclass(frozen=True)
class UniformGrid:
    """A recording's IMU samples on a uniform time grid, and the way back to its rows.

    Row i of the original lies between grid samples ``idx[i]`` and ``idx[i] + 1`` at the
    fraction ``u[i]``.
    """

    rec: ImuRecording
    idx: NDArray[np.intp]
    u: Array


def uniform_grid(rec: ImuRecording, jitter: float = UNIFORM_JITTER) -> UniformGrid | None:
    """``None`` if the sampling is uniform (within ``jitter``), else the resampled recording.

    Filters with a fixed sample time (VQF, Madgwick, Mahony) integrate every interval as
    one median interval: dropped rows or a gap in a logged stream would be lost rotation.
    The grid keeps the median interval; gyro, accelerometer and magnetometer are linearly
    interpolated onto it (across a gap, the straight line between its ends).
    """
    t = rec.t_s
    d = np.diff(t)
    dt = float(np.median(d)) if len(d) else 0.0
    if dt <= 0.0 or np.all(np.abs(d - dt) <= jitter * dt):
        return None
    n = int(np.ceil((t[-1] - t[0]) / dt - 1e-9)) + 1
    tg = t[0] + np.arange(n) * dt

    def on_grid(a: Array) -> Array:
        return np.stack([np.interp(tg, t, a[:, i]) for i in range(a.shape[1])], axis=1)

    grid = ImuRecording(rec.source, tg, on_grid(rec.gyro_rad_s), on_grid(rec.acc_m_s2),
                        None if rec.mag_ut is None else on_grid(rec.mag_ut))
    idx = np.clip(np.searchsorted(tg, t, side="right") - 1, 0, n - 2)
    u = np.clip((t - tg[idx]) / dt, 0.0, 1.0)
    return UniformGrid(grid, idx, u)


def _dataset(f, path: Path, name: str, width: int, n: int | None, finite: bool) -> Array:
    if name not in f:
        raise LogError(f"{path}: dataset {name}: missing (a BROAD trial has imu_acc, imu_gyr, "
                       "imu_mag, opt_quat, movement)")
    node = f[name]
    kind = getattr(getattr(node, "dtype", None), "kind", None)
    if kind is None:  # a group (or a link to one), not a dataset
        raise LogError(f"{path}: {name}: expected a dataset of numbers, got a "
                       f"{type(node).__name__.lower()}")
    if kind not in "biuf":  # strings, compounds, references: no numbers to read
        raise LogError(f"{path}: dataset {name}: expected numbers, got {node.dtype} values")
    arr = np.asarray(node[()], dtype=float)
    if width == 1 and arr.ndim == 2 and 1 in arr.shape:
        arr = arr.reshape(-1)  # MAT-style column vectors
    want = (n if n is not None else arr.shape[0],) + ((width,) if width > 1 else ())
    if arr.shape != want:
        raise LogError(f"{path}: dataset {name}: expected shape {want}, got {arr.shape}")
    if finite:
        bad = ~np.isfinite(arr).reshape(len(arr), -1).all(axis=1)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise LogError(f"{path}: dataset {name}, sample {i}: expected finite numbers, "
                           f"got {arr[i].tolist()}")
    return arr


def read_broad(path: str | Path) -> ImuRecording:
    """Read a BROAD HDF5 trial (needs the ``imu`` extra for h5py)."""
    h5py = import_extra("h5py", "imu", "reading a BROAD HDF5 trial")
    path = Path(path)
    if not path.is_file():
        raise LogError(f"{path}: file not found")
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise LogError(f"{path}: not a readable HDF5 file ({' '.join(str(exc).split())})"
                       ) from None
    with f:
        if "sampling_rate" not in f.attrs:
            raise LogError(f"{path}: attribute sampling_rate: missing")
        try:
            rate = float(np.asarray(f.attrs["sampling_rate"]).reshape(-1)[0])
        except (TypeError, ValueError, IndexError):
            rate = float("nan")
        if not (np.isfinite(rate) and rate > 0):
            raise LogError(f"{path}: attribute sampling_rate: expected a rate in Hz > 0, "
                           f"got {f.attrs['sampling_rate']!r}")
        gyr = _dataset(f, path, "imu_gyr", 3, None, True)
        n = len(gyr)
        if n < 2:
            raise LogError(f"{path}: dataset imu_gyr: expected at least 2 samples, got {n}")
        acc = _dataset(f, path, "imu_acc", 3, n, True)
        mag = _dataset(f, path, "imu_mag", 3, n, True) if "imu_mag" in f else None
        ref = _dataset(f, path, "opt_quat", 4, n, False) if "opt_quat" in f else None
        mov = _dataset(f, path, "movement", 1, n, True) if "movement" in f else None
    if mov is not None and not np.isin(mov, (0.0, 1.0)).all():
        i = int(np.flatnonzero(~np.isin(mov, (0.0, 1.0)))[0])
        raise LogError(f"{path}: dataset movement, sample {i}: expected 0 or 1, "
                       f"got {float(mov[i]):g}")
    rec = ImuRecording(str(path), np.arange(n) / rate, gyr, acc, mag, ref,
                       None if mov is None else mov.astype(bool))
    return _check_scorable(rec, "dataset opt_quat", "dataset movement")


def _check_scorable(rec: ImuRecording, ref_name: str, mov_name: str) -> ImuRecording:
    """Refuse a reference that leaves nothing to score: every quaternion NaN (the optical
    system lost track throughout) or no movement sample where it is finite. The scores
    would be the RMSE of an empty set; the file is what is wrong, so it is named."""
    if rec.ref_quat is None:
        return rec
    finite = np.isfinite(rec.ref_quat).all(axis=1)
    if not finite.any():
        raise LogError(f"{rec.source}: {ref_name}: no sample has a finite reference "
                       "quaternion (all NaN); nothing to score")
    if rec.movement is not None and not (rec.movement & finite).any():
        what = ("every sample is 0" if not rec.movement.any()
                else "no sample marked 1 has a finite reference")
        raise LogError(f"{rec.source}: {mov_name}: {what}; no sample to score")
    return rec


def load_recording(path: str | Path) -> ImuRecording:
    """A BROAD trial (``.hdf5``/``.h5``) or a project IMU log (``.csv``/``.parquet``)."""
    path = Path(path)
    if path.suffix.lower() in HDF5_SUFFIXES:
        return read_broad(path)
    if path.suffix.lower() not in (".csv", ".parquet"):
        raise LogError(f"{path}: expected a BROAD trial (.hdf5) or an IMU log (.csv/.parquet), "
                       f"got {path.suffix or 'no suffix'!r}")
    df = load_attitude_log(path)
    gyro, acc = imu_columns(df)

    def columns(names: tuple[str, ...]) -> Array:
        return df[list(names)].to_numpy(dtype=float)

    def cols(names: tuple[str, ...]) -> Array | None:
        return columns(names) if names[0] in df.columns else None

    mov = df[MOVEMENT_COLUMN].to_numpy() > 0.5 if MOVEMENT_COLUMN in df.columns else None
    rec = ImuRecording(str(path), df["t_s"].to_numpy(dtype=float), columns(gyro), columns(acc),
                       cols(MAG_COLUMNS), cols(REF_QUAT_COLUMNS), mov,
                       cols(DEVICE_QUAT_COLUMNS))
    return _check_scorable(rec, f"columns {','.join(REF_QUAT_COLUMNS)}",
                           f"column {MOVEMENT_COLUMN}")
