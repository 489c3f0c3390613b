"""The flight report on a synthetic flight run: every part where the log has its data,
a note where it has not, and a run that is no flight refused."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import signal

from analysis.errors import LogError
from analysis.flight_report import flight_report
from analysis.run_record import RunRecord

RATE = 1000.0


def _flight(seconds: float = 25.0, rpm: bool = True) -> RunRecord:
    rng = np.random.default_rng(2)
    t = np.arange(0.0, seconds, 1.0 / RATE)
    cols: dict[str, np.ndarray] = {"t_s": t}
    wn = 2 * np.pi * 15.0
    loop = signal.TransferFunction([wn * wn], [1.0, 1.2 * wn, wn * wn])
    for axis in ("x", "y", "z"):
        u = np.zeros(t.size)
        k = int(5 * RATE)  # the first 5 s: a hover without stick input
        while k < t.size:
            n = int(rng.uniform(0.2, 0.5) * RATE)
            u[k:k + n] = np.radians(rng.uniform(-300, 300))
            k += n
        _, y, _ = signal.lsim(loop, u, t)
        cols[f"rate_sp_{axis}_rad_s"] = u
        cols[f"gyro_{axis}_rad_s"] = y + rng.normal(0, 0.01, t.size)
    thr = 0.45 + 0.05 * np.sin(0.5 * t)
    for m in range(1, 5):
        cols[f"motor{m}_norm"] = thr + rng.normal(0, 0.01, t.size)
        if rpm:
            target = 20000 * cols[f"motor{m}_norm"]
            w = signal.lfilter([1 - np.exp(-1 / RATE / 0.03)], [1, -np.exp(-1 / RATE / 0.03)],
                               target, zi=[target[0] * np.exp(-1 / RATE / 0.03)])[0]
            cols[f"motor{m}_rpm"] = w
    cols["voltage_v"] = np.full(t.size, 15.8)
    cols["current_a"] = 12.0 + 2.0 * (thr - 0.45) / 0.05
    meta = {"kind": "flight", "id": "synthetic"}
    return RunRecord(Path("synthetic"), meta, pd.DataFrame(cols))


def test_a_flight_gives_every_part():
    rep = flight_report(_flight())
    s = rep.summary()
    assert set(s["step_response"]) == {"x", "y", "z"}
    assert s["step_response"]["x"]["overshoot_pct"] == pytest.approx(
        s["step_response"]["y"]["overshoot_pct"], abs=3)  # one loop on every axis
    assert set(s["motors"]) == {"motor1", "motor2", "motor3", "motor4"}
    assert s["motors"]["motor1"]["tau_up_ms"] == pytest.approx(30.0, rel=0.15)
    hover = s["hover"]
    assert 0.40 <= hover["throttle"] <= 0.50 and hover["hover_s"] >= 2.0
    # the current follows the throttle: the hover's power is the one of its throttle
    assert hover["power_w"] == pytest.approx(15.8 * (12.0 + 40.0 * (hover["throttle"] - 0.45)),
                                             rel=0.03)
    assert s["noise_peaks"]["x"] and not s["notes"]


def test_a_flight_without_speeds_notes_it_and_a_bench_run_is_refused():
    rep = flight_report(_flight(rpm=False))
    assert rep.motors == {} and any("no motor speed" in n for n in rep.notes)
    bench = _flight()
    bench.meta["kind"] = "step1"
    with pytest.raises(LogError, match="flight-report reads flight logs"):
        flight_report(bench)
