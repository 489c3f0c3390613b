"""Accuracy of the step fit against the simulated plant's truth (drivers.sim, OpenRig.truth).

The sim's true time constant is the plant linearised at a thrust (``truth.tau_up_s``, C.3 /
E.8 with the propeller's drag slope as D), which is what a fit of a small step around that
thrust measures; the runs here step +-2 % (noiseless) and +-5 % (with the documented sensor
noise) around hover and compare with the truth at the middle of the band. Noiseless runs are
fitted on the rotor speed (the state the time constant belongs to; without noise the load
cell's 16-bit ADC steps are not dithered, and thrust ~ w^2 bends larger steps), noisy runs
on both the load-cell thrust and the speed. The latency is compared with the ESC firmware's
latency (commands leave on frame boundaries, so the frame wait is zero; the load cell adds a
fraction of a millisecond): it must be within one ESC frame. The large Paper C Step 1 (175 g
<-> 325 g) is used for the Table C.1 pattern of the three ESC modes.
"""

from __future__ import annotations

import dataclasses

import pytest

from analysis.run_record import read_run
from analysis.static_curves import TABLE_C2
from analysis.step_response import fit_run
from analysis.validation import validate_run
from bench.cli import main
from bench.plan_runner.runner import RunOptions
from bench.plan_runner.session import run_sequence
from bench.plans.sequences import G0
from bench.plans.stand_sequences import hover_band_n, step1, step2
from bench.rig.rig import default_rig_path, load_rig
from drivers.factory import open_rig

HOVER_N = 0.25 * G0  # Paper C: 250 g per rotor of the 1 kg quadcopter


def _run(tmp, mode: str, noise: bool, band: tuple[float, float], repeats: int = 4,
         seq=step1):
    rig = load_rig(default_rig_path()).with_esc_mode(mode)
    rig = dataclasses.replace(rig, sim=dataclasses.replace(rig.sim, noise=noise))
    seq = seq(repeats=repeats, hold_s=0.6, settle_s=0.5, band_n=band)
    out = run_sequence(rig, seq, tmp, open_rig, options=RunOptions(tick_s=0.02))
    with open_rig(rig) as devices:
        truth = devices.truth()
    return read_run(out.run_dir), truth


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("accuracy")
    small = {False: 0.02, True: 0.05}
    out = {}
    for mode in ("complementary", "diode", "stock"):
        for noise, rel in small.items():
            band = (HOVER_N * (1 - rel), HOVER_N * (1 + rel))
            out[(mode, noise)] = _run(tmp, mode, noise, band)
        out[(mode, "step1")] = _run(tmp, mode, True, hover_band_n(), repeats=5)
    for mode in ("complementary", "diode"):
        out[(mode, "step2")] = _run(tmp, mode, True, hover_band_n(), repeats=2, seq=step2)
    return out


def _tol(noise: bool) -> float:
    return 0.05 if noise else 0.01


CASES = [(False, "rpm"), (True, "thrust"), (True, "rpm")]


@pytest.mark.parametrize(("noise", "signal"), CASES)
def test_complementary_time_constants_and_latency(runs, noise, signal):
    record, truth = runs[("complementary", noise)]
    fit = fit_run(record, signal=signal)
    assert fit.up.tau.n == 4 and fit.down.tau.n == 4
    assert fit.up.tau.value == pytest.approx(truth.tau_up_s(HOVER_N), rel=_tol(noise))
    assert fit.down.tau.value == pytest.approx(truth.tau_dn_s(HOVER_N), rel=_tol(noise))
    for d in (fit.up, fit.down):
        assert abs(d.latency.value - truth.latency_s) < truth.frame_period_s
        assert d.gain.value == pytest.approx(1.0, rel=0.05) if signal == "thrust" else True


