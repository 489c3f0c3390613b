"""`fit` on the esc_test family (synthetic logs of the shipped files' structure, logfamily.py)
and on the shipped ESC32 log: duty or any named column is the command, a log without command
steps points to the static analysis, a slow channel says why it is not fitted and the speed
is fitted instead, the summary comes from the edges that were fitted, the text mode prints
n/a with the reason, and every error names the run."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from bench.cli import main

ESC32 = "esc_test/autoquad_esc32_f40_steps_5-2.csv"


def _import(src, fmt, out, capsys):
    assert main(["import", str(src), "--format", fmt, "--out", str(out)]) == 0
    capsys.readouterr()
    return out


def _fit(run, capsys, *extra):
    code = main(["fit", str(run), *extra])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def test_esc32_duty_steps_fit_from_the_fitted_edges(logfamily, tmp_path, capsys):
    run = _import(logfamily.esc32_log(tmp_path / "esc32.csv", tau_s=0.06), "esc32",
                  tmp_path / "r", capsys)
    code, out, err = _fit(run, capsys, "--json")
    assert code == 0, err
    s = json.loads(out)
    assert s["command"] == "duty_pct" and s["signal"] == "rpm" and s["gain_unit"] == "rpm/%"
    # the generator's rotor has tau 60 ms; the ESC32 rows come every 15 ms
    assert s["tau_up_ms"] == pytest.approx(60.0, abs=8.0)
    assert s["tau_down_ms"] == pytest.approx(60.0, abs=8.0)
    up = s["summary_up"]
    assert up["from"].startswith("mean of") and len(up["edges"]) == s["repeats_up"] >= 10
    fitted = [e for e in s["edges"] if e["fitted"]]
    assert {i for i, e in enumerate(s["edges"]) if e["fitted"] and e["direction"] == "up"} \
        == set(up["edges"])
    # the headline is the mean of the fitted edges, not the first level pair (0 -> 5 %)
    assert s["tau_up_ms"] == pytest.approx(
        np.mean([e["tau_ms"] for e in fitted if e["direction"] == "up"]), rel=1e-3)
    assert all(e.get("why") for e in s["edges"] if not e["fitted"])


def test_rcbenchmark_without_command_steps_points_to_static_analysis(logfamily, tmp_path,
                                                                      capsys):
    run = _import(logfamily.rcbenchmark_log(tmp_path / "Log.csv", seconds=20), "rcbenchmark",
                  tmp_path / "r", capsys)
    code, out, err = _fit(run, capsys)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and "Traceback" not in err
    assert str(run) in err and "no command column with data" in err
    assert "static analysis" in err and "rotorbench report" in err


def test_command_option_names_any_column(logfamily, tmp_path, capsys):
    run = _import(logfamily.esc32_log(tmp_path / "e.csv", seconds=30), "esc32",
                  tmp_path / "r", capsys)
    code, out, _ = _fit(run, capsys, "--command", "motor_voltage_v", "--json")
    assert code == 0 and json.loads(out)["command"] == "motor_voltage_v"
    assert json.loads(out)["gain_unit"] == "rpm/unit of motor_voltage_v"
    code, _, err = _fit(run, capsys, "--command", "nope")
    assert code == 2 and f"{run}: --command nope: no such column" in err
    code, _, err = _fit(run, capsys, "--command", "thrust_n")  # schema column, empty
    assert code == 2 and "the column is empty" in err


def test_slow_thrust_channel_says_why_and_fits_speed(logfamily, tmp_path, capsys):
    # an RCbenchmark log whose ESC signal was logged: thrust every ~150 ms, rpm every ~24 ms
    src = logfamily.rcbenchmark_log(tmp_path / "Log.csv", esc_signal=True, tau_s=0.05)
    run = _import(src, "rcbenchmark", tmp_path / "r", capsys)
    code, out, err = _fit(run, capsys, "--json")
    assert code == 0, err
    s = json.loads(out)
    assert s["signal"] == "rpm" and s["tau_up_ms"] == pytest.approx(50.0, abs=5.0)
    assert len(s["notes"]) == 2
    assert s["notes"][0].startswith("not fitted: thrust_n: sampled every 1")
    assert "samples per time constant" in s["notes"][0]
    assert s["notes"][1] == "fitted rpm instead"
    code, out, _ = _fit(run, capsys)
    assert code == 0 and "note: fitted rpm instead" in out
    # asked for explicitly, the slow channel is refused with the reason
    code, out, err = _fit(run, capsys, "--signal", "thrust")
    assert code == 2 and "thrust_n: sampled every" in err and "too slowly" in err


def _write_run(path, df, meta):
    path.mkdir()
    (path / "run.json").write_text(json.dumps(meta), encoding="utf-8")
    df.to_parquet(path / "samples.parquet")


def test_text_mode_prints_na_with_the_reason(tmp_path, capsys):
    # rising edges fit, the falling edge starts from a level that never settled: the
    # down numbers are missing and the text says n/a and why (was a TypeError)
    t = np.arange(0.0, 3.0, 0.001)
    u = np.where(t < 1.0, 1200.0, np.where(t < 2.0, 1400.0, 1600.0))
    y = np.where(t < 1.0, 2.0, np.where(t < 2.0, 3.0, 4.0))
    for t0, a, b in ((1.0, 2.0, 3.0), (2.0, 3.0, 4.0)):
        sel = t >= t0
        y[sel] = a + (b - a) * (1 - np.exp(-(t[sel] - t0) / 0.04))
    _write_run(tmp_path / "r", pd.DataFrame({"t_s": t, "throttle_us": u, "thrust_n": y}),
               {"id": "r"})
    code, out, err = _fit(tmp_path / "r", capsys)
    assert code == 0, err
    assert "down: n/a (no falling edge in the run)" in out
    assert "rise/fall rms n/a" in out
    assert "N/A" in out  # the table's empty cells


def test_no_fitted_edge_at_all_says_why_and_names_the_run(tmp_path, capsys):
    t = np.arange(0.0, 3.0, 0.001)
    u = np.where((t // 0.5) % 2 == 1, 1400.0, 1200.0)
    y = np.full(t.size, 1.0)  # the rotor never answers
    _write_run(tmp_path / "flat", pd.DataFrame({"t_s": t, "throttle_us": u, "rpm": y}), {})
    code, out, err = _fit(tmp_path / "flat", capsys)
    assert code == 2 and out == ""
    assert err.startswith(f"rotorbench: error: {tmp_path / 'flat'}: no signal can be fitted")
    assert "does not change" in err


def test_shipped_esc32_rise_times_match_an_independent_per_edge_estimate(shared_data,
                                                                          tmp_path, capsys):
    """Done-when check: rise_time_63_up/down_ms of `fit --json` within 10 / 15 ms of a
    per-edge 63 % crossing read straight from the raw file (pandas, no importer, no bins)."""
    src = shared_data / ESC32
    run = _import(src, "esc32", tmp_path / "r", capsys)
    code, out, err = _fit(run, capsys, "--json")
    assert code == 0, err
    s = json.loads(out)
    raw = pd.read_csv(src)
    stamp = pd.to_datetime(raw["Timestamp"], format="%Y-%m-%d %H:%M:%S:%f")
    t = (stamp - stamp.iloc[0]).dt.total_seconds().to_numpy()
    duty, rpm = raw["Duty"].to_numpy(float), raw["RPM"].to_numpy(float)
    t63 = {"up": [], "down": []}
    for k in np.flatnonzero(np.diff(duty)) + 1:
        te = 0.5 * (t[k - 1] + t[k])
        before = (t > te - 0.5) & (t < te)
        after = (t > te + 0.3) & (t <= te + 0.5)  # settled (the last edge has a gap)
        held_before, held_after = duty[(t > te - 1.0) & (t < te)], duty[(t > te) & (t < te + 1)]
        if held_before.size < 10 or held_after.size < 10 or np.ptp(held_before) > 0 \
                or np.ptp(held_after) > 0:
            continue  # a level not held for a second either side
        y0, y1 = rpm[before].mean(), rpm[after].mean()
        if y0 == 0.0:
            continue  # a start from standstill (ESC start-up routine) is no first-order step
        z = (rpm - y0) / (y1 - y0)
        j = k + int(np.flatnonzero(z[k:] >= 1 - np.exp(-1))[0])
        tc = t[j - 1] + (1 - np.exp(-1) - z[j - 1]) / (z[j] - z[j - 1]) * (t[j] - t[j - 1])
        t63["up" if duty[k] > duty[k - 1] else "down"].append((tc - te) * 1e3)
    assert len(t63["up"]) == 18 and len(t63["down"]) == 3
    assert s["rise_time_63_up_ms"] == pytest.approx(np.mean(t63["up"]), abs=10.0)
    assert s["rise_time_63_down_ms"] == pytest.approx(np.mean(t63["down"]), abs=15.0)
