"""Step-response identification on synthetic responses with known parameters."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from analysis.errors import LogError
from analysis.run_record import read_run
from analysis.step_response import (
    Estimate,
    detect_edges,
    first_order_step,
    fit_step_response,
    pooled_std,
    second_order_step,
)

FS = 25_000.0


def synth(levels, hold_s, lat, tau_up, tau_dn, noise=0.0, gain=1.0, seed=0, ramp_s=0.0,
          model="first", tau2=0.0):
    """Command steps between ``levels`` (held ``hold_s``), response = delayed first-order
    lag from each settled level (up and down time constants differ); ``lat`` one latency
    or one per edge."""
    n_seg = len(levels)
    t = np.arange(int(n_seg * hold_s * FS)) / FS
    u = np.repeat(levels, int(hold_s * FS)).astype(float)
    y = np.full(t.size, gain * levels[0], float)
    for k in range(1, n_seg):
        t0 = k * hold_s
        sel = t >= t0
        a, b = gain * levels[k - 1], gain * levels[k]
        tau = tau_up if b > a else tau_dn
        lag = float(lat[k - 1]) if np.ndim(lat) else lat
        if model == "first":
            shape = first_order_step(t[sel] - t0, lag, tau)
        else:
            shape = second_order_step(t[sel] - t0, lag, tau, tau2)
        y[sel] = a + (b - a) * shape
    if ramp_s:  # a slow ramp in front, as a sweep or a soft start has
        pre_t = np.arange(int(ramp_s * FS)) / FS
        pre_u = np.linspace(0.0, levels[0], pre_t.size)
        t = np.concatenate((pre_t, t + ramp_s))
        u = np.concatenate((np.round(pre_u, 0), u))  # ramp moves in small increments
        y = np.concatenate((gain * pre_u, y))
    rng = np.random.default_rng(seed)
    return t, u, y + noise * rng.standard_normal(t.size)


def test_first_order_recovered_exactly_without_noise():
    t, u, y = synth([1.7, 3.2] * 4 + [1.7], 0.5, 0.015, 0.030, 0.065)
    res = fit_step_response(t, y, u)
    assert res.up.latency.value == pytest.approx(0.015, abs=2e-4)
    assert res.up.tau.value == pytest.approx(0.030, rel=2e-3)
    assert res.down.tau.value == pytest.approx(0.065, rel=2e-3)
    assert res.up.gain.value == pytest.approx(1.0, rel=1e-3)
    assert res.up.tau.n == 4 and res.down.tau.n == 4
    # the 63 % rise time read from the data is delay + tau for a first-order lag
    assert res.up.t63.value == pytest.approx(0.045, abs=3e-4)
    assert res.down.t63.value == pytest.approx(0.080, abs=3e-4)


def test_repeats_whose_latencies_scatter_are_averaged_aligned():
    """A firmware ESC's outputs wait on its own tasks: each edge's latency differs (here
    5-46 ms, as a Betaflight SITL's down edges had), its lag does not. Averaged at the
    command edge the mean's lag widens to about sqrt(tau^2 + sigma^2) (37 ms read for
    30 ms); aligned at each edge's own latency the fit gives the lag, and the latency is
    the edges' mean."""
    lats = [0.012, 0.046, 0.009, 0.016, 0.007, 0.016, 0.019, 0.016, 0.010, 0.005]
    t, u, y = synth([1.5, 1.75] * 5 + [1.5], 0.5, lats, 0.030, 0.030, noise=0.002, seed=1)
    res = fit_step_response(t, y, u)
    for d, edge_lats in ((res.up, lats[0::2]), (res.down, lats[1::2])):
        assert d.aligned and "aligned at their own latencies" in d.describe()
        assert d.tau.value == pytest.approx(0.030, rel=0.01), d.describe()
        assert d.latency.value == pytest.approx(np.mean(edge_lats), abs=5e-4)
    # without a scatter beyond the noise nothing is moved
    t, u, y = synth([1.5, 1.75] * 5 + [1.5], 0.5, 0.015, 0.030, 0.030, noise=0.002, seed=1)
    res = fit_step_response(t, y, u)
    assert not res.up.aligned and not res.down.aligned


