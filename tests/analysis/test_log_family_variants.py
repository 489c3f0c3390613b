"""Other members of the log families, not only the shipped files: the same RCbenchmark /
Flight Stand and ESC32 logs written by other versions or re-saved by other tools (header
spellings seen in public scripts that read them: 'Torque (N-m)', 'Motor Current (A)',
'Motor Speed (RPM)', 'ESC signal (us)', thrust in kgf or N; spaces after commas, CRLF,
columns reordered or added, a subset of ESC32 telemetry columns, '.mmm' stamps), a load
cell mounted the other way, and an ESC32 step log whose first edge starts the rotor from
rest. Each variant must give the numbers of the plain log (logfamily.py)."""

from __future__ import annotations

import io
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis.errors import LogError
from analysis.importers import import_esc32, import_rcbenchmark
from analysis.static_curves import fit_static
from analysis.step_response import START_WHY
from bench.cli import main


def _rewrite(src: Path, dst: Path, edit) -> Path:
    dst.write_text(edit(src.read_text(encoding="utf-8")), encoding="utf-8", newline="")
    return dst


def _scale_column(text: str, header: str, new_header: str, factor: float) -> str:
    df = pd.read_csv(io.StringIO(text.lstrip("\ufeff")), dtype=str, keep_default_na=False)
    cells = pd.to_numeric(df[header].where(df[header] != ""), errors="coerce") * factor
    df[header] = [repr(float(v)) if np.isfinite(v) else "" for v in cells]
    return df.rename(columns={header: new_header}).to_csv(index=False)


RCB_VARIANTS = {
    "torque N-m": lambda s: s.replace("Torque (N·m)", "Torque (N-m)"),
    "torque N⋅m": lambda s: s.replace("Torque (N·m)", "Torque (N⋅m)"),
    "torque N.m": lambda s: s.replace("Torque (N·m)", "Torque (N.m)"),
    "ESC signal (us)": lambda s: s.replace("ESC signal (µs)", "ESC signal (us)"),
    "ESC (µs)": lambda s: s.replace("ESC signal (µs)", "ESC (µs)"),
    "Motor Current": lambda s: s.replace("Current (A)", "Motor Current (A)"),
    "Motor Speed": lambda s: s.replace("Motor Electrical Speed (RPM)", "Motor Speed (RPM)"),
    "RPM only": lambda s: s.replace("Motor Electrical Speed (RPM)", "RPM"),
    "no BOM, CRLF": lambda s: s.lstrip("\ufeff").replace("\n", "\r\n"),
    "space after comma": lambda s: s.replace(",", ", "),
    "extra columns": lambda s: "\n".join(
        line + ("90% settling time (s),Max acceleration (RPM/s)," if i == 0 else ",,")
        for i, line in enumerate(s.rstrip("\n").split("\n"))) + "\n",
    "reordered": lambda s: pd.read_csv(io.StringIO(s.lstrip("\ufeff")), dtype=str,
                                       keep_default_na=False).iloc[:, ::-1].to_csv(index=False),
    "thrust kgf": lambda s: _scale_column(s, "Thrust (gf)", "Thrust (kgf)", 1e-3),
    "thrust N": lambda s: _scale_column(s, "Thrust (gf)", "Thrust (N)", 9.80665e-3),
}


@pytest.fixture(scope="module")
def rcb_base(logfamily, tmp_path_factory):
    src = logfamily.rcbenchmark_log(tmp_path_factory.mktemp("rcb") / "Log.csv", seconds=40,
                                    esc_signal=True, steps_back=2, seed=5)
    df, meta = import_rcbenchmark(src)
    return src, df, meta


@pytest.mark.parametrize("name", RCB_VARIANTS)
def test_rcbenchmark_header_variants_import_like_the_plain_log(rcb_base, tmp_path, name):
    src, base, base_meta = rcb_base
    df, meta = import_rcbenchmark(_rewrite(src, tmp_path / "Log.csv", RCB_VARIANTS[name]))
    assert sorted(df.columns) == sorted(base.columns)
    for col in base.columns:
        np.testing.assert_allclose(df[col].to_numpy(), base[col].to_numpy(), rtol=1e-9,
                                   atol=1e-12, err_msg=f"{name}: {col}")
    assert meta["time_order"]["reordered_rows"] == base_meta["time_order"]["reordered_rows"]


