"""``evaluate`` like eCalc: full throttle, hover throttle, partial load, free-form parts."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bench.cli import main
from optimizer.catalogs.catalog import load_catalog
from optimizer.model import operating_points as ops
from optimizer.model import physics
from optimizer.model.design_model import evaluate_design, single_design_catalog
from optimizer.model.sheet import design_sheet, drive_of
from tests.conftest import CATALOGS

CASE_I = ("P4", "M1", "B3")  # Case I's best thesis-e design, 4 actuators (Table E.8)


def evaluate_json(capsys, *argv: str) -> dict:
    assert main(["evaluate", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.fixture
def case_i(capsys, fixtures_dir) -> dict:
    cat = str(CATALOGS / "thesis-e")
    return evaluate_json(capsys, "--catalog", cat, "--actuators", "4", "--propeller", "P4",
                         "--motor", "M1", "--battery", "B3")


def test_case_i_thrust_to_weight_and_partial_load(case_i) -> None:
    g = 9.81
    ratio = 4 * case_i["max_thrust_n"] / (case_i["total_mass_kg"] * g)
    assert case_i["thrust_to_weight"] == pytest.approx(ratio, rel=0.01)
    rows = case_i["partial_load"]
    assert [r["throttle_pct"] for r in rows] == list(range(10, 101, 10))
    thrust = np.array([r["thrust_n"] for r in rows])
    assert np.all(np.diff(thrust) > 0)
    assert thrust[-1] == pytest.approx(case_i["max_thrust_n"])
    for key in ("throttle_pct", "thrust_n", "current_a", "power_w", "rpm", "efficiency_g_per_w"):
        assert key in rows[0]


@pytest.mark.parametrize("model", ["thesis", "drive"])
def test_case_i_current_at_hover_thrust(capsys, fixtures_dir, model) -> None:
    """One current definition per run: the partial-load table, the hover point and the
    design's per-actuator current x18 / N agree, whichever model the run uses."""
    cat = str(CATALOGS / "thesis-e")
    out = evaluate_json(capsys, "--catalog", cat, "--actuators", "4", "--propeller", "P4",
                        "--motor", "M1", "--battery", "B3", "--current-model", model)
    assert out["current_model"] == model
    rows = out["partial_load"]
    hover = out["total_mass_kg"] * 9.81 / 4
    current = np.interp(hover, [r["thrust_n"] for r in rows], [r["current_a"] for r in rows])
    design = out["current_a"] / 4
    assert current == pytest.approx(design, rel=0.05)  # within 5 % of the design's current
    assert out["hover_current_per_actuator_a"] == pytest.approx(design, rel=1e-9)
    assert out["hover_battery_current_a"] == pytest.approx(out["current_a"], rel=1e-9)
    assert out["flight_time_min"] == pytest.approx(60 * 16.0 / out["current_a"])  # (E.72)
    assert out["current_models"][model]["current_per_actuator_a"] == pytest.approx(design)
    assert out["current_models"][model]["flight_time_min"] == pytest.approx(
        out["flight_time_min"])


def test_the_two_current_models_differ_by_the_copper_loss(case_i) -> None:
    """(E.67) divides the shaft power by B_V; the drive adds the winding loss R I_w^2
    (I_0 = 0 in thesis-e): 3.84 A against 4.55 A per actuator for Case I."""
    models = case_i["current_models"]
    assert case_i["current_model"] == "thesis"  # the catalog's default: Table E.8 holds
    assert case_i["flight_time_min"] == pytest.approx(62.5, abs=0.05)
    i_w, r, v = case_i["motor_current_a"], 0.222, 12.0
    diff = models["drive"]["current_per_actuator_a"] - models["thesis"]["current_per_actuator_a"]
    assert diff == pytest.approx(r * i_w**2 / v)
    assert models["drive"]["flight_time_min"] < models["thesis"]["flight_time_min"]


def test_drive_model_current_is_the_motor_electric_power(fixtures_dir) -> None:
    """Hand-computed: I_b = (K_e omega + R I_w) I_w / B_V with I_w = Q / K_t + I_0."""
    from optimizer.model.design_model import hover_actuator

    kt, r, i0, v = 0.025, 0.1, 0.5, 12.0
    ct, cp, rho, d, thrust = 0.1, 0.05, 1.225, 0.254, 5.0
    thesis = hover_actuator(thrust, ct, cp, rho, d, r, 1e-5, kt, v, i0)
    drive = hover_actuator(thrust, ct, cp, rho, d, r, 1e-5, kt, v, i0, current_model="drive")
    n = np.sqrt(thrust / (ct * rho * d**4))  # (E.1) solved for n
    w = cp * rho * n**3 * d**5  # (E.2)
    i_w = w / (2 * np.pi * n) / kt + i0
    assert thesis.current_a == pytest.approx(w / v)  # (E.67)
    assert drive.current_a == pytest.approx((kt * 2 * np.pi * n + r * i_w) * i_w / v)
    with pytest.raises(ValueError, match="current_model"):
        hover_actuator(thrust, ct, cp, rho, d, r, 1e-5, kt, v, i0, current_model="eCalc")


