"""Autopilot exports: known curves are recovered; the real F40 test and the sim export."""

from __future__ import annotations

import json

import numpy as np
import pytest

from analysis import exports as exports_module
from analysis import step_response
from analysis.errors import LogError
from analysis.exports import (
    ThrustCurve,
    ardupilot_params,
    expo_webtool,
    px4_params,
)
from bench.cli import main
from bench.plan_runner.runner import RunOptions
from bench.plan_runner.session import run_sequence
from bench.plans.stand_sequences import hover_band_n, step1, sweep
from bench.rig.rig import default_rig_path, load_rig
from drivers.factory import open_rig


def ardupilot_curve(expo: float, spin_min: float, spin_max: float, t_max: float = 10.0):
    """Thrust the ArduPilot model expects: T = (1 - e) x + e x^2 over [SPIN_MIN, SPIN_MAX],
    nothing below SPIN_MIN, flat (saturated) above SPIN_MAX."""
    a = np.linspace(0.0, 1.0, 101)
    x = np.clip((a - spin_min) / (spin_max - spin_min), 0.0, 1.0)
    return a, t_max * ((1 - expo) * x + expo * x * x)


@pytest.mark.parametrize("expo", [0.0, 0.45, 0.8])
def test_ardupilot_recovers_expo_and_spin_limits(expo):
    a, t = ardupilot_curve(expo, 0.12, 0.9)
    out = ardupilot_params(ThrustCurve(a, t), hover_thrust_n=4.0)
    assert out["MOT_THST_EXPO"] == pytest.approx(expo, abs=0.01)
    assert out["MOT_SPIN_MIN"] == pytest.approx(0.12, abs=0.02)
    assert out["MOT_SPIN_MAX"] == pytest.approx(0.9, abs=0.011)
    assert out["expo_webtool"] == pytest.approx(expo, abs=0.03)
    assert out["MOT_THST_HOVER"] == pytest.approx(0.4, abs=0.01)  # 4 N of 10 N
    assert out["fit_rms"] < 0.01


def test_ardupilot_keeps_defaults_where_data_is_silent():
    a = np.linspace(0.3, 0.8, 20)  # no start of thrust, no saturation in the data
    out = ardupilot_params(ThrustCurve(a, 5 * a**2))
    assert out["MOT_SPIN_MIN"] is None and out["MOT_SPIN_MAX"] is None
    assert any("SPIN_MIN" in n for n in out["notes"])
    assert any("SPIN_MAX" in n for n in out["notes"])
    with pytest.raises(LogError, match=">= 4"):
        ThrustCurve(a[:3], a[:3])


@pytest.mark.parametrize("fac", [0.0, 0.3, 0.7, 1.0])
def test_px4_recovers_thr_mdl_fac(fac):
    s = np.linspace(0.0, 1.0, 30)
    out = px4_params(ThrustCurve(1000 + 1000 * s, 8.0 * (fac * s * s + (1 - fac) * s)))
    assert out["THR_MDL_FAC"] == pytest.approx(fac, abs=1e-3)


def test_webtool_expo_is_the_most_linear():
    a, t = ardupilot_curve(0.6, 0.1, 0.95)
    c = ThrustCurve(a, t)
    assert expo_webtool(c, 0.1, 0.95) == pytest.approx(0.6, abs=0.01)


@pytest.fixture
def real_runs(shared_data, tmp_path):
    src = shared_data / "esc_test"
    assert main(["import", str(src / "rcbenchmark_Log_2019-11-05_171350.csv"),
                 "--format", "rcbenchmark", "--out", str(tmp_path / "rcb")]) == 0
    assert main(["import", str(src / "autoquad_esc32_f40_steps_5-2.csv"),
                 "--format", "esc32", "--out", str(tmp_path / "esc32")]) == 0
    return tmp_path / "rcb", tmp_path / "esc32"


def _json(capsys, argv):
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_real_f40_exports(real_runs, capsys):
    rcb, esc32 = real_runs
    ap = _json(capsys, ["export", "ardupilot", str(esc32), "--thrust-run", str(rcb),
                        "--auw-kg", "1.5", "--motors", "4", "--json"])
    assert -0.2 < ap["MOT_THST_EXPO"] < 0.6  # ESC32 duty is close to linear in thrust
    assert abs(ap["MOT_THST_EXPO"] - ap["expo_webtool"]) < 0.15
    assert 0.0 < ap["MOT_SPIN_MIN"] < 0.15  # the rotor starts between 0 and 10 % duty
    assert ap["MOT_THST_HOVER"] == pytest.approx(1.5 * 9.80665 / 4 / ap["thrust_at_spin_max_n"],
                                                 abs=1e-3)
    px4 = _json(capsys, ["export", "px4", str(esc32), "--thrust-run", str(rcb), "--json"])
    assert 0.0 <= px4["THR_MDL_FAC"] <= 1.0
    gz = _json(capsys, ["export", "gazebo", str(esc32), "--thrust-run", str(rcb), "--json"])
    assert 3e-6 < gz["motorConstant"] < 6e-6
    assert 0.005 < gz["momentConstant"] < 0.03
    assert gz["maxRotVelocity"] > 1600 and gz["notes"] == [
        "timeConstantUp/Down: give a step run (--step-run) to fit them"]
    # the stand log alone has no command column
    assert main(["export", "ardupilot", str(rcb)]) == 2
    assert "no command column" in capsys.readouterr().err


