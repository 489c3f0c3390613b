"""Vibration: the simulated load cell's accelerometer, its spectrum's lines where the rotor
puts them, vibration against speed in `report`, and a stand log too slow for a spectrum."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis.errors import LogError
from analysis.run_record import read_run
from analysis.vibration import vibration_spectrum, vibration_vs_speed
from bench.cli import main
from tests.conftest import RIGS

RCB = "esc_test/rcbenchmark_Log_2019-11-05_171350.csv"


def _rig(fixtures_dir: Path, tmp_path: Path, imbalance: float, blade_pass: float,
         blades: int) -> Path:
    """sim-vibration.toml with other amplitudes and blade count, beside its thrust map."""
    src = RIGS / "sim-vibration.toml"
    text = src.read_text(encoding="utf-8")
    text = text.replace("vibration_imbalance_m_s2 = 3.0", f"vibration_imbalance_m_s2 = {imbalance}")
    text = text.replace("vibration_blade_pass_m_s2 = 1.5",
                        f"vibration_blade_pass_m_s2 = {blade_pass}")
    text = text.replace("vibration_blades = 2 ", f"vibration_blades = {blades} ")
    rig = tmp_path / "rig.toml"
    rig.write_text(text, encoding="utf-8")
    (tmp_path / "sim.thrust_map.csv").write_bytes(
        (RIGS / "sim.thrust_map.csv").read_bytes())
    return rig


# a spectrum needs a steady speed: Step 1 with 2 s holds (a sweep's ramp is no hold)
STEP = ["step", "--hold", "2", "--repeats", "2"]


def _step(rig: Path, out: Path, capsys) -> Path:
    assert main([*STEP, "--rig", str(rig), "--out", str(out)]) == 0
    capsys.readouterr()
    return next(out.glob("*-step1"))


@pytest.fixture(scope="module")
def shipped_step(fixtures_dir_module, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("vib")
    assert main([*STEP, "--rig", str(RIGS / "sim-vibration.toml"),
                 "--out", str(out)]) == 0
    return next(out.glob("*-step1"))


@pytest.fixture(scope="module")
def fixtures_dir_module() -> Path:
    from tests.conftest import FIXTURES

    return FIXTURES


def test_the_psd_peak_lands_at_the_rotor_frequency(shipped_step):
    rec = read_run(shipped_step)
    spec = vibration_spectrum(rec.samples, blades=2)
    # the rotor frequency from the hall sensor's speed over the same hold, not from the model
    t, rpm = rec.column("t_s"), rec.column("rpm")
    hold = (t >= spec.t0_s) & (t <= spec.t1_s)
    rotor_hz = float(np.median(rpm[hold])) / 60.0
    resolution = spec.f_hz[1] - spec.f_hz[0]
    assert spec.fs_hz == pytest.approx(25_000, rel=1e-3)
    assert abs(spec.peak_hz - rotor_hz) <= resolution
    # the blade pass is the second line: a local maximum at 2 x rotor, far above the floor
    k = int(np.argmin(np.abs(spec.f_hz - 2 * rotor_hz)))
    near = spec.psd[k - 2:k + 3]
    floor = np.median(spec.psd[(spec.f_hz > 3 * rotor_hz) & (spec.f_hz < 6 * rotor_hz)])
    assert near.max() > 100 * floor


def test_a_three_blade_rotor_with_little_imbalance_peaks_at_blade_pass(fixtures_dir,
                                                                      tmp_path, capsys):
    rec = read_run(_step(_rig(fixtures_dir, tmp_path, 0.3, 3.0, 3), tmp_path / "runs",
                          capsys))
    spec = vibration_spectrum(rec.samples, blades=3)
    resolution = spec.f_hz[1] - spec.f_hz[0]
    assert abs(spec.peak_hz - 3 * spec.rotor_hz) <= 1.5 * resolution


def test_a_rig_without_vibration_samples_exactly_as_before(fixtures_dir, tmp_path, capsys):
    plain = read_run(_step(RIGS / "sim.toml", tmp_path / "a", capsys))
    vib = read_run(_step(RIGS / "sim-vibration.toml", tmp_path / "b",
                          capsys))
    assert "acc_x_m_s2" not in plain.samples.columns
    for col in ("t_s", "thrust_n", "current_a", "voltage_v", "rpm"):
        np.testing.assert_array_equal(plain.column(col), vib.column(col), err_msg=col)


def test_report_shows_vibration_against_speed_and_the_spectrum(shipped_step, tmp_path,
                                                              capsys):
    out = tmp_path / "rep"
    assert main(["report", str(shipped_step), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "Vibration against speed" in text
    rid = shipped_step.name
    assert (out / f"vibration_{rid}.png").is_file()
    assert (out / f"vibration_psd_{rid}.png").is_file()
    rows = pd.read_csv(out / "vibration.csv")
    assert rows["run"].tolist() == [rid] and rows["source"].tolist() == ["acc_x_m_s2"]
    summary = json.loads((out / "report.json").read_text())["vibration"][rid]
    assert summary["spectrum"]["blades_from"] == "rig"
    levels = summary["against_speed"]["level_m_s2"]
    # imbalance and blade pass grow with speed^2 above the noise floor
    assert levels[-1] > 2 * levels[0]


def test_a_sweep_gets_vibration_against_speed_but_no_spectrum(fixtures_dir, tmp_path,
                                                              capsys):
    assert main(["sweep", "--rig", str(RIGS / "sim-vibration.toml"),
                 "--out", str(tmp_path / "runs")]) == 0
    run = next((tmp_path / "runs").glob("*-sweep"))
    capsys.readouterr()
    assert main(["report", str(run), "--out", str(tmp_path / "rep")]) == 0
    out = capsys.readouterr().out
    assert "Vibration against speed" in out
    assert "no vibration spectrum (no steady speed held for 0.5 s" in " ".join(out.split())
    assert (tmp_path / "rep" / f"vibration_{run.name}.png").is_file()
    assert not (tmp_path / "rep" / f"vibration_psd_{run.name}.png").exists()


def test_vibration_against_speed_is_the_rms_about_the_bin_mean():
    fs, a_ref = 5000.0, 2.0
    t = np.arange(0, 20, 1 / fs)
    rpm = np.repeat([2000.0, 4500.0, 7000.0, 10_000.0], t.size // 4)
    theta = np.cumsum(rpm / 60 * 2 * np.pi / fs)
    amp = a_ref * (rpm / 10_000) ** 2
    df = pd.DataFrame({"t_s": t, "rpm": rpm, "acc_x_m_s2": 9.0 + amp * np.sin(theta)})
    curve = vibration_vs_speed(df, bins=4)
    assert curve is not None and curve.kind == "rms of acceleration"
    np.testing.assert_allclose(curve.rpm, [2000, 4500, 7000, 10_000])
    np.testing.assert_allclose(curve.level_m_s2, a_ref * (curve.rpm / 10_000) ** 2 / np.sqrt(2),
                               rtol=0.01)
    assert vibration_vs_speed(df.drop(columns="acc_x_m_s2")) is None


def test_the_stand_logs_vibration_level_is_reported_and_its_rate_refuses_a_spectrum(
        shared_data):
    from analysis.importers import import_rcbenchmark

    df, _ = import_rcbenchmark(shared_data / RCB)
    curve = vibration_vs_speed(df)
    assert curve is not None and curve.source == "vibration_m_s2"
    assert curve.rpm[-1] > 15_000 and curve.level_m_s2.max() > 5.0  # m/s^2, not g
    with pytest.raises(LogError, match=r"sampled at 4\d(\.\d)? Hz \(Nyquist 2\d(\.\d)? Hz\), but "
                                       r"the rotor turns at \d+ Hz"):
        vibration_spectrum(df, blades=3)


def test_uneven_sampling_is_refused_even_at_a_high_rate():
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.5e-4, 1.5e-4, 40_000))
    df = pd.DataFrame({"t_s": t, "rpm": np.full(t.size, 6000.0),
                       "acc_x_m_s2": np.sin(2 * np.pi * 100 * t)})
    with pytest.raises(LogError, match="not evenly sampled"):
        vibration_spectrum(df, blades=2)


def test_report_blades_out_of_range_is_one_line(shipped_step, tmp_path, capsys):
    assert main(["report", str(shipped_step), "--blades", "0", "--out",
                 str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert "--blades: expected a whole number 1-12, got 0" in err
    assert "Traceback" not in err and not (tmp_path / "r").exists()


def test_report_blades_without_a_vibration_run_says_so(fixtures_dir, tmp_path, capsys):
    assert main(["sweep", "--out", str(tmp_path / "runs")]) == 0
    run = next((tmp_path / "runs").glob("*-sweep"))
    capsys.readouterr()
    assert main(["report", str(run), "--blades", "3", "--out", str(tmp_path / "rep")]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "--blades: no run has a vibration column" in out
    assert "Vibration against speed" not in out
