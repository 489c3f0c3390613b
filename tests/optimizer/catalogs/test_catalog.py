"""Catalog loader: SI conversion and one exact message per kind of bad catalog."""

from __future__ import annotations

import math
import re
import shutil
from pathlib import Path

import pandas as pd
import pytest

from optimizer.catalogs.catalog import Catalog, load_catalog
from optimizer.catalogs.model_constants import ModelConstants
from optimizer.errors import CatalogError

ROOT = Path(__file__).resolve().parents[3]
THESIS_E = ROOT / "optimizer" / "data" / "catalogs" / "thesis-e"


@pytest.fixture
def cat_dir(tmp_path: Path) -> Path:
    target = tmp_path / "cat"
    shutil.copytree(THESIS_E, target)
    return target


def _set_cell(path: Path, row: int, column: str, value: str) -> None:
    """Replace one cell; ``row`` is the 1-based data row."""
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    cells = lines[row].split(",")
    cells[header.index(column)] = value
    lines[row] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")


def _drop_column(path: Path, column: str) -> None:
    frame = pd.read_csv(path, dtype=str, keep_default_na=False)
    frame.drop(columns=[column]).to_csv(path, index=False)


def _fails(folder: Path, message: str) -> None:
    with pytest.raises(CatalogError, match=f"^{re.escape(message)}$") as info:
        load_catalog(folder)
    assert info.value.exit_code == 2


def test_thesis_catalogs_load_and_convert_units():
    cat = load_catalog(THESIS_E)
    assert cat.propeller_ids == ("P1", "P2", "P3", "P4")
    assert cat.motor_ids == ("M1", "M2", "M3")
    assert cat.battery_ids == ("B1", "B2", "B3", "B4")
    assert cat.propellers["mass_kg"].tolist() == pytest.approx([0.012, 0.014, 0.018, 0.025])
    assert cat.propellers["pitch_m"].iloc[0] == pytest.approx(4.7 * 0.0254)
    assert cat.motors["kv_rad_s_per_v"].iloc[0] == pytest.approx(380 * 2 * math.pi / 60)
    assert cat.motors["mass_kg"].iloc[0] == pytest.approx(0.111)
    assert cat.batteries["capacity_ah"].tolist() == pytest.approx([4.0, 8.0, 16.0, 3.3])
    assert cat.constants.price_includes_propellers is False
    d = load_catalog(ROOT / "optimizer" / "data" / "catalogs" / "thesis-d")
    assert d.propeller_ids == tuple(f"P{i}" for i in range(1, 7))
    assert d.motor_ids == tuple(f"M{i}" for i in range(1, 6))
    # 2200 mAh x 25 C = 55 A (Paper D section 4)
    assert d.batteries["max_current_a"].iloc[0] == pytest.approx(55.0)


def test_extra_columns_are_kept(cat_dir):
    frame = pd.read_csv(cat_dir / "motors.csv", dtype=str)
    frame["supplier"] = "hobbyking"
    frame.to_csv(cat_dir / "motors.csv", index=False)
    assert load_catalog(cat_dir).motors["supplier"].tolist() == ["hobbyking"] * 3


def test_missing_column(cat_dir):
    _drop_column(cat_dir / "propellers.csv", "ct")
    _fails(
        cat_dir,
        f"{cat_dir / 'propellers.csv'}: missing column 'ct' "
        "(required: id, name, mass_g, diameter_m, ct, cp, price)",
    )


def test_non_numeric(cat_dir):
    _set_cell(cat_dir / "motors.csv", 2, "mass_g", "abc")
    _fails(
        cat_dir,
        f"{cat_dir / 'motors.csv'}: data row 2 (line 3), column 'mass_g': "
        "expected a number, got 'abc'",
    )


def test_negative(cat_dir):
    _set_cell(cat_dir / "batteries.csv", 4, "price", "-1")
    _fails(
        cat_dir,
        f"{cat_dir / 'batteries.csv'}: data row 4 (line 5), column 'price': "
        "expected a number >= 0, got -1",
    )


def test_zero_where_positive_needed(cat_dir):
    _set_cell(cat_dir / "propellers.csv", 1, "diameter_m", "0")
    _fails(
        cat_dir,
        f"{cat_dir / 'propellers.csv'}: data row 1 (line 2), column 'diameter_m': "
        "expected a number > 0, got 0",
    )


def test_nan(cat_dir):
    _set_cell(cat_dir / "propellers.csv", 3, "cp", "NaN")
    _fails(
        cat_dir,
        f"{cat_dir / 'propellers.csv'}: data row 3 (line 4), column 'cp': "
        "expected a finite number, got 'NaN'",
    )


def test_empty_value(cat_dir):
    _set_cell(cat_dir / "motors.csv", 1, "resistance_ohm", "")
    _fails(
        cat_dir,
        f"{cat_dir / 'motors.csv'}: data row 1 (line 2), column 'resistance_ohm': "
        "expected a number, got an empty value",
    )


def test_duplicate_id(cat_dir):
    _set_cell(cat_dir / "batteries.csv", 3, "id", "B1")
    _fails(
        cat_dir,
        f"{cat_dir / 'batteries.csv'}: data row 3 (line 4), column 'id': "
        "duplicate id 'B1' (first at data row 1)",
    )


def test_empty_file(cat_dir):
    (cat_dir / "motors.csv").write_text("")
    _fails(cat_dir, f"{cat_dir / 'motors.csv'}: file is empty (expected a header and data rows)")


def test_header_only(cat_dir):
    path = cat_dir / "propellers.csv"
    path.write_text(path.read_text().splitlines()[0] + "\n")
    _fails(cat_dir, f"{path}: no data rows")


