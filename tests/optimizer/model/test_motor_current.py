"""Motor winding current: I_w = Q / K_t + I_0 at hover (Q = W / omega, (E.3)) vs max_current_a.

The thesis' own check (x18 / N, (E.67): battery-side current per actuator) stays beside it
and alone with ``motor_current = "battery"``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from optimizer.catalogs.catalog import Catalog, load_catalog
from optimizer.errors import CatalogError
from optimizer.model.design_model import evaluate_design, evaluate_grid
from optimizer.solve.objectives import single
from optimizer.solve.selection import Requirements, optimize
from tests.conftest import SIZINGLAB

ROOT = Path(__file__).resolve().parents[3]
CATALOGS = ROOT / "optimizer" / "data" / "catalogs"
ISSUE_KEYS = (
    "actuators, feasible, propeller, motor, battery, flight_time_min, time_constant_ms, price, "
    "total_mass_kg, hover_rpm, propeller_power_w, current_a, roll_inertia_kgm2, "
    "pitch_inertia_kgm2"
).split(", ")


@pytest.fixture(scope="module")
def thesis_e() -> Catalog:
    return load_catalog(CATALOGS / "thesis-e")


def _with(cat: Catalog, motors: pd.DataFrame | None = None, **constants) -> Catalog:
    """``cat`` in datasheet units again, with other motors and/or constants."""
    props = cat.propellers.assign(mass_g=cat.propellers["mass_kg"] * 1e3)
    bats = cat.batteries.assign(
        mass_g=cat.batteries["mass_kg"] * 1e3, capacity_mah=cat.batteries["capacity_ah"] * 1e3
    )
    if motors is None:
        motors = _datasheet_motors(cat)
    return Catalog.from_frames(
        props.drop(columns=["mass_kg", "pitch_m"]),
        motors,
        bats.drop(columns=["mass_kg", "capacity_ah"]),
        cat.constants.with_updates(**constants),
        source=cat.source,
    )


def _datasheet_motors(cat: Catalog) -> pd.DataFrame:
    return cat.motors.assign(
        mass_g=cat.motors["mass_kg"] * 1e3,
        kv_rpm_per_v=cat.motors["kv_rad_s_per_v"] * 60 / (2 * math.pi),
    ).drop(columns=["mass_kg", "kv_rad_s_per_v"])


def _hyperion(no_load: float | None = None) -> pd.DataFrame:
    """Table D.3 #1: 3900 Kv, 16.67 A, 200 W (a high-K_v motor)."""
    row = {
        "id": "H1",
        "name": "Hyperion 3900 Kv",
        "kv_rpm_per_v": 3900,
        "resistance_ohm": 0.064,
        "mass_g": 32,
        "max_current_a": 16.67,
        "max_power_w": 200,
        "price": 0,
    }
    if no_load is not None:
        row["no_load_current_a"] = no_load
    return pd.DataFrame([row])


def test_high_kv_motor_on_large_prop_is_infeasible_by_winding_current(thesis_e) -> None:
    cat = _with(thesis_e, _hyperion())
    d = evaluate_design(cat, 4, "P4", "H1", "B3", 1.5)  # 14 in propeller
    # battery side (E.67): well inside the rating; the winding carries far more
    assert d["current_a"] / 4 < 16.67 / 2
    assert d["motor_current_a"] > 2 * 16.67
    assert not d["feasible"]
    assert d["reason"].startswith("motor winding current")
    assert "> limit 16.67 A" in d["reason"]
    labels = {c["label"]: c for c in d["checks"]}
    assert labels["motor current"]["ok"] and not labels["motor winding current"]["ok"]
    # the thesis reading (battery-side current only) accepts it
    thesis = evaluate_design(_with(cat, motor_current="battery"), 4, "P4", "H1", "B3", 1.5)
    assert thesis["feasible"] and thesis["reason"] == ""
    assert "motor winding current" not in {c["label"] for c in thesis["checks"]}
    assert thesis["motor_current_a"] == pytest.approx(d["motor_current_a"])  # still reported


