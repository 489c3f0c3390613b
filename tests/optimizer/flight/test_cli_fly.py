"""``rotorbench fly`` and ``optimize --max-roll-rise-ms``: output keys, actuator sources,
one-line errors."""

from __future__ import annotations

import json

import pytest

from bench.cli import main
from optimizer.catalogs.catalog import load_catalog
from optimizer.flight.design import setup
from optimizer.model.design_model import evaluate_grid
from optimizer.model.measured import MeasuredActuator
from tests.conftest import CATALOGS

CASE_I = ["--actuators", "4", "--propeller", "P4", "--motor", "M1", "--battery", "B3"]


def _json(capsys, *argv: str) -> dict:
    assert main(list(argv)) == 0
    return json.loads(capsys.readouterr().out)


def test_fly_json_has_the_issue_keys(capsys, tmp_path) -> None:
    doc = _json(capsys, "fly", *CASE_I, "--maneuver", "roll_step", "gust", "--json",
                "--plot", str(tmp_path))
    assert set(doc["hover"]) >= {"rpm", "throttle", "power_w"}
    assert doc["hover"]["rpm"] == pytest.approx(doc["design"]["hover_rpm"], rel=0.02)
    assert 0 < doc["hover"]["throttle"] < 1
    assert list(doc["maneuvers"]) == ["roll_step", "gust"]
    for m in doc["maneuvers"].values():
        assert {"rise_time_ms", "overshoot_pct", "settling_time_ms", "saturation_pct"} <= set(m)
    assert doc["maneuvers"]["roll_step"]["rise_time_ms"] > 0
    assert sorted(p.name for p in tmp_path.glob("*.png")) == [
        "fly_gust.png", "fly_hover.png", "fly_roll_step.png"]
    # the hover's shaft power is the model's (E.60-E.63) at evaluate's hover speed
    grid = evaluate_grid(load_catalog(CATALOGS / "thesis-e"), 4)
    model_w = 4 * float(grid.metrics["propeller_power_w"][3, 0, 2])  # P4+M1+B3
    assert doc["hover"]["shaft_power_w"] == pytest.approx(model_w, rel=0.02)
    assert doc["hover"]["can_hover"] is True and doc["hover"]["note"] == ""
    assert doc["vehicle"]["drag_n_s_m"] == 0.0


def test_a_design_that_cannot_hover_says_so(capsys) -> None:
    """Case III's pick under the thesis' rules (P1+M1+B3, no thrust-to-weight check) falls:
    the report says why instead of only showing empty rise times."""
    argv = ["fly", "--actuators", "4", "--propeller", "P1", "--motor", "M1", "--battery", "B3",
            "--maneuver", "roll_step"]
    doc = _json(capsys, *argv, "--json", "--thesis-rules")
    assert doc["design"]["feasible"] is True
    margin = _json(capsys, *argv, "--json")  # the default hover margin names it infeasible
    assert margin["design"]["feasible"] is False
    assert "thrust to weight 0.734" in margin["design"]["reason"]
    assert doc["hover"]["can_hover"] is False
    assert doc["hover"]["note"].startswith("cannot hover: needs 4994 rpm")
    assert doc["maneuvers"]["roll_step"]["rise_time_ms"] is None
    assert main(argv) == 0
    assert "cannot hover: needs 4994 rpm" in capsys.readouterr().out


def test_drag_reaches_the_vehicle(capsys) -> None:
    doc = _json(capsys, "fly", *CASE_I, "--maneuver", "gust", "--json", "--drag", "0.5")
    still = _json(capsys, "fly", *CASE_I, "--maneuver", "gust", "--json")
    assert doc["vehicle"]["drag_n_s_m"] == 0.5
    assert doc["maneuvers"]["gust"] != still["maneuvers"]["gust"]


def test_the_minimum_time_constant_flyable_design_flies(capsys) -> None:
    """The minimum-time-constant design of the thesis' rules cannot hover (above); with the
    flyable-design rules (hover throttle band, ...) the fastest design it picks flies every
    maneuver: hover at evaluate's speed within 2 %, overshoot below 25 %."""
    best = _json(capsys, "optimize", "--objective", "time-constant", "--actuators", "4",
                 "--flyable", "--json")["best"]
    doc = _json(capsys, "fly", "--actuators", "4", "--propeller", best["propeller"],
                "--motor", best["motor"], "--battery", best["battery"], "--json")
    assert doc["hover"]["can_hover"]
    assert doc["hover"]["rpm"] == pytest.approx(doc["design"]["hover_rpm"], rel=0.02)
    for name in ("roll_step", "pitch_step", "yaw_step", "altitude_step"):
        m = doc["maneuvers"][name]
        assert m["rise_time_ms"] is not None and m["overshoot_pct"] < 25.0, (name, m)
    assert doc["maneuvers"]["gust"]["settling_time_ms"] is not None


def test_plus_layout_flies_the_same_roll_step(capsys) -> None:
    x = _json(capsys, "fly", *CASE_I, "--maneuver", "roll_step", "--json")
    plus = _json(capsys, "fly", *CASE_I, "--maneuver", "roll_step", "--json", "--layout", "plus")
    assert plus["vehicle"]["layout"] == "plus"
    rx, rp = (d["maneuvers"]["roll_step"]["rise_time_ms"] for d in (x, plus))
    assert rp == pytest.approx(rx, rel=0.05)  # equal inertias; same gains rule


