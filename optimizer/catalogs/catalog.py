"""Component catalogs: read, validate and convert datasheet tables to SI.

A catalog is a folder with ``propellers.csv``, ``motors.csv``, ``batteries.csv`` and an
optional ``catalog.toml`` (model constants, see ``optimizer.catalogs.model_constants``).
Datasheet units live only here: columns are converted by name (``mass_g`` -> ``mass_kg``,
``capacity_mah`` -> ``capacity_ah``, ``kv_rpm_per_v`` -> ``kv_rad_s_per_v``, ...). Every
bad value raises ``CatalogError`` naming the file, the data row (1-based, header excluded)
with its CSV line, and the column. The same validation runs for catalogs built in code
(``Catalog.from_frames``).
A physical size a part cannot lack (mass, capacity, K_V, diameter, winding resistance,
C_t, C_p) must be > 0: a 0 g battery made the optimizer promise an 85 min flight.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from optimizer.catalogs.model_constants import (
    ModelConstants,
    constants_from_mapping,
    load_constants,
)
from optimizer.errors import CatalogError

RPM_PER_V_TO_RAD_S_PER_V = 2.0 * math.pi / 60.0
#: The largest number a catalog cell may hold (the free-form "no limit" stand-in is 1e9;
#: beyond it no datasheet value lies, and 1e308 made the sheet divide by an underflowed 0).
MAX_VALUE = 1e9


@dataclass(frozen=True)
class Column:
    """One catalog column: its datasheet name, SI name, scale and value rule."""

    name: str
    si_name: str
    scale: float = 1.0
    rule: str = ">=0"  # ">=0", ">0", "text", "id"


def _col(name: str, si_name: str | None = None, scale: float = 1.0, rule: str = ">=0") -> Column:
    return Column(name, si_name or name, scale, rule)


ID = _col("id", rule="id")
NAME = _col("name", rule="text")

PROPELLER_REQUIRED = (
    ID,
    NAME,
    _col("mass_g", "mass_kg", 1e-3, ">0"),
    _col("diameter_m", rule=">0"),
    _col("ct", rule=">0"),
    _col("cp", rule=">0"),
    _col("price"),
)
PROPELLER_OPTIONAL = (
    _col("pitch_in", "pitch_m", 0.0254),
    _col("inertia_kgm2"),
)
MOTOR_REQUIRED = (
    ID,
    NAME,
    _col("kv_rpm_per_v", "kv_rad_s_per_v", RPM_PER_V_TO_RAD_S_PER_V, ">0"),
    _col("resistance_ohm", rule=">0"),
    _col("mass_g", "mass_kg", 1e-3, ">0"),
    _col("max_current_a"),
    _col("max_power_w"),
    _col("price"),
)
ROTOR_GEOMETRY = (
    _col("rotor_diameter_m", rule=">0"),
    _col("rotor_length_m", rule=">0"),
    _col("rotor_wall_m", rule=">0"),
    _col("rotor_density_kg_m3", rule=">0"),
)
MOTOR_OPTIONAL = (_col("inertia_kgm2"), _col("no_load_current_a"), *ROTOR_GEOMETRY)
BATTERY_REQUIRED = (
    ID,
    NAME,
    _col("mass_g", "mass_kg", 1e-3, ">0"),
    _col("capacity_mah", "capacity_ah", 1e-3, ">0"),
    _col("cells", rule=">0"),
    _col("price"),
)
BATTERY_CURRENT = (_col("max_current_a"), _col("c_rating", rule=">0"))
BATTERY_OPTIONAL = (
    *BATTERY_CURRENT,
    _col("nominal_voltage_v", rule=">0"),
    # battery model (optimizer.model.battery): burst C rating and measured pack resistance
    _col("burst_c_rating", rule=">0"),
    _col("resistance_mohm", "resistance_ohm", 1e-3),
)

FILES = ("propellers.csv", "motors.csv", "batteries.csv")


class _Table:
    """A raw table (all cells as text) plus where each data row came from."""

    def __init__(self, label: str, frame: pd.DataFrame, lines: list[int] | None) -> None:
        self.label = label
        self.frame = frame
        self.lines = lines

    def where(self, i: int, column: str) -> str:
        row = f"data row {i + 1}"
        if self.lines is not None:
            row += f" (line {self.lines[i]})"
        return f"{self.label}: {row}, column '{column}'"


def check_unique_header(path: Path, sep: str = ",") -> None:
    """Refuse a table whose header names a column twice: pandas renames the second to
    'X.1' and the reader would take one of them silently."""
    raw = pd.read_csv(path, sep=sep, dtype=str, keep_default_na=False, header=None, nrows=1,
                      skipinitialspace=True).iloc[0].tolist()
    names = [str(c).strip() for c in raw]
    twice = sorted({n for n in names if n and names.count(n) > 1})
    if twice:
        raise CatalogError(f"{path}: the header names column {twice[0]!r} twice; rename one")


def _read_csv(path: Path) -> _Table:
    label = str(path)
    if path.is_symlink() and not path.exists():
        raise CatalogError(f"{path}: a symbolic link that leads nowhere (a loop or a "
                           "missing target)")
    if path.exists() and not path.is_file():  # a folder, a FIFO (blocks), a device
        raise CatalogError(f"{path}: not a regular file")
    if not path.is_file():
        raise CatalogError(f"{path.parent}: missing file {path.name}")
    try:
        frame = pd.read_csv(
            path, dtype=str, keep_default_na=False, skip_blank_lines=False, skipinitialspace=True
        )
        check_unique_header(path)
    except pd.errors.EmptyDataError:
        raise CatalogError(f"{label}: file is empty (expected a header and data rows)") from None
    except (pd.errors.ParserError, UnicodeDecodeError) as exc:
        raise CatalogError(f"{label}: not a readable CSV file: {exc}") from None
    frame.columns = [str(c).strip() for c in frame.columns]
    blank = _blank_rows(frame)
    lines = [i + 2 for i in range(len(frame)) if not blank[i]]  # header is line 1
    frame = frame.loc[~blank].reset_index(drop=True)
    return _Table(label, frame, lines)


def _blank_rows(frame: pd.DataFrame) -> np.ndarray:
    """Rows whose every cell is empty or spaces (plain Python over the cells: a pandas
    ``map`` builds a whole new frame to answer this)."""
    return np.array([all(str(v).strip() == "" for v in row) for row in frame.to_numpy(object)],
                    bool)


def _parse_number(table: _Table, i: int, column: Column, raw: Any, *, allow_empty: bool) -> float:
    text = "" if raw is None else str(raw).strip()
    if isinstance(raw, float) and math.isnan(raw):
        text = ""
    if text == "":
        if allow_empty:
            return math.nan
        raise CatalogError(f"{table.where(i, column.name)}: expected a number, got an empty value")
    try:
        value = float(text)
    except ValueError:
        raise CatalogError(
            f"{table.where(i, column.name)}: expected a number, got {text!r}"
        ) from None
    if not math.isfinite(value):
        raise CatalogError(f"{table.where(i, column.name)}: expected a finite number, got {text!r}")
    if column.rule == ">0" and value <= 0:
        raise CatalogError(f"{table.where(i, column.name)}: expected a number > 0, got {text}")
    if abs(value) > MAX_VALUE:
        raise CatalogError(f"{table.where(i, column.name)}: expected a number <= {MAX_VALUE:g}, "
                           f"got {text} (larger values overflow the model)")
    if value < 0:
        raise CatalogError(f"{table.where(i, column.name)}: expected a number >= 0, got {text}")
    return value


def _convert(
    table: _Table, required: tuple[Column, ...], optional: tuple[Column, ...]
) -> pd.DataFrame:
    """Validate one table and return it in SI (extra columns kept as text)."""
    frame = table.frame
    if len(frame.columns) == 0:
        raise CatalogError(f"{table.label}: file is empty (expected a header and data rows)")
    missing = [c.name for c in required if c.name not in frame.columns]
    if missing:
        need = ", ".join(c.name for c in required)
        header = str(frame.columns[0])
        hint = ""
        if len(frame.columns) == 1 and any(sep in header for sep in ";\t|"):
            hint = "; the header is one field: columns must be separated by commas"
        raise CatalogError(
            f"{table.label}: missing column {', '.join(repr(m) for m in missing)} "
            f"(required: {need}){hint}"
        )
    if len(frame) == 0:
        raise CatalogError(f"{table.label}: no data rows")
    out: dict[str, Any] = {}
    known = set()
    for column, is_optional in [(c, False) for c in required] + [(c, True) for c in optional]:
        if column.name not in frame.columns:
            continue
        known.add(column.name)
        raw = frame[column.name].tolist()
        if column.rule in ("id", "text"):
            values = [
                "" if v is None or (isinstance(v, float) and math.isnan(v)) else str(v).strip()
                for v in raw
            ]
            if column.rule == "id":
                seen: dict[str, int] = {}
                for i, v in enumerate(values):
                    if v == "":
                        raise CatalogError(
                            f"{table.where(i, 'id')}: expected an id, got an empty value"
                        )
                    if v in seen:
                        raise CatalogError(
                            f"{table.where(i, 'id')}: duplicate id {v!r} "
                            f"(first at data row {seen[v] + 1})"
                        )
                    seen[v] = i
            out[column.si_name] = values
        else:
            nums = [
                _parse_number(table, i, column, v, allow_empty=is_optional)
                for i, v in enumerate(raw)
            ]
            out[column.si_name] = np.asarray(nums, dtype=float) * column.scale
    result = pd.DataFrame(out)
    for extra in frame.columns:
        if extra not in known and extra not in result.columns:
            result[extra] = frame[extra].to_numpy()
    return result


def _finish_motors(table: _Table, motors: pd.DataFrame) -> pd.DataFrame:
    present = [c.name for c in ROTOR_GEOMETRY if c.name in motors.columns]
    if present and len(present) < len(ROTOR_GEOMETRY):
        lacking = [c.name for c in ROTOR_GEOMETRY if c.name not in present]
        raise CatalogError(
            f"{table.label}: rotor geometry needs all of "
            f"{', '.join(c.name for c in ROTOR_GEOMETRY)}; missing {', '.join(lacking)}"
        )
    for c in ROTOR_GEOMETRY:
        if c.name not in motors.columns:
            motors[c.name] = np.nan
    for name in ("inertia_kgm2", "no_load_current_a"):
        if name not in motors.columns:
            motors[name] = np.nan
    geom = motors[[c.name for c in ROTOR_GEOMETRY]].to_numpy()
    partial = np.isnan(geom).any(axis=1) & ~np.isnan(geom).all(axis=1)
    if partial.any():
        i = int(np.flatnonzero(partial)[0])
        col = ROTOR_GEOMETRY[int(np.flatnonzero(np.isnan(geom[i]))[0])].name
        raise CatalogError(f"{table.where(i, col)}: rotor geometry is incomplete on this row")
    wall = motors["rotor_wall_m"].to_numpy()
    radius = motors["rotor_diameter_m"].to_numpy() / 2
    bad = wall > radius
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise CatalogError(
            f"{table.where(i, 'rotor_wall_m')}: expected a wall <= rotor radius "
            f"{radius[i]:g} m, got {wall[i]:g}"
        )
    return motors


def _finish_batteries(table: _Table, batteries: pd.DataFrame) -> pd.DataFrame:
    if not any(c.name in batteries.columns for c in BATTERY_CURRENT):
        raise CatalogError(
            f"{table.label}: missing column 'max_current_a' or 'c_rating' (one is required)"
        )
    for name in ("max_current_a", "c_rating", "nominal_voltage_v", "burst_c_rating",
                 "resistance_ohm"):
        if name not in batteries.columns:
            batteries[name] = np.nan
    current = batteries["max_current_a"].to_numpy()
    from_rating = batteries["c_rating"].to_numpy() * batteries["capacity_ah"].to_numpy()
    neither = np.isnan(current) & np.isnan(from_rating)
    if neither.any():
        i = int(np.flatnonzero(neither)[0])
        raise CatalogError(
            f"{table.where(i, 'max_current_a')}: expected 'max_current_a' or 'c_rating', "
            "both are empty"
        )
    # Max current = capacity [Ah] x C-rating [1/h] (Paper D section 4) when not given.
    batteries["max_current_a"] = np.where(np.isnan(current), from_rating, current)
    cells = batteries["cells"].to_numpy()
    bad = cells != np.round(cells)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise CatalogError(f"{table.where(i, 'cells')}: expected a whole number, got {cells[i]:g}")
    return batteries


def _finish_propellers(propellers: pd.DataFrame) -> pd.DataFrame:
    for name in ("pitch_m", "inertia_kgm2"):
        if name not in propellers.columns:
            propellers[name] = np.nan
    return propellers


@dataclass(frozen=True)
class Catalog:
    """Validated components in SI units plus the model constants.

    Frames: ``propellers`` (id, name, mass_kg, diameter_m, ct, cp, price, pitch_m,
    inertia_kgm2), ``motors`` (id, name, kv_rad_s_per_v, resistance_ohm, mass_kg,
    max_current_a, max_power_w, price, inertia_kgm2, no_load_current_a, rotor_*),
    ``batteries`` (id, name, mass_kg, capacity_ah, cells, price, max_current_a, c_rating,
    nominal_voltage_v).
    Optional values not given are NaN; extra columns are kept as text.
    """

    propellers: pd.DataFrame
    motors: pd.DataFrame
    batteries: pd.DataFrame
    constants: ModelConstants = field(default_factory=ModelConstants)
    source: str = "<memory>"

    @property
    def propeller_ids(self) -> tuple[str, ...]:
        return tuple(self.propellers["id"])

    @property
    def motor_ids(self) -> tuple[str, ...]:
        return tuple(self.motors["id"])

    @property
    def battery_ids(self) -> tuple[str, ...]:
        return tuple(self.batteries["id"])

    @classmethod
    def from_frames(
        cls,
        propellers: pd.DataFrame,
        motors: pd.DataFrame,
        batteries: pd.DataFrame,
        constants: ModelConstants | Mapping[str, Any] | None = None,
        *,
        source: str = "<memory>",
    ) -> Catalog:
        """Build a catalog from frames in datasheet units (CSV column names).

        Runs the same validation as ``load_catalog``; messages name ``source/<file>``
        and the 1-based data row.
        """
        tables = []
        for name, frame in zip(FILES, (propellers, motors, batteries), strict=True):
            if not isinstance(frame, pd.DataFrame):
                raise CatalogError(f"{source}/{name}: expected a pandas DataFrame")
            text = frame.reset_index(drop=True).copy()
            text.columns = [str(c).strip() for c in text.columns]
            tables.append(_Table(f"{source}/{name}", text, None))
        if constants is None:
            consts = ModelConstants()
        elif isinstance(constants, ModelConstants):
            consts = constants
        else:
            consts = constants_from_mapping(dict(constants), f"{source}/catalog.toml")
        props, mots, bats = tables
        return cls._build(props, mots, bats, consts, source)

    @classmethod
    def _build(
        cls, props: _Table, mots: _Table, bats: _Table, constants: ModelConstants, source: str
    ) -> Catalog:
        propellers = _finish_propellers(_convert(props, PROPELLER_REQUIRED, PROPELLER_OPTIONAL))
        motors = _finish_motors(mots, _convert(mots, MOTOR_REQUIRED, MOTOR_OPTIONAL))
        batteries = _finish_batteries(bats, _convert(bats, BATTERY_REQUIRED, BATTERY_OPTIONAL))
        return cls(propellers, motors, batteries, constants, source)


def load_catalog(path: str | Path) -> Catalog:
    """Load and validate a catalog folder (see docs/catalogs.md)."""
    folder = Path(path)
    if not folder.is_dir():
        raise CatalogError(
            f"{folder}: not a catalog folder (expected a directory with {', '.join(FILES)})"
        )
    if (folder / "robot.toml").is_file() and not (folder / FILES[0]).is_file():
        raise CatalogError(f"{folder}: the section 2.4.1 mobile-robot example (robot.toml), not "
                           "a multirotor catalog: it is solved by "
                           "optimizer.cases.robot.solve_robot (docs/thesis-formulation.md)")
    props, mots, bats = (_read_csv(folder / name) for name in FILES)
    constants = load_constants(folder / "catalog.toml")
    return Catalog._build(props, mots, bats, constants, str(folder))
