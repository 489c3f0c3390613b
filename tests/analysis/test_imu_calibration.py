"""Paper A calibration on the simulated hexapod with the ADIS16400's noise.

The logs use the shortened protocol (``paper_a_protocol(short=True)``: 3000-sample hold,
two 20 s beats of the gyro sines, a 0.02 Hz slow rotation, 20 s lever-arm motions, 30 s
verification), which keeps each simulation + calibration under a second; the accuracy
targets of the full protocol still hold there (K ~0.1 %, R < 1.1 mm over seeds 0-5).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis.errors import CalibrationError, LogError
from analysis.imu_calibration import (
    TABLE_A2,
    Calibration,
    apply_to_frame,
    calibrate,
    decompose,
    load_calibration,
    save_calibration,
)
from drivers.sim.hexapod_motions import Motion, Phase, paper_a_protocol
from drivers.sim.imu import ADIS16400, ImuModel
from drivers.sim.imu_calibration_log import simulate_calibration_log

MODEL = ADIS16400


def _frame(model: ImuModel = MODEL, seed: int = 0,
           phases: list[Phase] | None = None) -> pd.DataFrame:
    phases = phases if phases is not None else paper_a_protocol(model.rate_hz, short=True)
    df = pd.DataFrame(simulate_calibration_log(model, phases, seed=seed))
    df.attrs["path"] = "sim.csv"
    return df


def _rel(k: np.ndarray, k_true: np.ndarray) -> float:
    return float(np.linalg.norm(k - k_true) / np.linalg.norm(k_true))


@pytest.fixture(scope="module", params=[0, 1])
def result(request: pytest.FixtureRequest):
    df = _frame(seed=request.param)
    return df, calibrate(df, measured_mounting_deg=(0.0, 0.0, 17.0))


def test_k_matrices_within_0p2_percent(result) -> None:
    _, cal = result
    assert _rel(cal.kg, MODEL.k_gyro()) < 0.002
    assert _rel(cal.ka, MODEL.k_acc()) < 0.002


def test_lever_arm_within_2_mm_and_both_estimates_agree(result) -> None:
    _, cal = result
    assert np.abs(np.asarray(cal.lever_arm_m) - MODEL.lever_arm_m).max() < 0.002
    table = cal.lever_arm_estimates["table_a1_alpha_m"]
    for axis, comps in (("x", "yz"), ("y", "xz"), ("z", "xy")):
        assert sorted(table[axis]) == sorted(comps)  # Table A.1: two per rotation axis
    assert max(cal.lever_arm_estimates["agreement_m"]) < 0.003


def test_gyro_bias_within_three_standard_errors(result) -> None:
    _, cal = result
    z = (np.asarray(cal.gyro_bias_rad_s) - MODEL.gyro_bias_rad_s) / \
        np.asarray(cal.gyro_bias_stderr_rad_s)
    assert np.all(np.abs(z) < 3.0)


def test_time_offset_recovered(result) -> None:
    _, cal = result
    assert abs(cal.time_offset_s - MODEL.clock_offset_s) < 0.5e-3


def test_verification_no_worse_than_table_a2(result) -> None:
    _, cal = result
    v = cal.verification_rms
    for kind in ("acc_m_s2", "gyro_rad_s"):
        corrected = np.asarray(v[kind]["corrected"])
        assert np.all(corrected <= np.asarray(TABLE_A2[kind]))
        assert np.all(corrected < np.asarray(v[kind]["raw"]))  # the correction helps


def test_mounting_rotation_matches_measured_psi_17(result) -> None:
    _, cal = result
    for sensor in ("gyro", "acc"):
        d = cal.decomposition[sensor]
        assert d["rotation_vs_measured_deg"] < 0.1
        assert abs(d["euler_deg"][2] - 17.0) < 0.1


@pytest.mark.parametrize("offset", [-0.05, 0.0, 0.0137, 0.2])
def test_time_offsets_of_either_sign_are_recovered(offset: float) -> None:
    model = ImuModel(clock_offset_s=offset)
    phases = paper_a_protocol(model.rate_hz, short=True)[:2] + \
        paper_a_protocol(model.rate_hz, short=True)[2:8]
    cal = calibrate(_frame(model, seed=5, phases=phases))
    assert abs(cal.time_offset_s - offset) < 0.5e-3
    assert cal.verification_rms is None  # no verify phase in this log


def test_ignoring_a_20ms_lag_spoils_k() -> None:
    df = _frame(ImuModel(clock_offset_s=0.020), seed=2)
    ignored = calibrate(df, time_offset_s=0.0)
    estimated = calibrate(df)
    assert _rel(ignored.kg, MODEL.k_gyro()) > 0.002
    assert _rel(estimated.kg, MODEL.k_gyro()) < 0.002


def _gyro_phase(phase_y: float) -> Motion:
    amp = math.radians(4.0)
    return Motion("same_freq", 42.0, ((), (), (), ((amp, 0.65, 0.0),),
                                      ((amp, 0.65, phase_y),), ((amp, 0.7, 0.0),)))


def test_same_frequency_in_phase_is_refused() -> None:
    phases = paper_a_protocol(short=True)
    phases[1] = Phase("gyro", _gyro_phase(0.0))  # x and y identical: the thesis' failure
    with pytest.raises(CalibrationError, match="does not excite"):
        calibrate(_frame(phases=phases, seed=1), time_offset_s=MODEL.clock_offset_s)


def test_same_frequency_in_quadrature_is_separable() -> None:
    """Over whole periods sin and cos are orthogonal; only 0 or π phase is degenerate."""
    phases = paper_a_protocol(short=True)
    phases[1] = Phase("gyro", _gyro_phase(math.pi / 2))
    cal = calibrate(_frame(phases=phases, seed=1), time_offset_s=MODEL.clock_offset_s)
    assert cal.conditioning["gyro"] < 10
    assert _rel(cal.kg, MODEL.k_gyro()) < 0.003


def test_decompose_recovers_the_simulated_error_model() -> None:
    d = decompose(MODEL.k_gyro(), MODEL.mounting_deg)
    assert np.allclose(d["scale"], MODEL.gyro_scale)
    assert np.allclose(d["nonorthogonality_deg"], MODEL.gyro_nonorth_deg)
    assert np.allclose(d["euler_deg"], MODEL.mounting_deg, atol=1e-9)
    assert d["rotation_vs_measured_deg"] < 1e-9
    with pytest.raises(CalibrationError, match="reflection"):
        decompose(np.diag([1.0, -1.0, 1.0]))


def test_calibration_json_round_trip_and_apply(result, tmp_path: Path) -> None:
    df, cal = result
    path = save_calibration(cal, tmp_path / "cal.json")
    data = json.loads(path.read_text())
    for key in ("gyro_bias_rad_s", "k_gyro", "k_acc", "lever_arm_m", "time_offset_s",
                "verification_rms"):
        assert key in data
    back = load_calibration(path)
    assert np.allclose(back.kg, cal.kg) and back.time_offset_s == cal.time_offset_s
    verify = df[df["phase"] == "verify"].reset_index(drop=True)
    out = apply_to_frame(back, verify)
    assert len(out) >= len(verify) - 5  # only the edge rows the shift uncovers are dropped
    for i, a in enumerate("xyz"):
        err_w = out[f"gyro_{a}_rad_s"] - out[f"ref_omega_{a}_rad_s"]
        err_a = out[f"acc_{a}_m_s2"] - out[f"ref_acc_{a}_m_s2"]
        assert np.sqrt(np.mean(err_w**2)) <= TABLE_A2["gyro_rad_s"][i]
        assert np.sqrt(np.mean(err_a**2)) <= TABLE_A2["acc_m_s2"][i]


def test_bad_calibration_file_names_the_field(tmp_path: Path) -> None:
    path = tmp_path / "cal.json"
    path.write_text(json.dumps({"gyro_bias_rad_s": [0, 0, 0], "k_gyro": [[1, 0], [0, 1]]}))
    with pytest.raises(LogError, match=r"cal\.json: field k_gyro"):
        load_calibration(path)
    path.write_text("{not json")
    with pytest.raises(LogError, match="not a readable JSON"):
        load_calibration(path)


def test_weakly_excited_axis_warns_but_calibrates() -> None:
    big, small = math.radians(4.0), math.radians(0.6)
    weak = Motion("weak_z", 42.0, ((), (), (), ((big, 0.6, 0.0),), ((big, 0.65, 0.0),),
                                   ((small, 0.7, 0.0),)))
    phases = paper_a_protocol(short=True)
    phases[1] = Phase("gyro", weak)
    with pytest.warns(UserWarning, match="poorly conditioned"):
        cal = calibrate(_frame(phases=phases, seed=1), time_offset_s=MODEL.clock_offset_s)
    assert 3.0 < cal.conditioning["gyro"] < 10.0
    assert any("poorly conditioned" in w for w in cal.warnings)


def test_apply_moves_and_turns_the_magnetometer_with_the_imu() -> None:
    """A magnetometer in the IMU package: same time offset, turned by K_ω's mounting into the
    body frame (it was copied unchanged, in the IMU frame, next to a body-frame gyro)."""
    from scipy.spatial.transform import Rotation

    mount = Rotation.from_euler("xyz", [3.0, -2.0, 17.0], degrees=True).as_matrix()
    k = mount * 1.01  # body = K·(reading - b); a magnetometer's body field = mount·reading
    t = np.arange(400) / 200.0
    body_field = np.stack([20 * np.cos(t), 20 * np.sin(t), -44 + 0 * t], axis=1)
    offset = 0.05  # IMU row stamped t was measured at t - offset
    reading = np.stack([np.interp(t - offset, t, c) for c in (body_field @ mount).T], axis=1)
    df = pd.DataFrame({"t_s": t, **{f"imu_gyro_{a}_rad_s": 0.0 for a in "xyz"},
                       **{f"imu_acc_{a}_m_s2": [0.0, 0.0, 9.8][i] for i, a in enumerate("xyz")},
                       **{f"mag_{a}_ut": reading[:, i] for i, a in enumerate("xyz")}})
    cal = Calibration(gyro_bias_rad_s=[0.0] * 3, gyro_bias_stderr_rad_s=[0.0] * 3,
                      acc_bias_m_s2=[0.0] * 3, k_gyro=k.tolist(), k_acc=k.tolist(),
                      lever_arm_m=[0.0] * 3, time_offset_s=offset)
    out = apply_to_frame(cal, df)
    got = out[[f"mag_{a}_ut" for a in "xyz"]].to_numpy()
    want = body_field[np.isin(t, out["t_s"].to_numpy())]
    inner = slice(20, -20)  # the linear interpolations' ends
    assert np.abs(got - want)[inner].max() < 0.02  # µT of a ~48 µT field
    assert np.abs(reading[: len(got)] - want).max() > 5.0  # untouched it would be far off


def test_time_offset_with_a_huge_max_lag_is_unbounded_not_an_overflow() -> None:
    """--max-lag 1e308 ended in 'OverflowError: cannot convert float infinity to integer'."""
    from analysis.imu_calibration import estimate_time_offset

    t = np.arange(400) * 0.01
    ref = np.zeros((400, 3))
    ref[150:250, 2] = 1.0  # one rotation pulse
    gyro = np.roll(ref, 3, axis=0)  # 30 ms behind
    lag = estimate_time_offset(t, ref, gyro, np.zeros(3), max_lag_s=1e308)
    assert lag == pytest.approx(0.03, abs=0.01)