def test_measured_actuator_numbers_reach_the_flight_model() -> None:
    catalog = load_catalog(CATALOGS / "thesis-e")
    item = MeasuredActuator("P4", "M1", time_constant_s=0.09, tau_up_s=0.06, tau_down_s=0.12,
                            latency_s=0.004, k_f_n_s2=6e-5, k_m_nm_s2=2e-6,
                            time_constant_source="run-x")
    grid = evaluate_grid(catalog, 4, overrides=[item])
    vehicle, actuator = setup(catalog, grid, (3, 0, 2))
    assert (actuator.tau_up_s, actuator.tau_down_s, actuator.latency_s) == (0.06, 0.12, 0.004)
    assert (vehicle.k_f, vehicle.k_m) == (6e-5, 2e-6)
    assert actuator.source == "measured: run run-x"
    _, model = setup(catalog, grid, (3, 1, 2))  # another motor: the datasheet model
    assert model.source == "model (E.35)"


def test_step_run_is_fitted_on_the_fly(capsys, tmp_path) -> None:
    from bench.plan_runner.runner import RunOptions
    from bench.plan_runner.session import run_sequence
    from bench.plans.stand_sequences import hover_band_n, step1
    from bench.rig.rig import default_rig_path, load_rig
    from bench.store.constants_fit import fit_for_store
    from drivers.factory import open_rig

    rig = load_rig(default_rig_path())
    run = run_sequence(rig, step1(repeats=2, band_n=hover_band_n()), tmp_path, open_rig,
                       options=RunOptions(tick_s=0.02)).run_dir
    doc = _json(capsys, "fly", *CASE_I, "--maneuver", "roll_step", "--json",
                "--step-run", str(run))
    data = fit_for_store(run)[3]
    act = doc["actuator"]
    assert act["tau_up_ms"] == pytest.approx(data["tau_up_s"] * 1e3)
    assert act["tau_down_ms"] == pytest.approx(data["tau_down_s"] * 1e3)
    assert run.name in act["source"]
    # the default rig's actuator is no catalog part: the run flies on P4/M1 with a warning
    key = fit_for_store(run)[0]
    assert (key.propeller, key.motor) != ("P4", "M1")
    [warning] = doc["warnings"]
    assert warning.startswith("--step-run measured another actuator")
    assert f"motor {key.motor} (design: M1)" in warning
    assert f"propeller {key.propeller} (design: P4)" in warning


def test_step_run_of_the_same_actuator_has_no_warning() -> None:
    from bench.commands.fly import step_run_mismatch
    from optimizer.flight.design import StepConstants

    same = StepConstants(0.1, 0.1, 0.01, motor="M1", propeller="P4")
    assert step_run_mismatch(same, "P4", "M1") is None
    assert step_run_mismatch(None, "P4", "M1") is None
    assert "motor M1 (design: M2)" in step_run_mismatch(same, "P4", "M2")


def test_optimize_max_roll_rise(capsys) -> None:
    base = ["optimize", "--actuators", "4", "--json"]
    free = _json(capsys, *base)["best"]
    doc = _json(capsys, *base, "--max-roll-rise-ms", "300")["best"]
    assert doc["flight"]["roll_rise_ms"] <= 300
    assert doc["flight"]["flown"] >= 2  # Case I's design rises in ~420 ms: it was flown first
    assert doc["flight_time_min"] < free["flight_time_min"]
    assert main([*base, "--max-roll-rise-ms", "50"]) == 3
    out = json.loads(capsys.readouterr().out)
    assert "no feasible design rises in roll within 50 ms" in out["designs"][0]["reason"]


@pytest.mark.parametrize("argv, words", [
    (["fly", "--actuators", "5", "--propeller", "P1", "--motor", "M1", "--battery", "B1"],
     "--actuators"),
    (["fly", "--actuators", "4", "--propeller", "P9", "--motor", "M1", "--battery", "B1"],
     "--propeller 'P9'"),
    (["fly", "--actuators", "4", "--propeller", "P1", "--motor", "M1"], "--battery"),
    (["fly", "--sweep", "--propeller", "P1"], "--propeller does not apply to --sweep"),
    (["fly", *CASE_I, "--step-run", "/nonexistent/run"], "/nonexistent/run"),
    (["fly", *CASE_I, "--drag", "-1"], "--drag"),
    (["fly", *CASE_I, "--plot", "pyproject.toml"], "--plot pyproject.toml: is a file"),
    (["fly", "--sweep", "--plot", "pyproject.toml/figs"], "--plot pyproject.toml/figs"),
    (["optimize", "--max-roll-rise-ms", "-1"], "--max-roll-rise-ms"),
    (["optimize", "--actuators", "3", "--max-roll-rise-ms", "100"], "4, 6 or 8"),
    (["optimize", "--paper-e-cases", "--max-roll-rise-ms", "100"], "--paper-e-cases"),
])
def test_bad_input_is_one_line_exit_2(capsys, argv, words) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "Traceback" not in err
    assert words in err
