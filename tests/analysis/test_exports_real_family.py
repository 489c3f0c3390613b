"""Exports on the esc_test family: SPIN_MAX only where the curve really flattens, a vehicle
that cannot hover is refused, Gazebo's momentConstant is a positive magnitude, and the static
thrust coefficient of a jittery stand log agrees with an independent least-squares fit."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from analysis.errors import LogError
from analysis.exports import ThrustCurve, ardupilot_params, gazebo_params
from bench.cli import main

RCB = "esc_test/rcbenchmark_Log_2019-11-05_171350.csv"


def test_one_flat_bin_in_a_rising_curve_is_not_saturation():
    a = np.linspace(0.0, 1.0, 21)
    t = 12.0 * a**1.5
    t[13] = t[12] + 0.05  # a plateau's median a little low: the slope dips once
    out = ardupilot_params(ThrustCurve(a, t))
    assert out["MOT_SPIN_MAX"] is None
    assert any("does not saturate" in n for n in out["notes"])
    t_sat = np.minimum(12.0 * a**1.5, 12.0 * 0.85**1.5)  # really flat from 0.85 on
    assert ardupilot_params(ThrustCurve(a, t_sat))["MOT_SPIN_MAX"] == pytest.approx(0.85)


def test_a_vehicle_that_cannot_hover_is_refused():
    a = np.linspace(0.0, 1.0, 21)
    c = ThrustCurve(a, 10.0 * a**2, "stand")
    out = ardupilot_params(c, hover_thrust_n=8.0)  # SPIN_MAX 0.95 (default): 9.025 N
    assert out["MOT_THST_HOVER"] == pytest.approx(8.0 / 9.025, abs=1e-4)
    with pytest.raises(LogError, match=r"stand: MOT_THST_HOVER: the vehicle cannot hover: it "
                                       r"needs 20\.6 N per motor, .*at most 9\.02 N"):
        ardupilot_params(c, hover_thrust_n=20.6)


def test_moment_constant_is_a_positive_magnitude():
    out = gazebo_params(1e-6, -0.012, None, None, 1500.0, True)
    assert out["momentConstant"] == pytest.approx(0.012)
    assert any("opposite sign" in n for n in out["notes"])
    out = gazebo_params(1e-6, 0.012, None, None, 1500.0, True)
    assert out["momentConstant"] == pytest.approx(0.012)
    assert not any("opposite sign" in n for n in out["notes"])


def _independent_k_f(src):
    raw = pd.read_csv(src, encoding="utf-8-sig")
    thrust = raw["Thrust (gf)"].to_numpy(float) * 9.80665e-3
    w = raw["Motor Electrical Speed (RPM)"].to_numpy(float) * 2 * math.pi / 60
    ok = np.isfinite(thrust) & (w > 0)
    return float(np.linalg.lstsq((w[ok] ** 2)[:, None], thrust[ok], rcond=None)[0][0])


@pytest.mark.parametrize("seed", [1, 2])
def test_jittery_stand_log_gives_k_f_and_a_positive_moment_constant(logfamily, tmp_path,
                                                                      capsys, seed):
    src = logfamily.rcbenchmark_log(tmp_path / "Log.csv", steps_back=4, seed=seed)
    run = tmp_path / "r"
    assert main(["import", str(src), "--format", "rcbenchmark", "--out", str(run)]) == 0
    capsys.readouterr()
    assert main(["export", "gazebo", str(run), "--json"]) == 0
    gz = json.loads(capsys.readouterr().out)
    assert gz["motorConstant"] == pytest.approx(_independent_k_f(src), rel=0.03)
    assert gz["motorConstant"] == pytest.approx(logfamily.K_F, rel=0.03)
    # the family's torque reads negative: exported as the magnitude, with the reason
    assert gz["momentConstant"] == pytest.approx(logfamily.K_Q / logfamily.K_F, rel=0.05)
    assert any("opposite sign" in n for n in gz["notes"])


def test_shipped_stand_log_k_f_matches_an_independent_fit(shared_data, tmp_path, capsys):
    run = tmp_path / "r"
    assert main(["import", str(shared_data / RCB), "--format", "rcbenchmark", "--out",
                 str(run)]) == 0
    capsys.readouterr()
    assert main(["export", "gazebo", str(run), "--json"]) == 0
    gz = json.loads(capsys.readouterr().out)
    assert gz["motorConstant"] == pytest.approx(_independent_k_f(shared_data / RCB), rel=0.03)
    assert gz["momentConstant"] > 0
