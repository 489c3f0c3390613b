"""``rotorbench flight-report`` on a real PX4 flight (the shipped ULog with ESC rpm) and on
a synthetic flight with a design beside it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bench.cli import main

REPO = Path(__file__).resolve().parents[3]
EVENTS = REPO / "fixtures" / "data" / "px4_ulog" / "sample_px4_events.ulg"

pytest.importorskip("pyulog")


def test_a_real_px4_flight_says_what_it_holds_and_what_it_lacks(tmp_path, capsys):
    run = tmp_path / "px4"
    assert main(["import", str(EVENTS), "--out", str(run)]) == 0
    out = tmp_path / "report"
    assert main(["flight-report", str(run), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    rep = json.loads((out / "report.json").read_text())
    # a hover without stick input: no step response, and why
    assert all("no stick input" in r["why"] for r in rep["step_response"].values())
    # ESC telemetry at a few Hz: no time constant read from it, and why
    assert all("too slow" in m["why"] for m in rep["motors"].values())
    hover = rep["hover"]
    assert hover["hover_s"] > 5 and 0.40 < hover["throttle"] < 0.55  # the flight's hover
    assert "hover (" in text and "throttle" in text
    assert (out / "noise.png").stat().st_size > 10_000


def test_a_design_that_is_not_evaluate_json_and_a_bench_run_are_one_line(tmp_path, capsys):
    run = tmp_path / "px4"
    assert main(["import", str(EVENTS), "--out", str(run)]) == 0
    bad = tmp_path / "design.json"
    bad.write_text('{"motor": "M1"}')
    capsys.readouterr()
    assert main(["flight-report", str(run), "--design", str(bad)]) == 2
    assert "no hover_throttle_pct" in capsys.readouterr().err
    assert main(["step", "--repeats", "1", "--out", str(tmp_path / "runs")]) == 0
    (step,) = (tmp_path / "runs").glob("*step1")
    capsys.readouterr()
    assert main(["flight-report", str(step), "--out", str(tmp_path / "r2")]) == 2
    err = capsys.readouterr().err
    assert "flight-report reads flight logs" in err and len(err.strip().splitlines()) == 1


def test_the_design_model_stands_beside_the_flight(tmp_path, capsys):
    run = tmp_path / "px4"
    assert main(["import", str(EVENTS), "--out", str(run)]) == 0
    capsys.readouterr()
    assert main(["evaluate", "--catalog", "thesis-e", "--actuators", "4", "--propeller", "P1",
                 "--motor", "M2", "--battery", "B1", "--json"]) == 0
    design = json.loads(capsys.readouterr().out)
    path = tmp_path / "design.json"
    path.write_text(json.dumps(design))
    out = tmp_path / "report"
    assert main(["flight-report", str(run), "--design", str(path), "--out", str(out),
                 "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    rows = {r["quantity"]: r for r in rep["design_vs_flight"]}
    thr = rows["hover throttle"]
    assert thr["predicted"] == pytest.approx(design["hover_throttle_pct"])
    assert thr["flight"] == pytest.approx(100 * rep["hover"]["throttle"])
    assert rep["design"]["motor"] == "M2"


def test_a_store_for_the_bench_constants_and_a_report_folder_go_together(tmp_path, capsys):
    """--out is the report's folder, not a run root: beside --store it names no second
    store."""
    run = tmp_path / "px4"
    assert main(["import", str(EVENTS), "--out", str(run)]) == 0
    design = tmp_path / "design.json"
    design.write_text('{"hover_throttle_pct": 45, "motor": "M2"}')
    (tmp_path / "store").mkdir()
    out = tmp_path / "report"
    assert main(["flight-report", str(run), "--design", str(design), "--store",
                 str(tmp_path / "store"), "--out", str(out)]) == 0
    assert (out / "report.json").is_file()
