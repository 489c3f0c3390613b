"""``rotorbench calibrate-sensors`` on the simulated stand, whose load cell hides a
sensitivity error, a bow, hysteresis and creep drawn from the rig file's seed: the
calibration finds them, checked against the simulated cell's own model."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from analysis.run_record import read_run
from bench.cli import main
from bench.rig.rig import default_rig_path
from drivers.sim.cell_errors import CellErrors
from drivers.sim.sensor_params import SensorParams

SIM = default_rig_path()


def _rig(tmp_path: Path, seed: int, calibration: str = "latitude_deg = 52.27\n") -> Path:
    text = SIM.read_text().replace('file = "sim.thrust_map.csv"',
                                   f'file = "{SIM.parent / "sim.thrust_map.csv"}"')
    path = tmp_path / f"cell-{seed}.toml"
    path.write_text(text + f"\n[sim.sensors]\nload_cell_error_seed = {seed}\n"
                    + f"\n[calibration]\n{calibration}")
    return path


def _truth_gain(errors: CellErrors, record: dict, r: float | None = None
                ) -> tuple[float, float]:
    """The gain and hysteresis the hidden cell (range ``r``) really has over the series'
    loads: the least-squares line through its noise-free output at each step, and its
    largest up/down difference (fraction of the calibration's full-scale output)."""
    r = r or SensorParams().load_cell_range_n
    pts = record["result"]["points"]
    f = np.array([p["force"] for p in pts])
    branch = [1 if p["direction"] == "up" else -1 for p in pts]
    y = np.array([r * errors.steady(fi / r, b) for fi, b in zip(f, branch, strict=True)])
    slope = np.polyfit(f, y, 1)[0]
    both = {p["force"] for p in pts if p["direction"] == "down"}  # the top has no down
    hyst = max(abs(errors.steady(fi / r, -1) - errors.steady(fi / r, 1)) for fi in both) * r
    return 1.0 / slope, hyst / (slope * f.max())


@pytest.mark.parametrize("seed", [3, 11, 29])
def test_the_calibration_finds_the_hidden_errors_within_its_uncertainty(tmp_path, capsys, seed):
    rig = _rig(tmp_path, seed, "latitude_deg = 52.27\nhysteresis_max_pct = 5\n")
    code = main(["calibrate-sensors", "--rig", str(rig), "--yes", "--json", "--hold-s", "2",
                 "--out", str(tmp_path / "runs")])
    out = capsys.readouterr().out
    assert code == 0, out
    record = json.loads(out[out.index("{"):])
    errors = CellErrors.drawn(seed)
    gain, hyst = _truth_gain(errors, record)
    fit = record["result"]
    big_u = 2 * fit["u_scale"]
    assert abs(fit["scale"] - gain) <= big_u, (fit["scale"], gain, big_u)
    assert abs(fit["scale"] - 1.0) > 0.005  # the cell is off its datasheet: not a no-op
    chars = fit["characteristics_fraction_of_full_scale"]
    assert chars["hysteresis"] == pytest.approx(hyst, rel=0.1, abs=2e-5)
    assert record["gravity"]["source"].startswith("WELMEC")
    assert record["acceptance"]["passed"]
    # recorded as a run of its own, every hold's readings kept
    run = read_run(Path(tmp_path / "runs" / record["id"]))
    assert run.meta["kind"] == "calibration" and run.meta["calibration"] == record
    assert set(run.samples["step"].unique()) == set(range(1, 10))
    assert (run.path / "calibration.png").stat().st_size > 10_000
    from bench.store.run_index import RunIndex

    rows = RunIndex(tmp_path / "runs").list()
    assert [(r.sequence, r.status) for r in rows] == [("calibrate-sensors", "success")]


def test_the_torque_cell_is_calibrated_with_weights_on_its_arm(tmp_path, capsys):
    rig = _rig(tmp_path, 11, "latitude_deg = 52.27\nhysteresis_max_pct = 5\n")
    rig.write_text(rig.read_text().replace(
        "load_cell_error_seed = 11", "load_cell_error_seed = 11\ntorque_cell_range_nm = 0.5\n"
        "torque_cell_error_seed = 5"))
    code = main(["calibrate-sensors", "--rig", str(rig), "--yes", "--json", "--cell", "torque",
                 "--arm-m", "0.1", "--arm-u-m", "0.0002", "--masses-g", "0,50,100,200,300",
                 "--hold-s", "1", "--out", str(tmp_path / "runs")])
    out = capsys.readouterr().out
    assert code == 0, out
    record = json.loads(out[out.index("{"):])
    assert record["applies"]["channel"] == "torque_nm" and record["arm_m"] == 0.1
    gain, _hyst = _truth_gain(CellErrors.drawn(5), record, r=0.5)
    fit = record["result"]
    assert abs(fit["scale"] - gain) <= 2 * fit["u_scale"], (fit["scale"], gain)
    arm = next(t for t in fit["scale_budget"]["budget"] if t["name"].startswith("reference"))
    assert arm["u"] == pytest.approx(0.002, rel=0.01)  # 0.2 mm on 100 mm dominates g
    assert max(p["force"] for p in fit["points"]) == pytest.approx(0.3 * 9.8125 * 0.1,
                                                                     rel=1e-3)


def test_a_cell_outside_its_acceptance_limits_is_recorded_and_exits_1(tmp_path, capsys):
    rig = _rig(tmp_path, 11, "hysteresis_max_pct = 0.01\n")
    code = main(["calibrate-sensors", "--rig", str(rig), "--yes", "--hold-s", "1",
                 "--masses-g", "0,200,1000", "--out", str(tmp_path / "runs")])
    out = capsys.readouterr().out
    assert code == 1
    assert "NOT accepted: hysteresis" in out and "> limit 0.01 %" in out
    (run_dir,) = (tmp_path / "runs").glob("*calibration-thrust")
    meta = json.loads((run_dir / "run.json").read_text())
    assert meta["status"] == "success" and "outside its acceptance limits" in meta["reason"]
    assert meta["calibration"]["acceptance"]["passed"] is False


@pytest.mark.parametrize(("args", "message"), [
    (["--masses-g", "0,100,abc"], "--masses-g: 'abc' is not a mass in grams"),
    (["--masses-g", "0,200,100"], "masses: expected 0 and at least two more, ascending"),
    (["--masses-g=0,-100,100"], "masses: -100 g is negative"),
    (["--masses-g", "0,100"], "masses: expected 0 and at least two more, ascending"),
    (["--cell", "torque", "--arm-m", "0"], "give its length (--arm-m, 0 < m < 5)"),
    (["--weight-class", "Z9"], "weight class 'Z9'"),
    (["--cell", "torque"], "give its length (--arm-m"),
    (["--cell", "torque", "--arm-m", "0.1"], "no sensor reporting torque_nm"),
    (["--hold-s", "0"], "hold: expected 0 < seconds <= 600"),
])
def test_bad_plans_are_one_line_and_exit_2(tmp_path, capsys, args, message):
    code = main(["calibrate-sensors", "--yes", "--out", str(tmp_path / "runs"), *args])
    err = capsys.readouterr().err
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1, err


def test_without_an_operator_or_a_fixture_it_stops_in_one_line(tmp_path, capsys, monkeypatch):
    import io

    monkeypatch.setattr("sys.stdin", io.StringIO(""))  # nobody at the prompt
    code = main(["calibrate-sensors", "--out", str(tmp_path / "runs")])
    err = capsys.readouterr().err
    assert code == 2 and "no operator at the prompt" in err
    (run_dir,) = (tmp_path / "runs").glob("*calibration-thrust")  # kept, as failed
    assert json.loads((run_dir / "run.json").read_text())["status"] == "fail"
    plan = tmp_path / "plan.toml"
    plan.write_text("[calibration]\nmasses_g = [0, 100, 200]\nspeed = 3\n")
    assert main(["calibrate-sensors", "--yes", "--plan", str(plan)]) == 2
    assert "[calibration] speed: unknown key" in capsys.readouterr().err


def test_runs_apply_the_newest_calibration_and_refuse_a_failed_one(tmp_path, capsys, caplog):
    """A step run after a calibration reads through it (its id in run.json, the thrust
    corrected by the fitted gain); a newer calibration outside its limits stops the next
    run in one line unless --accept-uncalibrated, which then applies nothing."""
    out = tmp_path / "runs"
    rig = _rig(tmp_path, 11, "latitude_deg = 52.27\nhysteresis_max_pct = 5\n")
    step = ["step", "--rig", str(rig), "--repeats", "1", "--out", str(out)]
    assert main(step) == 0  # before any calibration: the datasheet scale
    assert main(["calibrate-sensors", "--rig", str(rig), "--yes", "--hold-s", "1",
                 "--out", str(out)]) == 0
    assert main(step) == 0
    capsys.readouterr()
    runs = sorted(p for p in out.iterdir() if p.name.endswith("step1"))
    before, after = (read_run(p) for p in runs)
    (cal_dir,) = out.glob("*calibration-thrust")
    record = json.loads((cal_dir / "run.json").read_text())["calibration"]
    assert "calibrations" not in before.meta
    assert after.meta["calibrations"]["thrust_n"]["id"] == record["id"]
    assert after.meta["calibrations"]["thrust_n"]["state"] == "valid"
    # the same seeded plant, read through the gain: the held thrust scales by it
    hold = lambda r: r.samples["thrust_n"].to_numpy()[-2000:].mean()  # noqa: E731
    assert hold(after) / hold(before) == pytest.approx(record["applies"]["gain"], rel=2e-3)

    strict = tmp_path / "strict.toml"
    strict.write_text(rig.read_text().replace("hysteresis_max_pct = 5",
                                              "hysteresis_max_pct = 0.01"))
    strict_cal = ["calibrate-sensors", "--rig", str(strict), "--yes", "--hold-s", "1",
                  "--out", str(out)]
    assert main(strict_cal) == 1  # not accepted, and the newest for this rig
    capsys.readouterr()
    strict_step = ["step", "--rig", str(strict), "--repeats", "1", "--out", str(out)]
    assert main(strict_step) == 2
    err = capsys.readouterr().err
    assert "failed its acceptance limits" in err and "--accept-uncalibrated" in err
    assert len(err.strip().splitlines()) == 1
    assert main([*strict_step, "--accept-uncalibrated"]) == 0
    last = read_run(sorted(p for p in out.iterdir() if p.name.endswith("step1"))[-1])
    assert last.meta["calibrations"]["thrust_n"]["state"] == "not accepted: not applied"


def test_a_record_of_another_sensor_is_refused_in_one_line_with_nothing_recorded(
        tmp_path, capsys):
    """The rig's newest thrust calibration was made on another cell (the stored record
    names another model): the run stops before it starts, unless --accept-uncalibrated,
    which then applies nothing."""
    out = tmp_path / "runs"
    rig = _rig(tmp_path, 11)
    assert main(["calibrate-sensors", "--rig", str(rig), "--yes", "--hold-s", "1",
                 "--out", str(out)]) == 0
    (cal_dir,) = out.glob("*calibration-thrust")
    meta = json.loads((cal_dir / "run.json").read_text())
    meta["calibration"]["sensor"]["model"] = "HX711 board #2"  # made on the other stand
    (cal_dir / "run.json").write_text(json.dumps(meta))
    capsys.readouterr()
    step = ["step", "--rig", str(rig), "--repeats", "1", "--out", str(out)]
    assert main(step) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert "is of another sensor (model 'HX711 board #2'" in err and "--accept-uncalibrated" in err
    assert not [p for p in out.iterdir() if p.name.endswith("step1")]  # nothing recorded
    assert main([*step, "--accept-uncalibrated"]) == 0
    (run,) = [read_run(p) for p in out.iterdir() if p.name.endswith("step1")]
    assert run.meta["calibrations"]["thrust_n"]["state"] == "another sensor's: not applied"


def test_the_web_view_shows_the_record_and_its_figure_and_survives_a_hostile_one(
        tmp_path, capsys):
    from fastapi.testclient import TestClient

    from bench.serve.app import create_app
    from bench.store.stores import open_store

    out = tmp_path / "runs"
    assert main(["calibrate-sensors", "--yes", "--hold-s", "1", "--masses-g", "0,200,1000",
                 "--operator", "A. Tester", "--out", str(out)]) == 0
    capsys.readouterr()
    (run_dir,) = out.glob("*calibration-thrust")
    with TestClient(create_app(open_store(str(out)))) as client:
        page = client.get(f"/runs/{run_dir.name}")
        assert page.status_code == 200
        assert 'id="calibration"' in page.text and "A. Tester" in page.text
        assert "accepted" in page.text and "budget of the gain" in page.text
        fig = client.get(f"/runs/{run_dir.name}/calibration.png")
        assert fig.status_code == 200 and fig.content[:4] == b"\x89PNG"
        meta = json.loads((run_dir / "run.json").read_text())
        meta["calibration"]["result"]["scale"] = "<script>alert(1)</script>"
        meta["calibration"]["operator"] = "<b>x</b>"
        (run_dir / "run.json").write_text(json.dumps(meta))
        (run_dir / "calibration.png").unlink()
        (run_dir / "calibration.png").symlink_to("/etc/passwd")
        page = client.get(f"/runs/{run_dir.name}")
        assert page.status_code == 200 and 'id="calibration"' not in page.text
        assert "<script>alert(1)</script>" not in page.text  # escaped in run.json's text
        assert client.get(f"/runs/{run_dir.name}/calibration.png").status_code == 422


def test_a_real_cell_without_a_calibration_warns_and_a_simulated_one_does_not(tmp_path,
                                                                           caplog):
    import logging
    from types import SimpleNamespace

    from bench.plan_runner.cell_calibrations import apply_calibrations
    from drivers.contracts import ChannelInfo, DeviceInfo

    cell = SimpleNamespace(describe=lambda: DeviceInfo(
        "load_cell", "m", "u", (ChannelInfo("thrust_n", "N", 1.0, 0.0, 1.0),)))
    devices = SimpleNamespace(sensors={"load_cell": cell})
    for url, warns in (("serial:///dev/ttyUSB0", True), ("serial://sim/loadcell", False),
                       ("sim://load_cell", False)):
        rig = SimpleNamespace(name="stand", devices={"load_cell": SimpleNamespace(url=url)})
        caplog.clear()
        with caplog.at_level(logging.WARNING):
            assert apply_calibrations(rig, devices, tmp_path) == {}
        assert any("no calibration of thrust_n" in r.message for r in caplog.records) == warns


def test_a_hold_ends_where_the_simulated_clock_cannot_reach_its_float_end():
    """105 ms + 0.2 s is a float the clock's whole nanoseconds never reach: the hold ended
    only within a nanosecond of it (it used to sleep 0 ns for ever)."""
    from types import SimpleNamespace

    from bench.jobs.sensor_calibration import _read_for
    from drivers.sim.clock import SimClock

    clock = SimClock()
    clock.sleep(0.105)
    reads = []

    def read_block():
        reads.append(clock.now())
        assert len(reads) < 100, "the hold never ended"
        return SimpleNamespace(t_s=np.array([clock.now()]), values={"thrust_n": np.zeros(1)})

    t, _ = _read_for(clock, SimpleNamespace(read_block=read_block), "thrust_n", 0.2)
    assert t.size == len(reads) <= 5 and clock.now() == pytest.approx(0.305, abs=1e-9)