@pytest.mark.parametrize(("noise", "signal"), CASES)
def test_diode_small_steps_are_driven_both_ways(runs, noise, signal):
    # a small step down never needs reverse winding current, so the body diode does not
    # conduct and the plant decelerates with its driven time constant (truth.tau_up_s);
    # truth.tau_dn_s is the coasting constant of large steps (see the Step 1 pattern test)
    record, truth = runs[("diode", noise)]
    fit = fit_run(record, signal=signal)
    assert fit.up.tau.value == pytest.approx(truth.tau_up_s(HOVER_N), rel=_tol(noise))
    assert fit.down.tau.value == pytest.approx(truth.tau_up_s(HOVER_N), rel=_tol(noise))
    assert abs(fit.up.latency.value - truth.latency_s) < truth.frame_period_s


@pytest.mark.parametrize("noise", [False, True])
def test_stock_second_order_fit_finds_filter_and_rotor(runs, noise):
    # the stock firmware low-pass filters the throttle: two lags in series, which the
    # second-order option (C.1 form) separates; the first-order fit would fold the filter
    # into a longer delay
    record, truth = runs[("stock", noise)]
    fit = fit_run(record, signal="rpm", second_order=True)
    so = fit.up.second_order
    assert so.tau1_s == pytest.approx(truth.tau_up_s(HOVER_N), rel=_tol(noise))
    assert so.tau2_s == pytest.approx(truth.filter_tau_s, rel=_tol(noise))
    assert abs(so.latency_s - truth.latency_s) < truth.frame_period_s
    assert fit.up.latency.value > truth.latency_s + truth.frame_period_s


def test_step1_reproduces_the_table_c1_pattern(runs):
    fits = {m: fit_run(runs[(m, "step1")][0]) for m in ("complementary", "diode", "stock")}
    comp, diode, stock = fits["complementary"], fits["diode"], fits["stock"]
    # complementary: one time constant both ways (SimonCmp 30 / 35 ms)
    assert 0.8 < comp.down.tau.value / comp.up.tau.value < 1.25
    # diode freewheeling (Simon 29 / 63 ms) and stock (50 / 78 ms): falling much slower
    for f in (diode, stock):
        assert f.down.tau.value > 1.3 * f.up.tau.value
        assert f.down.tau.value > 1.5 * comp.down.tau.value
    assert stock.up.tau.value > 1.2 * diode.up.tau.value
    # delays: 15 ms class for the SimonK firmware, longer for the stock one
    for f in (comp, diode):
        assert 0.010 < f.up.latency.value < 0.020
    assert stock.up.latency.value > diode.up.latency.value + 0.005
    # rise/fall asymmetry: complementary smallest (Table C.1 RMS 11 vs 96 and 279)
    assert comp.rise_fall_rms < stock.rise_fall_rms < diode.rise_fall_rms


def test_step2_validation_first_order_fits_complementary_best(runs):
    # Paper C section 5.1: the complementary ESC is almost exactly first order; the diode
    # scheme's falling response is not (Fig. C.17 vs C.18)
    err = {}
    for mode in ("complementary", "diode"):
        fit = fit_run(runs[(mode, "step1")][0])
        v = validate_run(runs[(mode, "step2")][0], fit)
        assert v.rising_starts.size == 2 and v.falling_starts.size == 2
        err[mode] = v.rms_first_order_pct
    assert err["complementary"] < 2.0
    assert err["diode"] > 1.5 * err["complementary"]


def test_report_command_writes_tables_and_figures(runs, tmp_path, capsys):
    s1 = runs[("complementary", "step1")][0].path
    s2 = runs[("complementary", "step2")][0].path
    out = tmp_path / "rep"
    assert main(["report", str(s1), str(s2), "--out", str(out)]) == 0
    names = {p.name for p in out.iterdir()}
    assert {"table_c1.csv", "steps.png", "validation.csv", "report.json"} <= names
    assert any(n.startswith("validation_") and n.endswith(".png") for n in names)
    table = (out / "table_c1.csv").read_text(encoding="utf-8").splitlines()
    assert table[1].startswith("complementary,") and table[2].startswith("From Parameters,")
    # "From Parameters" of the default rig's hardware: (C.3) with Table C.2 (32 ms)
    assert float(table[2].split(",")[2]) == pytest.approx(32.3, abs=0.1)
    assert TABLE_C2.kv_rpm_v == 920.0
    assert "Table C.1" in capsys.readouterr().out
    assert not any(p.name.startswith(".") for p in tmp_path.iterdir())