def test_sim_gazebo_export_matches_the_plant(tmp_path, capsys, monkeypatch):
    rig = load_rig(default_rig_path())
    opts = RunOptions(tick_s=0.02)
    sw = run_sequence(rig, sweep(duration_s=6.0), tmp_path, open_rig, options=opts).run_dir
    st = run_sequence(rig, step1(repeats=3, hold_s=0.5, band_n=hover_band_n()), tmp_path,
                      open_rig, options=opts).run_dir
    with open_rig(rig) as devices:
        truth = devices.truth()
    gz = _json(capsys, ["export", "gazebo", str(sw), "--step-run", str(st), "--json"])
    assert gz["motorConstant"] == pytest.approx(truth.params.thrust_k, rel=0.02)
    hover = 0.25 * 9.80665
    assert gz["timeConstantUp"] == pytest.approx(truth.tau_up_s(hover), rel=0.05)
    assert gz["timeConstantDown"] == pytest.approx(truth.tau_dn_s(hover), rel=0.05)
    assert gz["momentConstant"] is None
    # --out: the parameters to a file, and beside it their uncertainties, from one fit of
    # each run (the sidecar budgets the fits the parameters came from)
    fitted: list[str] = []
    for module, name in ((exports_module, "fit_static_run"), (step_response, "fit_run")):
        real = getattr(module, name)
        monkeypatch.setattr(module, name, lambda *a, _real=real, _name=name, **k:
                            fitted.append(_name) or _real(*a, **k))
    sdf = tmp_path / "motor.sdf"
    assert main(["export", "gazebo", str(sw), "--step-run", str(st), "--out", str(sdf)]) == 0
    assert sorted(fitted) == ["fit_run", "fit_static_run"]
    assert capsys.readouterr().out.startswith(f"wrote {sdf} and ")
    assert f"<motorConstant>{gz['motorConstant']}</motorConstant>" in sdf.read_text()
    side = json.loads((tmp_path / "motor.uncertainty.json").read_text())
    assert side["target"] == "gazebo" and side["without_budget"] == ["maxRotVelocity"]
    kf, up = side["constants"]["motorConstant"], side["constants"]["timeConstantUp"]
    assert kf["run"] == sw.name and up["run"] == st.name and kf["calibrations"] == []
    assert kf["value"] == pytest.approx(gz["motorConstant"], rel=1e-5)
    assert up["value"] == pytest.approx(gz["timeConstantUp"], rel=1e-3)
    for c in (kf, up):
        assert c["k"] == 2 and c["U"] == pytest.approx(2 * c["u"]) and c["budget"]
        assert 0 < c["u"] < 0.05 * c["value"] and "dof_eff" in c
    ap = _json(capsys, ["export", "ardupilot", str(sw), "--hover-thrust", str(hover),
                        "--json"])
    assert ap["command_axis"] == "throttle_us over 1000-2000"
    assert 0.0 < ap["MOT_SPIN_MIN"] < 0.15
    assert 0.0 < ap["MOT_THST_HOVER"] < 1.0


def test_a_step_run_or_a_fast_sweep_is_not_a_static_curve(tmp_path, capsys):
    """`export ardupilot STEP_RUN` gave MOT_THST_EXPO 0.71 (the sweep of the
    same rig 0.385) from the lagging transients between the step levels and from idle. A
    run whose steady commands leave part of its range uncovered is refused, naming the
    sweep command; the sweep itself still exports."""
    rig = load_rig(default_rig_path())
    opts = RunOptions(tick_s=0.02)
    sw = run_sequence(rig, sweep(duration_s=6.0), tmp_path, open_rig, options=opts).run_dir
    fast = run_sequence(rig, sweep(duration_s=1.0), tmp_path, open_rig, options=opts).run_dir
    st = run_sequence(rig, step1(repeats=2, hold_s=0.5, band_n=hover_band_n()), tmp_path,
                      open_rig, options=opts).run_dir
    for run in (st, fast):
        for target in ("ardupilot", "px4"):
            assert main(["export", target, str(run)]) == 2
            err = capsys.readouterr().err
            assert f"{run}: not a static sweep: its command never holds still" in err
            assert "(`rotorbench sweep`)" in err and len(err.splitlines()) == 1
    assert _json(capsys, ["export", "ardupilot", str(sw), "--json"])["MOT_THST_EXPO"] > 0