def test_a_damaged_repeat_is_left_out_not_averaged():
    """One of three down edges bunched by a stall (latency 0, tau 6 ms, as a wire rig's
    host-stamped load-cell lines once were) is listed with why; the fit is the others'."""
    levels = [1.5, 1.75] * 3 + [1.5]
    t, u, y = synth(levels, 0.5, 0.016, 0.030, 0.030, noise=0.002, seed=2)
    t0 = 4 * 0.5  # the second down edge
    sel = (t >= t0) & (t < t0 + 0.5)
    y[sel] = 1.75 - 0.25 * first_order_step(t[sel] - t0, 0.0, 0.006)
    res = fit_step_response(t, y, u)
    assert res.down.tau.value == pytest.approx(0.030, rel=0.02)
    assert res.down.latency.value == pytest.approx(0.016, abs=5e-4)
    left_out = {i: e["why"] for i, e in enumerate(res.summary()["edges"]) if not e["used"]}
    assert list(left_out) == [3] and "no repeat of its group's response" in left_out[3]
    assert res.up.tau.n == 3 and res.down.tau.n == 2
    # without the damage every edge is averaged
    t, u, y = synth(levels, 0.5, 0.016, 0.030, 0.030, noise=0.002, seed=2)
    assert all(e["used"] for e in fit_step_response(t, y, u).summary()["edges"])


def test_noise_spread_gives_the_uncertainty():
    t, u, y = synth([1.7, 3.2] * 8 + [1.7], 0.5, 0.015, 0.030, 0.050, noise=0.05, seed=3)
    res = fit_step_response(t, y, u)
    up = res.up
    assert up.tau.value == pytest.approx(0.030, rel=0.03)
    assert 0 < up.tau.std < 0.005
    assert up.tau.stderr == pytest.approx(up.tau.std / math.sqrt(8))
    # the mean-of-repeats fit is within a few standard errors of the truth
    assert abs(up.tau.value - 0.030) < 5 * up.tau.stderr + 3e-4


def test_the_latency_spread_pools_the_edges_of_both_directions():
    # rising latencies about 10 ms, falling about 30 ms: the pooled spread is that of one
    # edge about its own direction's mean, not the 10 ms between the directions
    up, down = np.array([0.009, 0.010, 0.011, 0.010]), np.array([0.028, 0.032])
    got = pooled_std([Estimate.of(up.mean(), up), Estimate.of(down.mean(), down)])
    dev = np.concatenate((up - up.mean(), down - down.mean()))
    assert got == pytest.approx(math.sqrt(np.sum(dev**2) / (up.size + down.size - 2)))
    one = Estimate.of(0.02, np.array([0.02]))  # a single edge has no spread: left out
    assert pooled_std([one, Estimate.of(up.mean(), up)]) == pytest.approx(np.std(up, ddof=1))
    assert math.isnan(pooled_std([one]))
    t, u, y = synth([1.7, 3.2] * 8 + [1.7], 0.5, 0.015, 0.030, 0.050, noise=0.05, seed=3)
    res = fit_step_response(t, y, u)
    want = pooled_std([res.up.latency, res.down.latency])
    assert 0 < want < 0.005
    assert res.summary()["latency_std_ms"] == pytest.approx(want * 1e3, abs=1e-4)


def test_symmetric_response_has_zero_rise_fall_rms_and_asymmetric_does_not():
    t, u, y = synth([1.0, 2.0] * 3 + [1.0], 0.5, 0.01, 0.03, 0.03)
    assert fit_step_response(t, y, u).rise_fall_rms < 1e-3
    t, u, y = synth([1.0, 2.0] * 3 + [1.0], 0.5, 0.01, 0.03, 0.08)
    assert fit_step_response(t, y, u).rise_fall_rms > 0.05


def test_gain_is_per_setpoint_unit():
    t, u, y = synth([1.0, 2.0] * 2 + [1.0], 0.5, 0.01, 0.03, 0.03, gain=0.9)
    sp = u * 1.0
    res = fit_step_response(t, y, u * 100 + 1000, setpoint=sp)
    assert res.up.gain.value == pytest.approx(0.9, rel=1e-3)


def test_ramps_are_not_edges_and_short_holds_are_not_fitted():
    t, u, _y = synth([300, 600, 300, 600, 300], 0.5, 0.01, 0.03, 0.03, ramp_s=1.0)
    edges = detect_edges(t, u)
    assert [e.direction for e in edges] == ["up", "down", "up", "down"]
    assert all(e.hold_after_s == pytest.approx(0.5, abs=1e-3) for e in edges[:-1])
    # Step 2-like excursions of 0.05 s are listed but not used
    t2, u2, y2 = synth([1.0, 2.0, 1.5, 2.0], 0.05, 0.01, 0.03, 0.03)
    with pytest.raises(LogError, match="none held"):
        fit_step_response(t2, y2, u2)


def test_event_times_set_the_edge_time():
    t, u, _y = synth([1.0, 2.0, 1.0], 0.5, 0.01, 0.03, 0.03)
    k = int(0.5 * FS)
    exact = 0.5 * (t[k - 1] + t[k]) + 1e-5
    edges = detect_edges(t, u, event_t=np.array([0.0, exact, 99.0]))
    assert edges[0].t_s == exact


