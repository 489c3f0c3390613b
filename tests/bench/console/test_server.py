"""The console's bench side without a window: the min/max envelope, the operator's
rate-limited throttle inside the safe run loop, limits tightened mid-run, the link's
verdict on a lost window. Runs go through run_sequence on the simulated rig (fast, not
paced) and are recorded and indexed like any CLI run."""

from __future__ import annotations

import time

import numpy as np
import pandas as pd
import pytest

from analysis.run_record import read_run
from bench.console.envelope import RollingEnvelope, envelope, envelopes
from bench.console.link import BenchLink
from bench.console.manual import ConsoleRunner, Setpoint, manual_sequence
from bench.errors import RigError
from bench.plan_runner.runner import RunOptions
from bench.plan_runner.session import esc_range_of, run_sequence
from bench.plans.sequences import EscRange
from bench.rig.rig import default_rig_path, load_rig
from bench.store.run_index import RunIndex
from drivers.factory import open_rig


def test_envelope_keeps_a_one_sample_spike_that_decimation_drops():
    t = np.arange(250_000) / 25_000.0  # 10 s at 25 kHz
    y = np.sin(t)
    y[123_457] = 50.0  # one sample
    x, e = envelope(t, y, 0.0, 10.0, 500)
    assert x.size == e.size == 1000
    assert e.max() == 50.0  # the spike is in its column's max
    assert y[:: len(t) // 500].max() < 1.01  # what plain decimation would show
    col = int(t[123_457] / (10.0 / 500))
    assert e[2 * col + 1] == 50.0 and x[2 * col] == pytest.approx((col + 0.5) * 0.02)


def test_envelope_skips_nans_and_few_points_pass_through():
    t = np.arange(10.0)
    y = np.where(t == 3, np.nan, t)
    x, _e = envelope(t, y, 0.0, 10.0, 100)  # fewer points than columns: unchanged
    np.testing.assert_array_equal(x, t)
    x, ys = envelopes(np.arange(1000.0), {"a": np.r_[np.nan, np.arange(1.0, 1000.0)]},
                      0.0, 1000.0, 10)
    assert ys["a"][0] == 1.0 and ys["a"][1] == 99.0  # the NaN is skipped


def test_rolling_envelope_fed_in_pieces_equals_the_envelope_of_the_whole():
    rng = np.random.default_rng(1)
    t = np.arange(60_000) / 25_000.0
    y = rng.normal(size=t.size)
    y[41_000] = 9.0
    env = RollingEnvelope(("y",), columns=200, width_s=1.0 / 200)  # the last second
    for a in range(0, t.size, 833):  # one frame of rows at a time
        env.update(t[a:a + 833], {"y": y[a:a + 833]})
    x, lines = env.lines()
    newest = int(np.floor(t[-1] * 200))
    first = (newest - 199) / 200
    x_ref, y_ref = envelope(t, y, first, first + 1.0, 200)
    np.testing.assert_allclose(x + t[-1], x_ref, atol=1e-9)
    np.testing.assert_array_equal(lines["y"], y_ref)
    assert lines["y"].max() == 9.0


def test_setpoint_follows_the_target_at_the_rate_limit_and_stop_means_idle():
    sp = Setpoint(EscRange(1000.0, 1100.0, 2000.0), rate_us_s=400.0)
    assert sp.set_fraction(0.5) == 1550.0
    us, trace = 1000.0, []
    for _ in range(200):
        us = sp.next_us(us, 0.02)
        trace.append(us)
    assert trace[0] == 1108.0  # from idle: the range's bottom, then 8 us per 20 ms
    assert np.max(np.diff(trace)) <= 8.0 + 1e-9 and trace[-1] == 1550.0
    assert sp.set_fraction(2.0) == 2000.0 and sp.set_fraction(float("nan")) == 1000.0
    sp.end()
    assert sp.ended and sp.target_us == 1000.0


def _esc_safe(rig):
    """The last command the simulated ESC got was a disarm, and its pulse is idle."""
    return rig.esc.last_pulse_us == 1000.0 and rig.esc.model.events[-1][1] == "disarm"


def _manual_run(tmp_path, script, rate=400.0):
    """A manual session on the sim rig; ``script(t, runner, setpoint)`` runs each tick."""
    rig = load_rig(default_rig_path())
    seq, index = manual_sequence(max_s=30.0, rate_us_s=rate)
    setpoint = Setpoint(esc_range_of(rig), rate)
    made = {}

    def factory(*args, **kwargs):
        made["runner"] = ConsoleRunner(*args, setpoint=setpoint, manual_index=index, **kwargs)
        return made["runner"]

    def on_progress(t, _total, _seg):
        script(t, made["runner"], setpoint)

    opened = {}

    def opener(r, seed=None):
        opened["rig"] = open_rig(r, seed=seed)
        return opened["rig"]

    outcome = run_sequence(rig, seq, tmp_path, opener, options=RunOptions(),
                           on_progress=on_progress, runner_factory=factory)
    samples = pd.read_parquet(outcome.run_dir / "samples.parquet")
    return outcome, samples, opened["rig"], made["runner"]


def test_a_manual_session_follows_the_throttle_at_the_rate_limit_and_stops_idle(tmp_path):
    def script(t, runner, sp):
        if t >= 1.2 and sp.target_us == 1000.0 and not sp.ended:
            sp.set_fraction(0.3)
        if t >= 4.0:
            sp.end()

    outcome, s, rig, _runner = _manual_run(tmp_path, script)
    assert outcome.result.status == "success"
    cmd = s["throttle_us"].to_numpy()
    t = s["t_s"].to_numpy()
    assert cmd.max() == 1300.0 and cmd[-1] == 1000.0
    rising = (t > 1.2) & (t < 2.5)
    steps = np.diff(cmd[rising])
    assert steps.max() <= 400.0 * 0.02 + 1e-9  # never more than the rate limit per tick
    assert t[np.argmax(cmd >= 1300.0)] > 1.2 + 0.7  # 300 us at 400 us/s: >= 0.75 s
    assert t[-1] >= 4.0 + 0.45  # the spin-down after the stop is recorded, at idle
    assert (cmd[t > 4.05] == 1000.0).all()
    assert _esc_safe(rig)
    events = read_run(outcome.run_dir).events
    assert "stop: idle + disarm" in set(events["label"])
    rows = RunIndex(tmp_path).list()
    assert [r.sequence for r in rows] == ["manual"] and rows[0].status == "success"


def test_limits_tighten_mid_run_and_trip_but_never_loosen(tmp_path):
    def script(t, runner, sp):
        if t >= 1.2 and sp.target_us == 1000.0:
            sp.set_fraction(0.3)
            with pytest.raises(RigError, match="loosen"):
                runner.tighten({"thrust_n": 9.0})
            runner.tighten({"thrust_n": 0.3})

    outcome, _s, rig, runner = _manual_run(tmp_path, script)
    res = outcome.result
    assert res.status == "abort" and res.trip is not None
    assert res.trip.limit == "thrust_n" and res.trip.limit_value == 0.3
    assert res.trip.sample["thrust_n"] > 0.3  # the tripping sample, recorded
    assert runner.limits["thrust_n"] == 0.3 and runner.limits["current_a"] == 25.0
    assert _esc_safe(rig)


def test_the_link_says_why_the_window_is_lost():
    link = BenchLink(capacity=100, heartbeat_bound_s=0.2)
    assert link.lost() is None  # no beat yet: still starting
    gui = link.gui_link()
    gui.beat()
    assert link.lost() is None
    time.sleep(0.25)
    assert "frozen" in link.lost() and link.lost(frozen=False) is None
    link.send("state", {"x": 1})  # not sent to a window that does not beat
    assert not gui.conn.poll()
    gui.beat()
    link.send("state", {"x": 1})
    assert gui.receive() == [("state", {"x": 1})]
    link.closed_by_operator = True
    assert link.lost() == "console window closed"


def test_console_refuses_a_bad_rig_file_or_limit_in_one_line(tmp_path, capsys):
    from bench.cli import main

    bad = tmp_path / "bad.toml"
    bad.write_text("[rig]\nname = 3\n")
    assert main(["console", "--rig", str(bad), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("rotorbench: error:") and str(bad) in err and "\n" not in err
    assert main(["console", "--limit", "thrust_n=99", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "only tighten" in err and "\n" not in err
