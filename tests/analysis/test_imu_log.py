"""Log validation: every bad input names the file, row and column."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis.errors import LogError
from analysis.imu_log import (
    CALIBRATION_COLUMNS,
    load_attitude_log,
    load_calibration_log,
    load_imu_log,
)

PHASES = ["bias", "gyro", "acc", "lever_x", "lever_y", "lever_z", "verify"]


def _log(rows_per_phase: int = 3) -> pd.DataFrame:
    n = rows_per_phase * len(PHASES)
    df = pd.DataFrame({c: np.zeros(n) for c in CALIBRATION_COLUMNS})
    df["t_s"] = np.arange(n) * 0.01
    df["phase"] = np.repeat(PHASES, rows_per_phase)
    return df


def _write(df: pd.DataFrame, path: Path) -> Path:
    if path.suffix == ".csv":
        df.to_csv(path, index=False)
    else:
        df.to_parquet(path, index=False)
    return path


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_valid_log_loads(tmp_path: Path, suffix: str) -> None:
    df = load_calibration_log(_write(_log(), tmp_path / f"log{suffix}"))
    assert len(df) == 21 and df["imu_acc_z_m_s2"].dtype == float


def test_missing_column_is_named(tmp_path: Path) -> None:
    path = _write(_log().drop(columns=["ref_alpha_y_rad_s2"]), tmp_path / "log.csv")
    with pytest.raises(LogError, match=r"log\.csv: missing column\(s\) ref_alpha_y_rad_s2"):
        load_calibration_log(path)


def test_bad_number_names_row_line_and_column(tmp_path: Path) -> None:
    df = _log().astype({"imu_gyro_y_rad_s": object})
    df.loc[4, "imu_gyro_y_rad_s"] = "abc"
    with pytest.raises(LogError, match=r"log\.csv: row 5, line 6, column imu_gyro_y_rad_s: "
                                       r"expected a finite number, got 'abc'"):
        load_calibration_log(_write(df, tmp_path / "log.csv"))


def test_bad_phase_names_row(tmp_path: Path) -> None:
    df = _log()
    df.loc[7, "phase"] = "wobble"
    with pytest.raises(LogError, match=r"row 8, line 9, column phase: expected one of bias"):
        load_calibration_log(_write(df, tmp_path / "log.csv"))


def test_missing_phase_and_time_order(tmp_path: Path) -> None:
    df = _log()
    with pytest.raises(LogError, match=r"no rows for phase.*lever_y"):
        load_calibration_log(_write(df[df["phase"] != "lever_y"], tmp_path / "a.parquet"))
    df.loc[10, "t_s"] = df.loc[9, "t_s"]
    with pytest.raises(LogError, match=r"b\.parquet: row 11, column t_s: time must increase"):
        load_calibration_log(_write(df, tmp_path / "b.parquet"))


def test_unreadable_and_wrong_files(tmp_path: Path) -> None:
    with pytest.raises(LogError, match="file not found"):
        load_calibration_log(tmp_path / "none.csv")
    with pytest.raises(LogError, match=r"expected a \.csv or \.parquet"):
        load_calibration_log(tmp_path / "log.txt")
    bad = tmp_path / "bad.parquet"
    bad.write_text("not parquet")
    with pytest.raises(LogError, match="cannot be read as parquet"):
        load_calibration_log(bad)


def _attitude(n: int = 5) -> pd.DataFrame:
    df = pd.DataFrame({"t_s": np.arange(n) * 0.01})
    for a in "xyz":
        df[f"gyro_{a}_rad_s"] = 0.0
        df[f"acc_{a}_m_s2"] = 9.81 if a == "z" else 0.0
    return df


def test_attitude_log_reference_columns(tmp_path: Path) -> None:
    df = _attitude()
    df["ref_qw"] = [1.0, np.nan, 1.0, 1.0, 1.0]  # marker loss is allowed
    for c in "xyz":
        df[f"ref_q{c}"] = 0.0
    assert len(load_attitude_log(_write(df, tmp_path / "ok.csv"))) == 5
    with pytest.raises(LogError, match="missing ref_qz"):
        load_attitude_log(_write(df.drop(columns=["ref_qz"]), tmp_path / "part.csv"))
    df["ref_qx"] = df["ref_qx"].astype(object)
    df.loc[2, "ref_qx"] = "x"
    with pytest.raises(LogError, match="row 3, line 4, column ref_qx"):
        load_attitude_log(_write(df, tmp_path / "text.csv"))


def test_imu_log_accepts_both_naming_schemes(tmp_path: Path) -> None:
    df = _attitude()
    assert len(load_imu_log(_write(df, tmp_path / "plain.csv"))) == 5
    with pytest.raises(LogError, match="missing column"):
        load_imu_log(_write(df.drop(columns=["acc_x_m_s2"]), tmp_path / "short.csv"))