def test_a_torque_unit_that_is_no_torque_is_still_refused(rcb_base, tmp_path):
    src, _, _ = rcb_base
    bad = _rewrite(src, tmp_path / "Log.csv", lambda s: s.replace("Torque (N·m)", "Torque (N-s)"))
    with pytest.raises(LogError, match=r"column 'Torque \(N-s\)': unit 'N-s' is not a torque"):
        import_rcbenchmark(bad)


ESC32_VARIANTS = {
    "BOM, CRLF": lambda s: "\ufeff" + s.replace("\n", "\r\n"),
    "space after comma": lambda s: s.replace(",", ", "),
    # every line ends with a comma, the last one with its line break as the logger writes it
    # (a last line without one is a cut write: dropped and said, tests/test_cli_careless_files)
    "trailing comma": lambda s: "".join(line + ",\n" for line in s.rstrip("\n").split("\n")),
    "dot milliseconds": lambda s: re.sub(r"(\d\d:\d\d:\d\d):(\d{3})", r"\1.\2", s),
    "reordered": lambda s: pd.read_csv(io.StringIO(s), dtype=str).iloc[:, ::-1]
    .to_csv(index=False),
    "subset": lambda s: pd.read_csv(io.StringIO(s), dtype=str)[
        ["Timestamp", "Duty", "RPM", "Amps"]].to_csv(index=False),
}


@pytest.fixture(scope="module")
def esc32_base(logfamily, tmp_path_factory):
    src = logfamily.esc32_log(tmp_path_factory.mktemp("esc32") / "esc32.csv", seconds=40)
    return src, import_esc32(src)[0]


@pytest.mark.parametrize("name", ESC32_VARIANTS)
def test_esc32_variants_import_like_the_plain_log(esc32_base, tmp_path, name):
    src, base = esc32_base
    df, meta = import_esc32(_rewrite(src, tmp_path / "esc32.csv", ESC32_VARIANTS[name]))
    for col in df.columns:
        np.testing.assert_allclose(df[col].to_numpy(), base[col].to_numpy(), rtol=1e-12,
                                   err_msg=f"{name}: {col}")
    assert {"t_s", "rpm", "duty_pct"} <= set(df.columns)
    if name == "subset":
        assert set(df.columns) == {"t_s", "duty_pct", "rpm", "current_a"}
        assert set(meta["columns"]) == set(df.columns)


def test_esc32_without_any_telemetry_column_says_which_it_knows(tmp_path):
    p = tmp_path / "e.csv"
    p.write_text("Timestamp,Foo\n2019-11-05 17:14:08:947,1\n", encoding="utf-8")
    with pytest.raises(LogError, match=r"e\.csv: none of the ESC32 telemetry columns "
                                       r"\['Amps', .*'Duty'\] \(columns: Timestamp, Foo\)"):
        import_esc32(p)


def test_reversed_load_cell_gives_the_same_curves_with_a_note(logfamily, rcb_base, tmp_path,
                                                              capsys):
    src, _, _ = rcb_base
    neg = _rewrite(src, tmp_path / "Log.csv",
                   lambda s: _scale_column(s, "Thrust (gf)", "Thrust (gf)", -1.0))
    runs = {}
    for name, path in (("plain", src), ("reversed", neg)):
        runs[name] = tmp_path / name
        assert main(["import", str(path), "--format", "rcbenchmark", "--out",
                     str(runs[name])]) == 0
    capsys.readouterr()
    out = {}
    for name, run in runs.items():
        for target in ("gazebo", "ardupilot", "px4"):
            assert main(["export", target, str(run), "--json"]) == 0
            out[name, target] = json.loads(capsys.readouterr().out)
    assert out["reversed", "gazebo"]["motorConstant"] == out["plain", "gazebo"]["motorConstant"]
    assert out["plain", "gazebo"]["motorConstant"] == pytest.approx(logfamily.K_F, rel=0.03)
    assert out["reversed", "ardupilot"]["MOT_THST_EXPO"] == \
        out["plain", "ardupilot"]["MOT_THST_EXPO"]
    assert out["reversed", "px4"]["THR_MDL_FAC"] == out["plain", "px4"]["THR_MDL_FAC"]
    for target in ("gazebo", "ardupilot", "px4"):
        assert any("sign is flipped" in n for n in out["reversed", target]["notes"])
        assert not any("sign is flipped" in n for n in out["plain", target]["notes"])