def test_missing_file(cat_dir):
    (cat_dir / "batteries.csv").unlink()
    _fails(cat_dir, f"{cat_dir}: missing file batteries.csv")


def test_blank_lines_keep_line_numbers(cat_dir):
    path = cat_dir / "motors.csv"
    lines = path.read_text().splitlines()
    lines.insert(2, "")  # blank line 3; the second data row moves to line 4
    path.write_text("\n".join(lines) + "\n")
    _set_cell(path, 3, "price", "x")  # text line index 3 = data row 2
    _fails(
        cat_dir,
        f"{path}: data row 2 (line 4), column 'price': expected a number, got 'x'",
    )


def test_battery_needs_max_current_or_c_rating(cat_dir):
    _drop_column(cat_dir / "batteries.csv", "max_current_a")
    _fails(
        cat_dir,
        f"{cat_dir / 'batteries.csv'}: missing column 'max_current_a' or 'c_rating' "
        "(one is required)",
    )


def test_battery_row_with_neither(cat_dir):
    path = cat_dir / "batteries.csv"
    frame = pd.read_csv(path, dtype=str, keep_default_na=False)
    frame["c_rating"] = ["25", "25", "25", ""]
    frame.loc[3, "max_current_a"] = ""
    frame.to_csv(path, index=False)
    _fails(
        cat_dir,
        f"{path}: data row 4 (line 5), column 'max_current_a': "
        "expected 'max_current_a' or 'c_rating', both are empty",
    )


def test_c_rating_gives_max_current(cat_dir):
    path = cat_dir / "batteries.csv"
    frame = pd.read_csv(path, dtype=str, keep_default_na=False)
    frame = frame.drop(columns=["max_current_a"])
    frame["c_rating"] = "30"
    frame.to_csv(path, index=False)
    cat = load_catalog(cat_dir)
    assert cat.batteries["max_current_a"].tolist() == pytest.approx([120, 240, 480, 99])


def test_partial_rotor_geometry(cat_dir):
    _drop_column(cat_dir / "motors.csv", "rotor_wall_m")
    _fails(
        cat_dir,
        f"{cat_dir / 'motors.csv'}: rotor geometry needs all of rotor_diameter_m, "
        "rotor_length_m, rotor_wall_m, rotor_density_kg_m3; missing rotor_wall_m",
    )


def test_toml_unknown_key(cat_dir):
    with (cat_dir / "catalog.toml").open("a") as fh:
        fh.write("air_densty = 1.2\n")
    with pytest.raises(CatalogError, match=r"catalog.toml: unknown key 'air_densty' \(known keys"):
        load_catalog(cat_dir)


def test_toml_bad_value(cat_dir):
    (cat_dir / "catalog.toml").write_text('air_density_kg_m3 = "thick"\n')
    _fails(
        cat_dir,
        f"{cat_dir / 'catalog.toml'}: key 'air_density_kg_m3': expected a number, got 'thick'",
    )
    (cat_dir / "catalog.toml").write_text('battery_voltage = "full"\n')
    _fails(
        cat_dir,
        f"{cat_dir / 'catalog.toml'}: key 'battery_voltage': "
        "expected one of 'in_flight', 'nominal', got 'full'",
    )
    (cat_dir / "catalog.toml").write_text("gravity_m_s2 = -9.81\n")
    _fails(
        cat_dir, f"{cat_dir / 'catalog.toml'}: key 'gravity_m_s2': expected a number > 0, got -9.81"
    )


def test_toml_syntax_error(cat_dir):
    (cat_dir / "catalog.toml").write_text("air_density_kg_m3 = \n")
    with pytest.raises(CatalogError, match=r"catalog.toml: invalid TOML"):
        load_catalog(cat_dir)


def test_toml_optional(cat_dir):
    (cat_dir / "catalog.toml").unlink()
    assert load_catalog(cat_dir).constants == ModelConstants()


def test_from_frames_validates_the_same_way():
    cat = load_catalog(THESIS_E)
    props = pd.read_csv(THESIS_E / "propellers.csv")
    motors = pd.read_csv(THESIS_E / "motors.csv")
    batts = pd.read_csv(THESIS_E / "batteries.csv")
    built = Catalog.from_frames(props, motors, batts, cat.constants, source="mem")
    pd.testing.assert_frame_equal(built.propellers, cat.propellers)
    pd.testing.assert_frame_equal(built.batteries, cat.batteries)
    motors.loc[1, "kv_rpm_per_v"] = -5
    with pytest.raises(
        CatalogError,
        match=re.escape(
            "mem/motors.csv: data row 2, column 'kv_rpm_per_v': expected a number > 0, got -5"
        ),
    ):
        Catalog.from_frames(props, motors, batts, source="mem")
    with pytest.raises(CatalogError, match=r"mem/catalog.toml: unknown key 'rho'"):
        Catalog.from_frames(
            props, pd.read_csv(THESIS_E / "motors.csv"), batts, {"rho": 1.2}, source="mem"
        )


@pytest.mark.parametrize(("file", "column"), [
    ("batteries.csv", "mass_g"), ("batteries.csv", "capacity_mah"),
    ("motors.csv", "mass_g"), ("motors.csv", "kv_rpm_per_v"), ("motors.csv", "resistance_ohm"),
    ("propellers.csv", "mass_g"), ("propellers.csv", "diameter_m"),
])
@pytest.mark.parametrize("value", ["0", "-2"])
def test_part_without_mass_capacity_kv_diameter_or_resistance(cat_dir, file, column, value):
    """A 0 g battery was accepted and the optimizer promised an 85 min flight with it."""
    _set_cell(cat_dir / file, 2, column, value)
    _fails(cat_dir, f"{cat_dir / file}: data row 2 (line 3), column '{column}': "
                    f"expected a number > 0, got {value}")
