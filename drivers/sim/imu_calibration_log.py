"""Write a full simulated hexapod calibration log in the analysis' log format.

Columns: ``t_s, phase, ref_omega_{x,y,z}_rad_s, ref_alpha_{x,y,z}_rad_s2,
ref_acc_{x,y,z}_m_s2`` (body-frame specific force at the centre of gravity, gravity
included) and ``imu_gyro_{x,y,z}_rad_s, imu_acc_{x,y,z}_m_s2``. The phases follow each
other on one continuous hexapod clock; the IMU columns of the row stamped ``t`` hold the
sample the IMU took at hexapod time ``t - clock_offset_s``.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from drivers.hexapod_motions import Phase, paper_a_protocol
from drivers.sim.hexapod import SimHexapod
from drivers.sim.imu import ADIS16400, ImuModel, SimImu

__all__ = ["LOG_COLUMNS", "simulate_calibration_log", "write_calibration_log"]

_XYZ = ("x", "y", "z")
LOG_COLUMNS = (
    "t_s",
    "phase",
    *(f"ref_omega_{a}_rad_s" for a in _XYZ),
    *(f"ref_alpha_{a}_rad_s2" for a in _XYZ),
    *(f"ref_acc_{a}_m_s2" for a in _XYZ),
    *(f"imu_gyro_{a}_rad_s" for a in _XYZ),
    *(f"imu_acc_{a}_m_s2" for a in _XYZ),
)


def simulate_calibration_log(
    model: ImuModel = ADIS16400,
    phases: list[Phase] | None = None,
    hexapod: SimHexapod | None = None,
    seed: int = 0,
) -> dict[str, NDArray]:
    """Run every phase on the simulated hexapod and IMU; return the log's columns."""
    hexapod = hexapod or SimHexapod()
    phases = phases if phases is not None else paper_a_protocol(model.rate_hz)
    imu = SimImu(model, np.random.default_rng(seed))
    dt = 1.0 / model.rate_hz
    parts: dict[str, list[NDArray]] = {c: [] for c in LOG_COLUMNS}
    start = 0.0
    for phase in phases:
        hexapod.check(phase.motion)
        n = round(phase.motion.duration_s * model.rate_hz)
        local = np.arange(n) * dt
        ref = hexapod.follow(phase.motion, local)
        seen = hexapod.follow(phase.motion, local - model.clock_offset_s)
        gyro, acc = imu.measure(seen)
        parts["t_s"].append(start + local)
        parts["phase"].append(np.full(n, phase.label, dtype=object))
        for i, a in enumerate(_XYZ):
            parts[f"ref_omega_{a}_rad_s"].append(ref.omega_b_rad_s[:, i])
            parts[f"ref_alpha_{a}_rad_s2"].append(ref.alpha_b_rad_s2[:, i])
            parts[f"ref_acc_{a}_m_s2"].append(ref.specific_force_b_m_s2[:, i])
            parts[f"imu_gyro_{a}_rad_s"].append(gyro[:, i])
            parts[f"imu_acc_{a}_m_s2"].append(acc[:, i])
        start += n * dt
    return {c: np.concatenate(v) for c, v in parts.items()}


def write_calibration_log(path: str | Path, columns: dict[str, NDArray]) -> Path:
    """Write the columns to ``.csv`` or ``.parquet`` atomically (temp file, then rename)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".csv", ".parquet"):
        raise ValueError(f"{path}: log files end in .csv or .parquet")
    fd, tmp = tempfile.mkstemp(dir=path.parent or ".", prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    try:
        if suffix == ".csv":
            _write_csv(Path(tmp), columns)
        else:
            import pyarrow as pa  # file-format boundary only
            import pyarrow.parquet as pq

            table = pa.table({c: (v.astype(str) if v.dtype == object else v)
                              for c, v in columns.items()})
            pq.write_table(table, tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def _write_csv(path: Path, columns: dict[str, NDArray]) -> None:
    names = list(columns)
    n = len(columns[names[0]])
    cells = []
    for c in names:
        v = columns[c]
        if v.dtype == object:
            cells.append(v.astype(str))
        else:
            cells.append(np.char.mod("%.9g", v))
    with open(path, "w", encoding="utf-8", newline="") as fh:
        fh.write(",".join(names) + "\n")
        rows = np.stack(cells, axis=1) if n else np.empty((0, len(names)), dtype=str)
        fh.writelines(",".join(row) + "\n" for row in rows)