def test_second_order_option_separates_two_poles():
    t, u, y = synth([1.0, 2.0] * 3 + [1.0], 0.6, 0.012, 0.030, 0.030, model="second",
                    tau2=0.018)
    res = fit_step_response(t, y, u, second_order=True)
    so = res.up.second_order
    assert so.tau1_s == pytest.approx(0.030, rel=0.01)
    assert so.tau2_s == pytest.approx(0.018, rel=0.02)
    assert so.latency_s == pytest.approx(0.012, abs=3e-4)
    assert so.rms < res.up.mean.rms / 5  # the first-order fit cannot follow it


def test_no_edges_is_a_log_error():
    t = np.arange(1000) / 1000.0
    with pytest.raises(LogError, match="no step edges"):
        fit_step_response(t, np.sin(t), np.full(t.size, 1500.0))


def _write_run(path, df, meta):
    path.mkdir()
    (path / "run.json").write_text(json.dumps(meta), encoding="utf-8")
    df.to_parquet(path / "samples.parquet")


def test_run_folder_reader_and_errors(tmp_path):
    t, u, y = synth([1.0, 2.0, 1.0], 0.5, 0.01, 0.03, 0.03)
    df = pd.DataFrame({"t_s": t, "throttle_us": u, "thrust_n": y})
    _write_run(tmp_path / "ok", df, {"id": "ok", "components": {"esc_mode": "diode"}})
    rec = read_run(tmp_path / "ok")
    assert rec.id == "ok" and rec.components["esc_mode"] == "diode"
    assert len(rec.samples) == t.size and rec.events.empty

    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "run.json").write_text("{not json", encoding="utf-8")
    with pytest.raises(LogError, match=r"run\.json: line 1"):
        read_run(bad)
    nosamples = tmp_path / "nos"
    nosamples.mkdir()
    (nosamples / "run.json").write_text("{}", encoding="utf-8")
    with pytest.raises(LogError, match=r"samples\.parquet: missing"):
        read_run(nosamples)
    not_t = tmp_path / "nott"
    _write_run(not_t, df.rename(columns={"t_s": "time"}), {})
    with pytest.raises(LogError, match="no 't_s' column"):
        read_run(not_t)
    assert LogError.exit_code == 2


def test_paper_e_tables_and_csv(tmp_path):
    from analysis.report import table_e11, table_e12, table_e13, table_e14, write_csv

    # Table E.11/E.12/E.13 arithmetic on the thesis' Test Case I, 4 actuators:
    # T_a 172, T_d 200 -> mean 186; simulated 144 -> dT -42; model 161 -> dT 25
    e11 = table_e11([("I-4", 0.172, 0.200)])
    assert e11.rows[0] == ("I-4", pytest.approx(172.0), pytest.approx(200.0))
    assert table_e12([("I-4", 0.144, 0.172, 0.200)]).rows[0][2] == pytest.approx(-42.0)
    assert table_e13([("I-4", 0.172, 0.200, 0.161)]).rows[0][1:] == (
        pytest.approx(186.0), pytest.approx(161.0), pytest.approx(25.0))
    e14 = table_e14([("I-4", 66.6, 62.5)])
    write_csv(e14, tmp_path / "e14.csv")
    assert (tmp_path / "e14.csv").read_text(encoding="utf-8").splitlines() == [
        "design,T_e [min],T_o [min]", "I-4,66.6,62.5"]
    assert "Table E.14" in str(e14.to_rich().title)


def test_a_setpoint_column_that_never_moves_falls_back_to_the_command(tmp_path) -> None:
    """A log whose thrust_setpoint_n is all zero (a stand that logs the column but not the
    setpoint) divided by a zero step; the gain is per command unit instead."""
    import json

    import pandas as pd

    from analysis.run_record import read_run
    from analysis.step_response import fit_run

    t = np.arange(0, 8, 1e-3)
    u = np.where((t // 1) % 2 == 1, 1500.0, 1200.0)
    lvl = np.where(u > 1300, 5.0, 2.0)
    y = lvl.copy()
    for k in range(1, t.size):  # first-order lag, tau 50 ms
        y[k] = y[k - 1] + (lvl[k - 1] - y[k - 1]) * (1e-3 / 0.05)
    run = tmp_path / "run"
    run.mkdir()
    pd.DataFrame({"t_s": t, "throttle_us": u, "thrust_setpoint_n": 0.0,
                  "thrust_n": y}).to_parquet(run / "samples.parquet")
    (run / "run.json").write_text(json.dumps({"id": "zero-setpoint"}))
    fit = fit_run(read_run(run))
    assert fit.up is not None and abs(fit.up.tau.value - 0.05) < 0.01
