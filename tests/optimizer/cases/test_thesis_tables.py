"""The model reproduces the designs reported in Paper E (Tables E.8-E.10) and Paper D.

Expected values are the tables' printed numbers; the model derives its values from the
shipped datasheet catalogs (optimizer/data/catalogs/thesis-e, thesis-d) and their catalog.toml
readings. See docs/thesis-reproduction.md for the readings and the discussion.
"""

from __future__ import annotations

import numpy as np
import pytest

from optimizer.catalogs.catalog import load_catalog
from optimizer.model.design_model import evaluate_design

# (table, N_a, payload kg, propeller, motor, battery, time constant ms, flight time min, price)
PAPER_E = [
    ("E.8", 4, 0.0, "P4", "M3", "B3", 161, 62.5, 227.4),
    # Table E.8 prints propeller 3 for 6 actuators; its numbers belong to propeller 4
    # (see test_table_e8_six_actuator_cell below and docs/thesis-reproduction.md).
    ("E.8", 6, 0.0, "P4", "M3", "B3", 165, 60.0, 290.2),
    ("E.8", 8, 0.0, "P4", "M2", "B3", 134, 55.5, 352.9),
    ("E.9", 4, 1.5, "P4", "M3", "B3", 150, 25.4, 227.4),
    ("E.9", 6, 1.5, "P4", "M3", "B3", 156, 27.1, 290.2),
    ("E.9", 8, 1.5, "P4", "M1", "B3", 123, 27.3, 352.9),
    ("E.10", 4, 0.0, "P1", "M1", "B1", 39, 37.2, 150.9),
    ("E.10", 6, 0.0, "P1", "M1", "B1", 39, 29.4, 213.65),
    ("E.10", 8, 0.0, "P1", "M1", "B1", 39, 23.8, 276.4),
]


@pytest.fixture(scope="module")
def thesis_e(request):
    from pathlib import Path

    root = Path(__file__).resolve().parents[3]
    return load_catalog(root / "optimizer" / "data" / "catalogs" / "thesis-e")


@pytest.mark.parametrize(
    ("table", "n", "payload", "prop", "motor", "batt", "tau_ms", "time_min", "price"),
    PAPER_E,
    ids=[f"{row[0]}-N{row[1]}" for row in PAPER_E],
)
def test_paper_e_tables(thesis_e, table, n, payload, prop, motor, batt, tau_ms, time_min, price):
    d = evaluate_design(thesis_e, n, prop, motor, batt, payload)
    assert d["flight_time_min"] == pytest.approx(time_min, rel=0.005)
    assert abs(d["time_constant_ms"] - tau_ms) <= 1.0
    # Prices are printed to 0.1 (213.65 to 0.01); 6 x 31.36 + 25.5 = 213.66.
    assert d["price"] == pytest.approx(price, abs=0.051)
    assert d["feasible"], d["reason"]


def test_table_e8_six_actuator_cell(thesis_e):
    """The printed propeller 3 cannot give Table E.8's 165 ms and 60.0 min; propeller 4 does."""
    printed = evaluate_design(thesis_e, 6, "P3", "M3", "B3", 0.0)
    assert abs(printed["time_constant_ms"] - 165) > 50
    assert printed["flight_time_min"] < 0.95 * 60.0


def test_readings_matter(thesis_e):
    """The printed alternatives (nominal 11.1 V, diagonal arms) miss Table E.8 by > 0.5 %."""
    from dataclasses import replace

    base = evaluate_design(thesis_e, 4, "P4", "M3", "B3")["flight_time_min"]
    for change in ({"battery_voltage": "nominal"}, {"arm_length": "diagonal"}):
        other = replace(thesis_e, constants=thesis_e.constants.with_updates(**change))
        t = evaluate_design(other, 4, "P4", "M3", "B3")["flight_time_min"]
        assert abs(t / 62.5 - 1) > 0.005, change
    assert base == pytest.approx(62.5, rel=0.005)


# Paper D, Tables D.5 (case 1: 0.5 kg payload, >= 10 min) and D.6 (case 2: max flight time).
# (table, N_a, propeller, motor, battery, tau_m s, roll+pitch inertia kg m^2, flight time min)
PAPER_D = [
    ("D.5", 4, "P5", "M1", "B3", 0.27, 0.04, 19),
    ("D.5", 6, "P4", "M1", "B1", 0.24, 0.09, 12),
    ("D.5", 8, "P5", "M1", "B5", 0.24, 0.19, 21),
    ("D.6", 4, "P6", "M5", "B4", 0.24, 0.10, 23),
    ("D.6", 6, "P5", "M1", "B4", 0.23, 0.11, 27),
    ("D.6", 8, "P5", "M2", "B4", 0.21, 0.27, 23),
]
D_IDS = [f"{row[0]}-N{row[1]}" for row in PAPER_D]
D_PAYLOAD_KG = 0.5  # "lift an SLR camera at 0.5 kg" (Paper D section 4.1)


@pytest.fixture(scope="module")
def thesis_d():
    from pathlib import Path

    root = Path(__file__).resolve().parents[3]
    return load_catalog(root / "optimizer" / "data" / "catalogs" / "thesis-d")


def _d(thesis_d, row):
    _, n, prop, motor, batt, *_ = row
    return evaluate_design(thesis_d, n, prop, motor, batt, D_PAYLOAD_KG)


def test_paper_d_designs_are_feasible(thesis_d):
    for row in PAPER_D:
        d = _d(thesis_d, row)
        assert d["feasible"], (row, d["reason"])
        assert d["flight_time_min"] >= 10.0  # case 1's requirement holds for every design


def test_paper_d_flight_times_differ_by_one_common_factor(thesis_d):
    """Table / model flight time is the same factor (0.60) for all six designs.

    The masses, hover power and capacities agree up to one scale; the printed equations
    (D.7)-(D.8) do not say where it comes from (docs/thesis-reproduction.md).
    """
    ratios = np.array([row[7] / _d(thesis_d, row)["flight_time_min"] for row in PAPER_D])
    # The table prints whole minutes: +-0.5 min is +-4 % on 12 min.
    assert np.max(np.abs(ratios / ratios.mean() - 1)) < 0.03
    assert ratios.mean() == pytest.approx(0.60, abs=0.01)


@pytest.mark.xfail(strict=True, reason="Paper D flight times are 0.60 x the model's (see doc)")
@pytest.mark.parametrize("row", PAPER_D, ids=D_IDS)
def test_paper_d_flight_time(thesis_d, row):
    assert _d(thesis_d, row)["flight_time_min"] == pytest.approx(row[7], abs=0.5)


@pytest.mark.xfail(strict=True, reason="Paper D's propeller/motor inertias are not printed")
@pytest.mark.parametrize("row", PAPER_D, ids=D_IDS)
def test_paper_d_time_constant(thesis_d, row):
    assert _d(thesis_d, row)["time_constant_ms"] / 1e3 == pytest.approx(row[5], abs=0.005)


@pytest.mark.xfail(
    strict=True, reason="Paper D: diagonal of (D.4) as arm for N=4,6; N=8 unexplained (see doc)"
)
@pytest.mark.parametrize("row", PAPER_D, ids=D_IDS)
def test_paper_d_inertia(thesis_d, row):
    d = _d(thesis_d, row)
    total = d["roll_inertia_kgm2"] + d["pitch_inertia_kgm2"]
    assert total == pytest.approx(row[6], abs=0.005)
