"""Static curves (Paper C section 4.4) and motor constants from parameters (2.37, C.3, C.4)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.errors import LogError
from analysis.flight_time import flight_time_min, hover_current_a
from analysis.importers import import_rcbenchmark
from analysis.run_record import read_run
from analysis.static_curves import (
    RPM_TO_RAD_S,
    TABLE_C2,
    MotorParams,
    fit_static,
    fit_static_run,
    from_parameters,
    lsq_through_origin,
    motor_constants,
)
from bench.plan_runner.runner import RunOptions
from bench.plan_runner.session import run_sequence
from bench.plans.stand_sequences import sweep
from bench.rig.rig import default_rig_path, load_rig
from drivers.factory import open_rig


def test_ke_kt_from_kv_2_37():
    ke, kt = motor_constants(920.0)
    assert ke == kt == pytest.approx(60 / (2 * math.pi * 920))
    assert ke == pytest.approx(0.0104, abs=5e-5)  # Table C.2 rounds it to 0.0104
    with pytest.raises(ValueError):
        motor_constants(0.0)


def test_from_parameters_c3_c4():
    tau, gain = from_parameters(TABLE_C2)
    ke, kt = motor_constants(TABLE_C2.kv_rpm_v)
    r, j, d = TABLE_C2.r_ohm, TABLE_C2.j_kg_m2, TABLE_C2.d_a_s_rad
    assert tau == pytest.approx(j * r / (r * kt * d + kt * ke))
    assert gain == pytest.approx(ke / (r * d + ke))
    assert round(tau * 1e3) == 32  # the "From Parameters" row of Table C.1
    # more damping (a heavier-loaded propeller) makes the lag faster and the gain smaller
    tau2, gain2 = from_parameters(TABLE_C2, d_a_s_rad=0.008)
    assert tau2 < tau and gain2 < gain
    with pytest.raises(ValueError, match="damping"):
        from_parameters(MotorParams(920.0, 0.22, 17e-6))


def test_fit_recovers_synthetic_curves_and_inverse():
    rng = np.random.default_rng(1)
    rpm = np.repeat(np.linspace(2000, 12000, 40), 50)
    w = rpm * RPM_TO_RAD_S
    thrust = 2.0e-6 * w**2 + 1e-4 * w + rng.normal(0, 0.01, w.size)
    current = 0.5 + 2e-9 * w**3 + rng.normal(0, 0.05, w.size)
    torque = 3e-8 * w**2
    thrust[::3] = np.nan  # a slower load cell: gaps are ignored, not filled
    s = fit_static(rpm, thrust, current, torque)
    _c0, c1, c2 = s.thrust_poly.convert().coef
    assert c2 == pytest.approx(2.0e-6, rel=0.02) and c1 == pytest.approx(1e-4, abs=3e-5)
    assert s.k_q == pytest.approx(3e-8, rel=1e-6)
    assert s.moment_constant_m == pytest.approx(s.k_q / s.k_f)
    f = np.array([1.0, 2.0, 4.0])
    np.testing.assert_allclose(s.thrust_at(s.omega_for_thrust(f)), f, rtol=1e-9)
    assert s.current_rms_binned < 0.02  # the medians; the raw samples carry the 0.05 A noise
    assert s.current_rms == pytest.approx(0.05, rel=0.1)
    assert s.damping_at(800.0) == pytest.approx(3 * 2e-9 * 800**2, rel=0.05)


def test_k_f_spread_is_that_of_one_speed_level():
    # the spread of one point is sqrt(n) times the least-squares standard error, which
    # scipy's curve_fit gives independently (its covariance of k in y = k x)
    from scipy.optimize import curve_fit

    rng = np.random.default_rng(2)
    w = np.linspace(300.0, 1200.0, 40)
    thrust = 2e-6 * w**2 + rng.normal(0, 0.02, w.size)
    k, spread = lsq_through_origin(w**2, thrust)
    (k_ref,), cov = curve_fit(lambda x, kk: kk * x, w**2, thrust, p0=[1e-6])
    assert k == pytest.approx(k_ref, rel=1e-9)
    assert spread == pytest.approx(math.sqrt(cov[0, 0]) * math.sqrt(w.size), rel=1e-6)
    # the noise of one point over the RMS of w^2: the k_f one level alone would give
    assert spread == pytest.approx(0.02 / math.sqrt(np.mean(w**4)), rel=0.3)
    thrust[::4] = np.nan  # gaps are left out, not counted
    assert math.isfinite(lsq_through_origin(w**2, thrust)[1])
    assert math.isnan(lsq_through_origin(w[:1] ** 2, thrust[:1])[1])  # one point: no spread
    s = fit_static(np.repeat(w / RPM_TO_RAD_S, 20), np.repeat(thrust, 20))
    assert s.summary()["k_f_std_n_s2"] == s.k_f_std and 0 < s.k_f_std < 0.1 * s.k_f
    assert s.summary()["k_q_std_nm_s2"] is None  # no torque logged


def test_no_spin_is_a_log_error():
    with pytest.raises(LogError, match="never turns"):
        fit_static(np.zeros(10), np.zeros(10))


def test_sim_sweep_gives_the_plants_thrust_constant(tmp_path):
    rig = load_rig(default_rig_path())
    out = run_sequence(rig, sweep(duration_s=6.0), tmp_path, open_rig,
                       options=RunOptions(tick_s=0.02))
    with open_rig(rig) as devices:
        truth = devices.truth()
    s = fit_static_run(read_run(out.run_dir))
    assert s.k_f == pytest.approx(truth.params.thrust_k, rel=0.02)
    # current rises with speed; its slope at hover is the D of Fig. C.5 (positive, small)
    w_hover = s.omega_for_thrust(0.25 * 9.80665)
    assert 0 < s.damping_at(float(w_hover)) < 0.05
    assert math.isnan(s.moment_constant_m)  # the sim stand logs no torque


def test_real_f40_static_curves(shared_data):
    df, _ = import_rcbenchmark(shared_data / "esc_test/rcbenchmark_Log_2019-11-05_171350.csv")
    s = fit_static(df["rpm"], df["thrust_n"], df["current_a"], df["torque_nm"], df["voltage_v"])
    # thrust follows w^2 closely: the quadratic fits the plateaus (binned medians) to a
    # few % of full thrust; single samples scatter more (load-cell noise, transients)
    assert s.thrust_rms_binned < 0.02 * np.nanmax(df["thrust_n"])
    assert s.thrust_rms_binned < s.thrust_rms < 0.05 * np.nanmax(df["thrust_n"])
    pred = s.k_f * s.omega**2
    ok = np.isfinite(s.thrust)
    assert np.sqrt(np.mean((pred[ok] - s.thrust[ok]) ** 2)) < 0.05 * np.nanmax(s.thrust)
    assert 0.005 < s.moment_constant_m < 0.03  # torque/thrust of a 7 in three-blade prop
    # one speed level's k_f and k_q scatter by a few % about the fit (2.3 %, 1.5 %):
    # the pure w^2 law is not exact over the range, and each level is a handful of samples
    assert 0.01 < s.k_f_std / s.k_f < 0.04 and 0.005 < s.k_q_std / s.k_q < 0.03
    assert s.omega_max / RPM_TO_RAD_S > 15000


def test_flight_time_from_measured_current():
    # Paper E section 4: capacity (Ah) / (measured current x number of actuators)
    assert flight_time_min(4000, 2.0, 4) == pytest.approx(30.0)
    # a bench supply of 16 V against an 11.1 V battery: equal power, more current
    assert flight_time_min(4000, 2.0, 4, 16.0, 11.1) == pytest.approx(30.0 * 11.1 / 16.0)
    with pytest.raises(ValueError):
        flight_time_min(4000, 0.0, 4)
    rpm = np.repeat(np.linspace(2000, 12000, 30), 5)
    w = rpm * RPM_TO_RAD_S
    s = fit_static(rpm, 2e-6 * w**2, 0.2 + 1e-8 * w**3)
    w_h = math.sqrt(2.0 / 2e-6)
    assert hover_current_a(s, 2.0) == pytest.approx(0.2 + 1e-8 * w_h**3, rel=1e-3)
    with pytest.raises(LogError, match="outside the measured thrust range"):
        hover_current_a(s, 100.0)


def test_thrust_rms_is_the_raw_residual_and_the_binned_one_is_labelled():
    # noise 0.2 N on every sample: the raw residual is the noise, the binned medians' is
    # far smaller (the report used to show only the latter as "thrust rms")
    rng = np.random.default_rng(4)
    rpm = np.repeat(np.linspace(2000, 12000, 30), 200)
    w = rpm * 2 * np.pi / 60
    thrust = 1.1e-6 * w**2 + rng.normal(0, 0.2, rpm.size)
    s = fit_static(rpm, thrust)
    assert s.thrust_rms == pytest.approx(0.2, rel=0.05)
    assert s.thrust_rms_binned < 0.05
    sm = s.summary()
    assert sm["thrust_rms_n"] == s.thrust_rms and sm["thrust_rms_binned_n"] == s.thrust_rms_binned


def test_slope_noise_from_interleaved_sub_sweeps_is_the_slopes_scatter():
    # a slow sweep read by a counter that holds each period's mean speed for the period
    # (a staircase, no lag) with white thrust noise: over 40 noise draws, k_f's own
    # scatter is what its replicate u says, and the bins' medians, paired, leave no bias
    w_true = np.linspace(300.0, 1200.0, 29_997)
    held = np.repeat(w_true.reshape(-1, 11).mean(axis=1), 11)
    k_true, ks, us = 2e-6, [], []
    for seed in range(40):
        noise = np.random.default_rng(seed).normal(0.0, 0.03, w_true.size)
        s = fit_static(held / RPM_TO_RAD_S, k_true * w_true**2 + noise)
        ks.append(s.k_f)
        us.append(s.k_f_u)
    sd, u = float(np.std(ks, ddof=1)), float(np.mean(us))
    assert 0.7 < u / sd < 1.4, (u, sd)
    assert abs(np.mean(ks) - k_true) < 3 * sd / math.sqrt(40) + 1e-4 * k_true