def test_current_model_choice_and_method_thesis(capsys, fixtures_dir) -> None:
    cat = str(CATALOGS / "thesis-e")
    with pytest.raises(SystemExit) as bad:
        main(["optimize", "--catalog", cat, "--actuators", "4", "--current-model", "ecalc"])
    assert bad.value.code == 2
    capsys.readouterr()
    code = main(["optimize", "--catalog", cat, "--actuators", "4", "--current-model", "drive",
                 "--method", "thesis"])
    err = capsys.readouterr().err
    assert code == 2 and "method milp or exact" in err and "Traceback" not in err


def test_lossless_motor_matches_the_thesis_current(fixtures_dir) -> None:
    cat = load_catalog(CATALOGS / "thesis-e")
    single = single_design_catalog(cat, *CASE_I)
    single.motors.loc[0, "resistance_ohm"] = 0.0
    record = evaluate_design(single, 4, *CASE_I)
    sheet = design_sheet(single, record)
    rows = sheet["partial_load"]
    hover = record["total_mass_kg"] * 9.81 / 4
    current = np.interp(hover, [r["thrust_n"] for r in rows], [r["current_a"] for r in rows])
    assert current == pytest.approx(record["current_a"] / 4, rel=0.05)
    assert sheet["hover_battery_current_a"] == pytest.approx(record["current_a"], rel=1e-9)


def test_full_throttle_is_the_motor_steady_state(fixtures_dir) -> None:
    cat = load_catalog(CATALOGS / "thesis-e")
    drive = drive_of(cat)
    op = ops.at_throttle(drive, 1.0, 12.0)
    omega = op.rpm / 60 * physics.TWO_PI
    # V = K_e omega + R I with I = Q / K_t (E.4)-(E.7), Q = W / omega (E.3)
    torque = op.shaft_power_w / omega
    v = drive.kt * omega + drive.resistance_ohm * torque / drive.kt
    assert np.allclose(v, 12.0)
    assert np.allclose(op.battery_current_a * 12.0, op.power_w)


def test_battery_model_beside_the_thesis_flight_time(case_i) -> None:
    bm = case_i["battery_model"]
    assert bm["thesis_flight_time_min"] == case_i["flight_time_min"]
    assert 0 < bm["flight_time_min"] < bm["thesis_flight_time_min"]
    assert bm["end_current_a"] > bm["start_current_a"]
    assert 80 < bm["usable_capacity_pct"] < 100
    labels = {m["label"] for m in case_i["limit_margins"]}
    assert {"battery burst (full throttle)", "motor current (full throttle)"} <= labels


def test_free_form_parts_equal_the_catalog_design(capsys, case_i, fixtures_dir) -> None:
    cat = str(CATALOGS / "thesis-e")
    free = evaluate_json(
        capsys, "--catalog", cat, "--actuators", "4",
        "--prop-diameter-m", "0.3556", "--prop-ct", "0.1027", "--prop-cp", "0.0630",
        "--prop-mass-g", "25", "--motor-kv", "380", "--motor-resistance", "0.222",
        "--motor-mass-g", "111", "--motor-max-current", "17", "--battery-cells", "3",
        "--battery-mah", "16000", "--battery-mass-g", "1236",
    )
    for key in ("flight_time_min", "total_mass_kg", "max_thrust_n", "hover_throttle_pct"):
        assert free[key] == pytest.approx(case_i[key], rel=1e-12)
    assert free["propeller"] == "prop" and free["catalog"] == "<free-form>"
    # no max power given: no motor power check
    assert all("power" not in c["label"] for c in free["checks"])


def test_free_form_without_catalog_and_its_errors(capsys) -> None:
    out = evaluate_json(
        capsys, "--actuators", "4", "--prop-diameter-m", "0.254", "--prop-ct", "0.12",
        "--prop-cp", "0.08", "--motor-kv", "920", "--motor-resistance", "0.1",
        "--motor-mass-g", "56", "--battery-cells", "3", "--battery-mah", "2200",
        "--battery-mass-g", "180", "--battery-c", "25",
    )
    assert out["thrust_to_weight"] > 1 and out["feasible"]
    code = main(["evaluate", "--actuators", "4", "--motor-kv", "920"])
    err = capsys.readouterr().err
    assert code == 2 and "--prop-diameter-m" in err and "Traceback" not in err
    bad = ["evaluate", "--actuators", "4", "--prop-diameter-m", "0.254", "--prop-ct", "0.12",
           "--prop-cp", "0.08", "--motor-kv", "-920", "--motor-resistance", "0.1",
           "--motor-mass-g", "56", "--battery-cells", "3", "--battery-mah", "2200",
           "--battery-mass-g", "180"]
    assert main(bad) == 2
    err = capsys.readouterr().err
    assert err.strip().endswith("--motor-kv: expected a number > 0, got -920.0")
    assert len(err.strip().splitlines()) == 1
    assert main(["evaluate", "--actuators", "4", "--propeller", "P1", "--motor-kv", "9"]) == 2
    assert "not both" in capsys.readouterr().err


def test_text_sheet_and_plot(capsys, tmp_path) -> None:
    png = tmp_path / "pl.png"
    assert main(["evaluate", "--actuators", "4", "--propeller", "P4", "--motor", "M1",
                 "--battery", "B3", "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    assert "Partial load" in out and "Thrust-to-weight" in out and "battery model" in out
    assert png.stat().st_size > 1000