def test_thrust_that_rises_with_speed_is_never_flipped():
    rpm = np.linspace(0.0, 12000.0, 400)
    w = rpm * np.pi / 30
    thrust = 1e-6 * w**2 - 0.3  # a large negative tare offset: still lift rising with speed
    curves = fit_static(rpm, thrust)
    assert curves.notes == () and curves.k_f > 0


def test_a_start_from_standstill_is_listed_not_fitted(logfamily, tmp_path, capsys):
    # the ESC's start-up holds the rotor for 250 ms: fitted, that edge alone would read as
    # a 250 ms latency and raise the mean rise time by ~20 ms over 13 edges
    src = logfamily.esc32_log(tmp_path / "esc32.csv", seconds=75, tau_s=0.04, startup_s=0.25)
    run = tmp_path / "r"
    assert main(["import", str(src), "--format", "esc32", "--out", str(run)]) == 0
    capsys.readouterr()
    assert main(["fit", str(run), "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    first = s["edges"][0]
    assert (first["u_before"], first["u_after"]) == (0.0, 5.0)
    assert not first["used"] and first["why"] == START_WHY
    assert 0 not in s["summary_up"]["edges"] and len(s["summary_up"]["edges"]) == 13
    # the running steps of the generator: no latency, tau 40 ms -> t63 = tau (+ one row)
    assert s["rise_time_63_up_ms"] == pytest.approx(40.0, abs=10.0)
    assert s["latency_up_ms"] < 10.0
    assert main(["fit", str(run)]) == 0
    assert "1 not: start from standstill" in capsys.readouterr().out


def test_output_into_a_closed_pipe_is_no_traceback():
    """`rotorbench ... | head -1`: the reader closes the pipe early (a dry run of 3000
    repeats prints far more than a pipe buffer); no BrokenPipeError traceback."""
    cmd = [sys.executable, "-c", "import sys; from bench.cli import main; "
           "sys.exit(main(sys.argv[1:]))", "step", "--dry-run", "--repeats", "3000"]
    with subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                          cwd=Path(__file__).resolve().parents[2]) as proc:
        assert proc.stdout is not None and proc.stderr is not None
        first = proc.stdout.readline()
        proc.stdout.close()  # what `head -1` does after its line
        err = proc.stderr.read().decode()
        code = proc.wait(timeout=60)
    assert code == 141
    assert first.startswith(b"rig sim")
    assert "Traceback" not in err and "BrokenPipeError" not in err


@pytest.mark.parametrize(("family", "name"), [*(("rcbenchmark", n) for n in RCB_VARIANTS),
                                              *(("esc32", n) for n in ESC32_VARIANTS)])
def test_import_detects_the_format_of_every_variant(logfamily, rcb_base, esc32_base, tmp_path,
                                                    capsys, family, name):
    """`rotorbench import FILE --out DIR`, no --format: the header names the family."""
    src = rcb_base[0] if family == "rcbenchmark" else esc32_base[0]
    edit = (RCB_VARIANTS if family == "rcbenchmark" else ESC32_VARIANTS)[name]
    log = _rewrite(src, tmp_path / "log.csv", edit)
    assert main(["import", str(log), "--out", str(tmp_path / "auto")]) == 0
    assert f"({family}, detected from the header)" in capsys.readouterr().out
    assert main(["import", str(log), "--format", family, "--out", str(tmp_path / "forced")]) == 0
    assert f"({family}, --format)" in capsys.readouterr().out
    auto, forced = (pd.read_parquet(tmp_path / d / "samples.parquet") for d in ("auto", "forced"))
    pd.testing.assert_frame_equal(auto, forced)
