"""Property test: random junk fed to every importer (`rotorbench import` in each format) and
to `rotorbench fit`: each either succeeds (exit 0) or exits 2 with one line naming the
problem; never a traceback (an exception escaping ``main``), a warning (errors under the
suite's filterwarnings), or a hang (hypothesis deadline)."""

from __future__ import annotations

import itertools
import json
import tempfile
from datetime import timedelta
from pathlib import Path

import numpy as np
import pandas as pd
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import analysis.importers
import analysis.step_response  # noqa: F401  (imported once here, not inside a timed example)
from bench.cli import build_parser, main

build_parser()  # imports every subcommand

_COUNTER = itertools.count()
# a hang fails the example; the bound is generous because the machine is shared and the
# first call also imports the subcommands (warmed up below)
SETTINGS = settings(max_examples=40, deadline=timedelta(seconds=20),
                    suppress_health_check=[HealthCheck.function_scoped_fixture,
                                           HealthCheck.too_slow])

RCB_HEADERS = ["Time (s)", "ESC signal (µs)", "Thrust (gf)", "Torque (N·m)", "Voltage (V)",
               "Current (A)", "Motor Electrical Speed (RPM)", "Motor Optical Speed (RPM)",
               "Thrust (kgf)", "Motor Electrical Speed (rad/s)", "App message"]
ESC32_HEADERS = ["Timestamp", "Amps", "Batt. Volts", "Motor Volts", "RPM", "Duty", "State"]
CSV_HEADERS = ["t_s", "throttle_us", "thrust_n", "rpm", "duty_pct", "time (ms)", "thrust (V)",
               "current_a", "x"]

cells = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-10**6, 10**6).map(str),
    st.sampled_from(["", "nan", "NaN", "inf", "-inf", "1e308", "-0", "abc", "1,5", '"',
                     "2019-11-05 17:14:08:947", "2019-13-45 99:99:99:999", "µ", ";"]),
    st.text(max_size=6),
)


@st.composite
def csv_like(draw, headers: list[str]) -> bytes:
    """A header drawn from the format's own column names (so parsing goes deep), then rows
    of junk cells; sometimes raw bytes instead."""
    if draw(st.integers(0, 9)) == 0:
        return draw(st.binary(max_size=300))
    cols = draw(st.lists(st.sampled_from(headers), min_size=1, max_size=6, unique=True))
    rows = draw(st.lists(st.lists(cells, min_size=len(cols), max_size=len(cols)),
                         max_size=12))
    text = "\n".join([",".join(cols), *(",".join(r) for r in rows)])
    if draw(st.booleans()):
        text = "\ufeff" + text
    return text.encode("utf-8", errors="replace")


def _one_clean_line(code: int, err: str) -> None:
    assert code in (0, 2), (code, err)
    assert "Traceback" not in err
    if code == 2:
        assert err.startswith("rotorbench: error: ") and err.count("\n") == 1, err


def _import(data: bytes, fmt: str, capsys) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "log.csv"
        src.write_bytes(data)
        out = Path(tmp) / f"run{next(_COUNTER)}"
        code = main(["import", str(src), "--format", fmt, "--out", str(out)])
        _one_clean_line(code, capsys.readouterr().err)
        if code == 2:
            assert not out.exists()  # nothing half-written
        else:
            assert main(["fit", str(out), "--json"]) in (0, 2)  # and fit never crashes
            _one_clean_line(0, capsys.readouterr().err)


@SETTINGS
@given(data=csv_like(RCB_HEADERS))
def test_rcbenchmark_import_of_junk(data, capsys):
    _import(data, "rcbenchmark", capsys)


@SETTINGS
@given(data=csv_like(ESC32_HEADERS))
def test_esc32_import_of_junk(data, capsys):
    _import(data, "esc32", capsys)


@SETTINGS
@given(data=csv_like(CSV_HEADERS))
def test_csv_import_of_junk(data, capsys):
    _import(data, "csv", capsys)


finite = st.floats(-1e4, 1e4, allow_nan=False)


@st.composite
def run_folders(draw) -> tuple[pd.DataFrame, object]:
    """Samples a run folder could hold: unsorted or repeated times, NaN, constant or stepped
    commands, missing signals; and run.json junk."""
    n = draw(st.integers(1, 400))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    dt = draw(st.sampled_from([1e-3, 0.015, 0.15, 0.0]))
    t = np.arange(n) * dt
    if draw(st.booleans()):
        t = t + rng.normal(0, 0.01, n)
    cols = {"t_s": t}
    for name in draw(st.lists(st.sampled_from(["throttle_us", "duty_pct", "thrust_setpoint_n",
                                               "thrust_n", "rpm"]), unique=True, max_size=5)):
        kind = draw(st.sampled_from(["steps", "const", "nan", "noise", "sparse"]))
        if kind == "steps":
            v = np.where((np.arange(n) // max(1, n // draw(st.integers(1, 8)))) % 2 == 1,
                         draw(finite), draw(finite))
        elif kind == "const":
            v = np.full(n, draw(finite))
        elif kind == "nan":
            v = np.full(n, np.nan)
        elif kind == "noise":
            v = rng.normal(0, 1, n)
        else:
            v = np.where(rng.random(n) < 0.15, rng.normal(5, 1, n), np.nan)
        cols[name] = v
    meta = draw(st.one_of(st.just({"id": "junk"}), st.just([]), st.just(None),
                          st.dictionaries(st.sampled_from(["id", "components", "rig", "kind"]),
                                          st.one_of(st.none(), st.integers(), st.text(max_size=4),
                                                    st.just({"esc": {"frame_rate_hz": "x"}}))
                                          )))
    return pd.DataFrame(cols), meta


@SETTINGS
@given(folder=run_folders(), text=st.booleans())
def test_fit_of_junk_run_folders(folder, text, capsys):
    df, meta = folder
    with tempfile.TemporaryDirectory() as tmp:
        run = Path(tmp) / "run"
        run.mkdir()
        (run / "run.json").write_text(json.dumps(meta), encoding="utf-8")
        df.to_parquet(run / "samples.parquet")
        code = main(["fit", str(run), *([] if text else ["--json"])])
        _one_clean_line(code, capsys.readouterr().err)
