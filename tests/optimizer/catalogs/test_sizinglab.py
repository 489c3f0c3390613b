"""SizingLab importer: the shared CSVs become a valid catalog the optimizer can use."""

from __future__ import annotations

import numpy as np
import pytest

from optimizer.catalogs.catalog import load_catalog
from optimizer.catalogs.sizinglab import (
    PROP_MASS_COEF_G,
    PROP_MASS_EXPONENT,
    import_sizinglab,
    import_to_folder,
    motor_inertia_kgm2,
)
from optimizer.errors import CatalogError
from optimizer.solve.objectives import single
from optimizer.solve.selection import Requirements, optimize
from tests.conftest import SIZINGLAB


@pytest.fixture
def sizinglab(shared_data):
    folder = SIZINGLAB
    return folder


def test_import_sizes_and_static_coefficients(sizinglab) -> None:
    catalog = import_sizinglab(sizinglab)
    props, motors, batteries = catalog.propellers, catalog.motors, catalog.batteries
    assert len(props) == 13  # distinct (pitch ratio, diameter) of the APC MR family
    assert len(motors) == 204
    assert 131 <= len(batteries) <= 131 + 187
    assert len(set(catalog.motor_ids)) == 204 and len(set(catalog.battery_ids)) == len(batteries)
    p10 = props[props["id"] == "APC-10x4.5MR"].iloc[0]
    # mean of the nine static rows (J = 0) of BETA 0.45, 10 in in Propeller_Data.csv
    assert p10["ct"] == pytest.approx(0.11284, abs=2e-5)
    assert p10["cp"] == pytest.approx(0.04409, abs=2e-5)
    assert p10["diameter_m"] == pytest.approx(0.254)
    assert p10["mass_kg"] * 1000 == pytest.approx(PROP_MASS_COEF_G * 10**PROP_MASS_EXPONENT, 1e-3)
    assert np.all(batteries["price"] > 0) and np.all(motors["price"] > 0)


def test_assumed_motor_inertia_matches_table_e5_scale() -> None:
    # the 111 g 4108 motor of Table E.5: hollow rotor gives ~6.5e-6 kg m^2
    assert 4e-6 < float(motor_inertia_kgm2(np.array([111.0]))[0]) < 1.2e-5


def test_optimize_over_sizinglab_milp_equals_enumeration(sizinglab) -> None:
    catalog = import_sizinglab(sizinglab)
    req = Requirements(payload_kg=1.0, min_flight_time_min=10.0)
    for objective in ("flight-time", "price"):
        a = optimize(catalog, single(objective), (4, 6), req, "milp")
        b = optimize(catalog, single(objective), (4, 6), req, "exact")
        assert [(d.propeller, d.motor, d.battery) for d in a.designs] == [
            (d.propeller, d.motor, d.battery) for d in b.designs
        ]
        assert a.best is not None and a.best.metrics["flight_time_min"] >= 10.0


def test_write_folder_round_trip(sizinglab, tmp_path) -> None:
    out = import_to_folder(sizinglab, tmp_path / "sl")
    again = load_catalog(out)
    assert again.motor_ids == import_sizinglab(sizinglab).motor_ids
    # real parts: the imported catalog draws the motors' electric power (winding loss)
    assert again.constants.current_model == "drive"
    assert again.constants == import_sizinglab(sizinglab).constants
    with pytest.raises(CatalogError, match="already exists"):
        import_to_folder(sizinglab, out)


def test_bad_folder_and_bad_file(tmp_path, sizinglab) -> None:
    with pytest.raises(CatalogError, match="not found"):
        import_sizinglab(tmp_path / "missing")
    for name in ("Propeller_Data.csv", "Batteries_Data.csv", "Batteries_Data_2.csv"):
        (tmp_path / name).write_bytes((sizinglab / name).read_bytes())
    text = (sizinglab / "Motors_Data.csv").read_text(encoding="utf-8", errors="replace")
    lines = text.splitlines()
    cols = lines[1].split(";")
    cols[5] = "n/a"  # R_ohm of the first motor
    lines[1] = ";".join(cols)
    (tmp_path / "Motors_Data.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
    with pytest.raises(CatalogError, match=r"Motors_Data.csv: line 2, column R_ohm"):
        import_sizinglab(tmp_path)


def _tiny_sizinglab(folder, *, prop=None, motor=None, battery=None):
    """A two-row-per-file SizingLab folder; ``prop``/``motor``/``battery`` = (column, value)
    replaced in the second data row (line 3)."""
    files = {
        "Propeller_Data.csv": ("BETA;J_adv-ratio;Ct;Cp;DIAMETER_IN",
                               ["0.45;0;0.11;0.043;10", "0.45;0;0.12;0.05;12"], prop),
        "Motors_Data.csv": ("TYPE;Model;Kv_rpm_v;Io_A;R_ohm;Mass_g;Imax_A;Voltage;Tnom_Nm",
                            ["AXI;A1;1525;0.4;0.39;18.5;7;7.4;0.032",
                             "AXI;A2;900;0.5;0.1;60;20;11.1;0.2"], motor),
        "Batteries_Data.csv": ("TYPE;Voltage_V;Capacity_mAh;Discharge_Rate_C;Weight_g;"
                               "Max_Burst_Discharge_Rate_C",
                               ["T;11.1;1300;45;119;90", "T;11.1;2200;45;180;90"], battery),
        "Batteries_Data_2.csv": ("Brand;Voltage_V;Capacity_mAh;Discharge_Rate_C;Weight_g;"
                                 "Max_Burst_Discharge_Rate_C",
                                 ["U;14.8;1300;75;150;150", "U;14.8;5000;25;500;50"], None),
    }
    folder.mkdir()
    for name, (header, rows, change) in files.items():
        if change is not None:
            cols = header.split(";")
            cells = rows[1].split(";")
            cells[cols.index(change[0])] = change[1]
            rows = [rows[0], ";".join(cells)]
        (folder / name).write_text("\n".join([header, *rows]) + "\n")
    return folder


@pytest.mark.parametrize(("kind", "file", "column"), [
    ("motor", "Motors_Data.csv", "Mass_g"), ("motor", "Motors_Data.csv", "R_ohm"),
    ("motor", "Motors_Data.csv", "Kv_rpm_v"), ("battery", "Batteries_Data.csv", "Weight_g"),
    ("battery", "Batteries_Data.csv", "Capacity_mAh"), ("prop", "Propeller_Data.csv", "Ct"),
    ("prop", "Propeller_Data.csv", "DIAMETER_IN"),
])
@pytest.mark.parametrize("value", ["0", "-1.5"])
def test_parts_without_mass_capacity_kv_diameter_or_resistance(tmp_path, kind, file, column,
                                                               value) -> None:
    good = _tiny_sizinglab(tmp_path / "good")
    assert len(import_sizinglab(good).motors) == 2  # the folder itself imports
    folder = _tiny_sizinglab(tmp_path / "bad", **{kind: (column, value)})
    with pytest.raises(CatalogError, match=rf"^{folder / file}: line 3, column {column}: "
                                           rf"expected a number > 0.*, got {value}$"):
        import_sizinglab(folder)
    with pytest.raises(CatalogError):
        import_to_folder(folder, tmp_path / "out")
    assert not (tmp_path / "out").exists()