def test_optimizer_avoids_the_high_kv_motor(thesis_e) -> None:
    # lighter than M1-M3 at the same price: the best flight time if the winding is ignored
    h1 = _hyperion().assign(price=31.36, mass_g=20)
    motors = pd.concat([_datasheet_motors(thesis_e), h1], ignore_index=True)
    req = Requirements(payload_kg=1.5)
    for mode, expect_h1 in (("battery", True), ("winding", False)):
        cat = _with(thesis_e, motors, motor_current=mode)
        for method in ("milp", "exact"):
            r = optimize(
                cat, single("flight-time"), actuators=(4,), requirements=req, method=method
            )
            assert (r.designs[0].motor == "H1") is expect_h1, (mode, method)


def test_winding_current_is_hover_torque_over_kt_plus_no_load(thesis_e) -> None:
    base = _with(thesis_e, _hyperion())
    with_io = _with(thesis_e, _hyperion(no_load=1.25))
    for n, payload in ((4, 0.0), (6, 0.5), (8, 1.5)):
        d = evaluate_design(base, n, "P2", "H1", "B1", payload)
        omega = d["hover_rpm"] * 2 * math.pi / 60
        kt = 60 / (2 * math.pi * 3900)  # K_t = 1 / K_v[rad/s/V]
        assert d["motor_current_a"] == pytest.approx(d["propeller_power_w"] / omega / kt)
        d_io = evaluate_design(with_io, n, "P2", "H1", "B1", payload)
        assert d_io["motor_current_a"] == pytest.approx(d["motor_current_a"] + 1.25)
        assert d_io["current_a"] == pytest.approx(d["current_a"])  # (E.67) unchanged


def test_winding_check_implies_e67_check_where_the_motor_reaches_hover_speed(thesis_e) -> None:
    """Wherever the back-EMF K_e omega at hover is below the battery voltage, Q / K_t >= W / V.

    So the thesis' check only adds something for designs whose motor cannot turn the
    hover speed at all (see the next test), which is why it is kept, not replaced.
    """
    rng = np.random.default_rng(7)
    motors = pd.DataFrame(
        {
            "id": [f"M{i}" for i in range(12)],
            "name": "random",
            "kv_rpm_per_v": rng.uniform(150, 4000, 12),
            "resistance_ohm": rng.uniform(0.02, 0.4, 12),
            "mass_g": rng.uniform(20, 200, 12),
            "max_current_a": rng.uniform(5, 40, 12),
            "max_power_w": 1e4,
            "price": 10,
        }
    )
    cat = _with(thesis_e, motors)
    for n in (4, 6, 8):
        g = evaluate_grid(cat, n, 1.0)
        e67 = g.metrics["current_a"] / n
        kv = cat.motors["kv_rad_s_per_v"].to_numpy()[None, :, None]
        back_emf = g.metrics["hover_rpm"] * 2 * math.pi / 60 / kv
        reachable = back_emf <= g.extras["voltage_v"]
        assert reachable.any() and (~reachable).any()
        assert np.all(g.extras["motor_current_a"][reachable] >= e67[reachable])
        assert np.all(g.extras["motor_current_a"][~reachable] < e67[~reachable])


def test_e67_check_still_rejects_a_motor_too_slow_for_the_hover_speed(thesis_e) -> None:
    slow = _hyperion().assign(kv_rpm_per_v=60, max_current_a=0.5)
    d = evaluate_design(_with(thesis_e, slow), 4, "P1", "H1", "B1", 0.0)
    assert d["hover_rpm"] / 60 > 12.0  # K_e omega > 12 V: the motor cannot reach hover
    labels = {c["label"]: c["ok"] for c in d["checks"]}
    assert labels["motor winding current"] and not labels["motor current"]
    assert not d["feasible"]


def test_thesis_e_picks_unchanged(thesis_e) -> None:
    """Paper E cases I-III: the same designs with and without the winding check."""
    assert thesis_e.constants.motor_current == "winding"
    battery = _with(thesis_e, motor_current="battery")
    cases = (("flight-time", 0.0), ("flight-time", 1.5), ("time-constant", 0.0))
    for objective, payload in cases:
        req = Requirements(payload_kg=payload)
        picks = {}
        for name, cat in (("winding", thesis_e), ("battery", battery)):
            r = optimize(cat, single(objective), actuators=(4, 6, 8), requirements=req)
            picks[name] = [(d.propeller, d.motor, d.battery) for d in r.designs]
            assert all(d.feasible for d in r.designs)
        assert picks["winding"] == picks["battery"], (objective, payload)
    # P4 on M3 (Table E.8, 4 actuators) hovers far inside the 26 A rating
    d = evaluate_design(thesis_e, 4, "P4", "M3", "B3", 0.0)
    assert d["feasible"] and d["motor_current_a"] < 26 / 2


