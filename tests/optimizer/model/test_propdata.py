"""APC static propeller data: coefficients, matching, use at hover (opt-in)."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from bench.cli import main
from optimizer.catalogs.catalog import load_catalog
from optimizer.model.design_model import evaluate_grid
from optimizer.model.propdata import catalog_curves, load_curves, match, match_report
from tests.conftest import CATALOGS, SIZINGLAB


@pytest.fixture(scope="module")
def curves():
    """The APC curves, read once for the file (the tests only read them)."""
    return load_curves(SIZINGLAB)


def test_coefficients_from_thrust_and_torque(curves, shared_data) -> None:
    raw = pd.read_csv(SIZINGLAB / "APC_STATIC-data-all-props.csv", sep=";")
    row = raw[(raw["TYPE"] == "MR") & (raw["DIAMETER(IN)"] == 10) & (raw["PITCH(IN)"] == 4.5)
              & (raw["RPM"] == 6000)].iloc[0]
    n, d = 100.0, 10 * 0.0254  # 6000 rpm
    ct = row["THRUST(LBF)"] * 4.4482216 / (1.225 * n**2 * d**4)
    cp = 2 * math.pi * row["TORQUE(IN.LBF)"] * 0.11298483 / (1.225 * n**2 * d**5)
    c = next(c for c in curves if c.family == "MR" and c.diameter_in == 10 and c.pitch_in == 4.5)
    k = int(np.flatnonzero(c.rpm == 6000)[0])
    assert c.ct[k] == pytest.approx(ct, rel=1e-6) and c.cp[k] == pytest.approx(cp, rel=1e-6)
    # APC's own two-decimal columns agree to their rounding
    assert abs(c.ct[k] - row["Ct"]) <= 0.006 and abs(c.cp[k] - row["Cp"]) <= 0.006


def test_matches_and_misses(curves, shared_data, fixtures_dir) -> None:
    from optimizer.catalogs.sizinglab import import_sizinglab

    lab = import_sizinglab(SIZINGLAB)
    found = match(lab, curves)
    assert all(c is not None and c.family == "MR" for c in found)
    for c, (_, row) in zip(found, lab.propellers.iterrows(), strict=True):
        assert c.diameter_in == pytest.approx(row["diameter_m"] / 0.0254)
        assert c.pitch_in == pytest.approx(row["pitch_m"] / 0.0254, abs=0.06)
    thesis_d = load_catalog(CATALOGS / "thesis-d")  # no pitch column
    report = match_report(thesis_d, catalog_curves(thesis_d, curves))
    assert report["matched"] == [] and report["missed"] == list(thesis_d.propeller_ids)


def test_constant_coefficients_reproduce_the_thesis_grid(fixtures_dir) -> None:
    cat = load_catalog(CATALOGS / "thesis-e")
    ct = cat.propellers["ct"].to_numpy(float)[:, None, None]
    cp = cat.propellers["cp"].to_numpy(float)[:, None, None]
    base = evaluate_grid(cat, 6)
    same = evaluate_grid(cat, 6, coefficients=lambda rpm: (ct + 0 * rpm, cp + 0 * rpm))
    for key, value in base.metrics.items():
        assert np.allclose(same.metrics[key], value, rtol=1e-12), key


def test_hover_with_data_is_self_consistent(curves, shared_data) -> None:
    from optimizer.catalogs.sizinglab import import_sizinglab

    lab = import_sizinglab(SIZINGLAB)
    table = catalog_curves(lab, curves)
    grid = evaluate_grid(lab, 4, coefficients=table.coefficients)
    rpm = grid.metrics["hover_rpm"]
    ct, _ = table.coefficients(rpm)
    d = lab.propellers["diameter_m"].to_numpy(float)[:, None, None]
    thrust = ct * 1.225 * (rpm / 60) ** 2 * d**4  # (E.1) at the converged speed
    assert np.allclose(thrust, grid.extras["hover_thrust_n"], rtol=1e-6)
    # interpolation on the table equals np.interp on the matched curve
    c = table.matched[2]
    r = np.array([3000.0, 4550.0, 7020.0])
    got = table.coefficients(np.broadcast_to(r, (len(lab.propellers), 3)))[0][2]
    assert np.allclose(got, np.interp(r, c.rpm, c.ct), rtol=2e-3)


def test_evaluate_prop_data(capsys, shared_data) -> None:
    assert main(["evaluate", "--actuators", "4", "--propeller", "P4", "--motor", "M1",
                 "--battery", "B3", "--prop-data", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)["propeller_data"]
    assert doc["matched"][0]["data"].startswith("APC 14x4.7")
    cmp_ = doc["comparison"]
    assert {"hover_rpm", "propeller_power_w", "max_thrust_n"} <= set(cmp_)
    assert cmp_["hover_rpm"]["data"] != cmp_["hover_rpm"]["constant"]


def test_optimize_prop_data_reports_matches(capsys, shared_data) -> None:
    assert main(["optimize", "--prop-data", "--actuators", "4", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert len(doc["propeller_data"]["matched"]) == 4 and doc["propeller_data"]["missed"] == []
    assert main(["optimize", "--actuators", "4", "--json"]) == 0
    plain = json.loads(capsys.readouterr().out)
    # measured coefficients change the hover speed of the chosen design
    assert doc["best"]["hover_rpm"] != plain["best"]["hover_rpm"]
