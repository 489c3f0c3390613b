"""Reading BROAD HDF5 trials and project logs into one ImuRecording."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis.errors import LogError
from analysis.imu_recording import load_recording, read_broad

h5py = pytest.importorskip("h5py")


def _write_broad(path: Path, n: int = 20, rate: float = 100.0, **override) -> Path:
    rng = np.random.default_rng(0)
    data = {
        "imu_gyr": rng.normal(size=(n, 3)),
        "imu_acc": rng.normal(size=(n, 3)) + np.array([0, 0, 9.81]),
        "imu_mag": rng.normal(size=(n, 3)),
        "opt_quat": np.tile([1.0, 0, 0, 0], (n, 1)),
        "movement": (np.arange(n) >= n // 2).astype(np.uint8)[:, None],  # MAT-style column
    }
    data.update(override)
    with h5py.File(path, "w") as f:
        for k, v in data.items():
            if v is not None:
                f.create_dataset(k, data=v)
        f.attrs["sampling_rate"] = rate
    return path


def test_broad_reader_units_shapes_and_mask(tmp_path: Path) -> None:
    q = np.tile([1.0, 0, 0, 0], (20, 1))
    q[3] = np.nan  # optical marker loss stays NaN
    path = _write_broad(tmp_path / "t.hdf5", opt_quat=q)
    rec = load_recording(path)
    with h5py.File(path) as f:
        assert np.array_equal(rec.gyro_rad_s, f["imu_gyr"][:])
        assert np.array_equal(rec.acc_m_s2, f["imu_acc"][:])
        assert np.array_equal(rec.mag_ut, f["imu_mag"][:])
    assert rec.t_s[1] == pytest.approx(0.01) and rec.rate_hz == pytest.approx(100.0)
    assert rec.movement.dtype == bool and rec.movement.sum() == 10 and not rec.movement[9]
    assert np.isnan(rec.ref_quat[3]).all() and np.isfinite(rec.ref_quat[4]).all()


@pytest.mark.parametrize(("override", "message"), [
    ({"imu_gyr": None}, "dataset imu_gyr: missing"),
    ({"imu_acc": np.zeros((20, 2))}, "dataset imu_acc: expected shape (20, 3), got (20, 2)"),
    ({"imu_acc": np.full((20, 3), np.nan)}, "dataset imu_acc, sample 0: expected finite"),
    ({"movement": np.full(20, 2.0)}, "dataset movement, sample 0: expected 0 or 1"),
])
def test_broad_reader_refuses_bad_datasets(tmp_path: Path, override: dict, message: str
                                           ) -> None:
    path = _write_broad(tmp_path / "bad.hdf5", **override)
    with pytest.raises(LogError, match=None) as err:
        read_broad(path)
    assert str(path) in str(err.value) and message in str(err.value)


def test_broad_reader_rate_and_file_errors(tmp_path: Path) -> None:
    with pytest.raises(LogError, match="attribute sampling_rate: expected a rate in Hz > 0"):
        read_broad(_write_broad(tmp_path / "r.hdf5", rate=0.0))
    text = tmp_path / "text.hdf5"
    text.write_text("not hdf5")
    with pytest.raises(LogError, match=r"text\.hdf5: not a readable HDF5 file"):
        read_broad(text)
    with pytest.raises(LogError, match="file not found"):
        read_broad(tmp_path / "missing.hdf5")
    with pytest.raises(LogError, match="expected a BROAD trial"):
        load_recording(tmp_path / "x.mat")


def test_project_log_with_magnetometer_and_movement(tmp_path: Path) -> None:
    df = pd.DataFrame({"t_s": [0.0, 0.01, 0.02], "imu_gyro_x_rad_s": 0.1,
                       "imu_gyro_y_rad_s": 0.0, "imu_gyro_z_rad_s": 0.0,
                       "imu_acc_x_m_s2": 0.0, "imu_acc_y_m_s2": 0.0, "imu_acc_z_m_s2": 9.8,
                       "mag_x_ut": 1.0, "mag_y_ut": 2.0, "mag_z_ut": 3.0,
                       "movement": [0, 1, 1]})
    path = tmp_path / "raw.csv"
    df.to_csv(path, index=False)
    rec = load_recording(path)
    assert rec.gyro_rad_s[0, 0] == 0.1 and rec.mag_ut[2, 2] == 3.0
    assert rec.movement.tolist() == [False, True, True] and rec.ref_quat is None
    df["movement"] = [0, 2, 1]
    df.to_csv(path, index=False)
    with pytest.raises(LogError, match="row 2, line 3, column movement: expected 0 or 1"):
        load_recording(path)
    df["movement"] = [0, 1, 1]
    df.drop(columns=["mag_z_ut"]).to_csv(path, index=False)
    with pytest.raises(LogError, match=r"magnetometer needs all of .* missing mag_z_ut"):
        load_recording(path)


def test_shipped_broad_trial_07(shared_data: Path) -> None:
    path = shared_data / "broad" / "07_undisturbed_fast_rotation_B.hdf5"
    rec = read_broad(path)
    assert len(rec.t_s) == 52518 and rec.rate_hz == pytest.approx(285.714, abs=1e-3)
    assert rec.movement.sum() == 33617
    assert np.median(np.linalg.norm(rec.acc_m_s2, axis=1)) == pytest.approx(9.81, abs=0.2)
    ok = np.isfinite(rec.ref_quat).all(axis=1)
    assert np.allclose(np.linalg.norm(rec.ref_quat[ok], axis=1), 1.0, atol=1e-6)