def test_thesis_d_keeps_the_thesis_reading() -> None:
    """Table D.5's designs draw 20-32 A winding current from 16.67 A motors."""
    cat = load_catalog(CATALOGS / "thesis-d")
    assert cat.constants.motor_current == "battery"
    assert evaluate_design(cat, 4, "P5", "M1", "B3", 0.5)["feasible"]
    winding = evaluate_design(_with(cat, motor_current="winding"), 4, "P5", "M1", "B3", 0.5)
    assert winding["reason"].startswith("motor winding current")


def test_record_keeps_issue_keys_and_adds_motor_current(thesis_e) -> None:
    d = evaluate_design(thesis_e, 6, "P3", "M2", "B2", 0.5)
    for key in ISSUE_KEYS:
        assert key in d, key
    assert isinstance(d["motor_current_a"], float) and d["motor_current_a"] > 0


def test_catalog_toml_motor_current_key(tmp_path, thesis_e) -> None:
    with pytest.raises(CatalogError, match="key 'motor_current': expected one of 'winding', 'b"):
        thesis_e.constants.with_updates(motor_current="phase")
    folder = tmp_path / "cat"
    folder.mkdir()
    for name in ("propellers.csv", "motors.csv", "batteries.csv"):
        (folder / name).write_text((CATALOGS / "thesis-e" / name).read_text())
    assert load_catalog(folder).constants.motor_current == "winding"  # the default
    (folder / "catalog.toml").write_text('motor_current = "sometimes"\n')
    with pytest.raises(CatalogError, match=r"catalog.toml: key 'motor_current'"):
        load_catalog(folder)


def test_no_load_current_column_is_optional_and_validated(tmp_path) -> None:
    folder = tmp_path / "cat"
    folder.mkdir()
    for name in ("propellers.csv", "batteries.csv", "catalog.toml"):
        (folder / name).write_text((CATALOGS / "thesis-e" / name).read_text())
    motors = pd.read_csv(CATALOGS / "thesis-e" / "motors.csv")
    motors.insert(6, "no_load_current_a", ["0.5", "", "0.7"])
    motors.to_csv(folder / "motors.csv", index=False)
    cat = load_catalog(folder)
    assert cat.motors["no_load_current_a"].tolist()[::2] == [0.5, 0.7]
    assert math.isnan(cat.motors["no_load_current_a"].iloc[1])  # empty: I_0 = 0
    motors.loc[2, "no_load_current_a"] = "-1"
    motors.to_csv(folder / "motors.csv", index=False)
    with pytest.raises(CatalogError, match=r"data row 3 \(line 4\), column 'no_load_current_a'"):
        load_catalog(folder)


def test_sizinglab_maps_no_load_and_continuous_current(shared_data) -> None:
    from optimizer.catalogs.sizinglab import import_sizinglab

    folder = SIZINGLAB
    raw = pd.read_csv(folder / "Motors_Data.csv", sep=";")
    motors = import_sizinglab(folder).motors
    assert motors["no_load_current_a"].to_numpy() == pytest.approx(raw["Io_A"].to_numpy())
    continuous = raw["Tnom_Nm"] * raw["Kv_rpm_v"] * 2 * math.pi / 60 + raw["Io_A"]
    expected = np.minimum(raw["Imax_A"], continuous).to_numpy()
    assert motors["max_current_a"].to_numpy() == pytest.approx(expected, abs=1e-3)
    kde = raw["TYPE"].str.startswith("KDE").to_numpy()
    maxon = raw["TYPE"].str.startswith("maxon").to_numpy()
    # KDE's Imax is its continuous current; maxon's Imax is far above the nominal one
    assert motors["max_current_a"].to_numpy()[kde] == pytest.approx(raw["Imax_A"].to_numpy()[kde])
    assert np.all(motors["max_current_a"].to_numpy()[maxon] < raw["Imax_A"].to_numpy()[maxon])
