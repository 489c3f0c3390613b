"""Import the Apache-2.0 SizingLab catalogs (droneapp-legacy) into a ``Catalog``.

The source files (semicolon-separated, their own column names) lack some of
what the model needs; the values filled in are assumptions, documented in
docs/optimizer.md ("SizingLab import") and repeated here:

Propellers (``Propeller_Data.csv``, APC MR family): one propeller per
(BETA = pitch/diameter, DIAMETER_IN); ``ct``/``cp`` = mean of its static rows
(J = 0, several speeds), APC's convention T = Ct rho n^2 D^4, P = Cp rho n^3 D^5
as in (E.1)-(E.2); pitch = BETA x D. Not in the data:
  * mass: m = 0.0641 g x D_in^2.26, a power law fitted to the APC propellers of
    Table D.2 (8-14 in, 7.1-25 g; within 4 % of each);
  * price: 0.5 $ per inch of diameter (thesis-e: 4.7-7.8 $ for 10-14 in).
Motors (``Motors_Data.csv``): Kv, R, mass, no-load current ``Io_A`` (->
``no_load_current_a``, part of the winding current Q / K_t + I_0) as given.
  * max current: the continuous winding current, min(``Imax_A``, ``Tnom_Nm``
    x Kv + ``Io_A``), i.e. the current of the nominal (continuous) torque.
    Hover is continuous operation. For KDE rows this is ``Imax_A``, for
    Scorpion 0.98-1 of it, for AXI 0.55-0.94, for maxon rows 0.02-0.64
    (their ``Imax_A`` is far above the nominal current: 46.8 A against 2.4 A
    for the 3070 Kv EC 13 50 W).
Not in the data:
  * max power: the continuous mechanical power at the rated voltage,
    ``Tnom_Nm`` x Kv x ``Voltage`` (nominal torque at no-load speed; 9.2 W for
    the "EC 10, 8 Watt" maxon motor), compared with the propeller (shaft)
    power like the thesis' limit. Rated voltage x ``Imax_A`` would be 8 x too
    lenient for small high-Kv motors;
  * price: 15 $ + 0.15 $/g (thesis-e: 31.36 $ for 111 g);
  * rotor inertia: J_m = 0.15 m r^2, the motor taken as a cylinder of length =
    diameter at an effective density of 1500 kg/m^3 (gives 47 mm for the 111 g
    4108 motor of Table E.5) and 15 % of its mass in a thin rotor ring at
    radius r (8.6e-6 kg m^2 for that motor, the hollow rotor of Table E.5 gives
    6.5e-6).
Batteries (``Batteries_Data.csv`` and ``Batteries_Data_2.csv``, exact duplicates
dropped): cells = round(V / 3.7), capacity, mass, continuous C rating
(``Discharge_Rate_C``), nominal voltage as given. Not in the data:
  * price: 0.6 $/Wh (thesis-e: 25.5 $ for 44.4 Wh).
Burst C rating (``Max_Burst_Discharge_Rate_C``) -> ``burst_c_rating`` (battery model and
the ``c-rate`` rule, docs/sizing.md).
Constants: nominal battery voltage, propeller prices in the total (E.18), and a
thrust-to-weight requirement of 2 at full voltage (the raw lists include
motors that cannot lift anything with these propellers).
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import cast

import numpy as np
import pandas as pd

from optimizer.catalogs.catalog import Catalog, check_unique_header
from optimizer.catalogs.shipped_data import SIZINGLAB
from optimizer.errors import CatalogError

#: The Apache-2.0 copies shipped with the package (optimizer/data/sizinglab, see its SOURCE.md).
DEFAULT_FOLDER = SIZINGLAB

PROP_MASS_COEF_G = 0.0641
PROP_MASS_EXPONENT = 2.26
PROP_PRICE_PER_INCH = 0.5
MOTOR_PRICE_BASE = 15.0
MOTOR_PRICE_PER_G = 0.15
MOTOR_EFFECTIVE_DENSITY = 1500.0  # kg/m^3
MOTOR_ROTOR_FRACTION = 0.15
BATTERY_PRICE_PER_WH = 0.6
CELL_NOMINAL_V = 3.7

CONSTANTS = {
    "battery_voltage": "nominal",
    "price_includes_propellers": True,
    "min_thrust_to_weight": 2.0,
    # real parts: the battery delivers the motors' electric power (winding loss included)
    "current_model": "drive",
    "description": "SizingLab droneapp-legacy catalogs (Apache-2.0), imported with "
    "documented assumptions (docs/optimizer.md)",
}

_PROP_COLS = ("BETA", "J_adv-ratio", "Ct", "Cp", "DIAMETER_IN")
_MOTOR_COLS = (
    "TYPE",
    "Model",
    "Kv_rpm_v",
    "R_ohm",
    "Mass_g",
    "Imax_A",
    "Io_A",
    "Voltage",
    "Tnom_Nm",
)
_BATT_COLS = ("Voltage_V", "Capacity_mAh", "Discharge_Rate_C", "Weight_g")
#: burst C rating, the limit of the battery model's full-throttle check (docs/sizing.md)
_BURST = "Max_Burst_Discharge_Rate_C"


def _read(path: Path, needed: tuple[str, ...], positive: tuple[str, ...] = ()) -> pd.DataFrame:
    """The table with ``needed`` columns as numbers; ``positive`` ones must be > 0 (a part
    without mass or resistance is a hole in the list, not a free lunch for the optimizer)."""
    if not path.is_file():
        raise CatalogError(f"{path}: SizingLab file not found")
    try:
        frame = pd.read_csv(path, sep=";", dtype=str, keep_default_na=False)  # as written
        check_unique_header(path, sep=";")
    except (pd.errors.ParserError, UnicodeDecodeError, pd.errors.EmptyDataError) as exc:
        raise CatalogError(f"{path}: not a semicolon-separated table ({exc})") from None
    frame.columns = [str(c).strip() for c in frame.columns]
    missing = [c for c in needed if c not in frame.columns]
    if missing:
        raise CatalogError(f"{path}: missing column(s) {', '.join(missing)}")
    frame.attrs["as_written"] = frame[list(needed)].copy()  # for messages
    for col in needed:
        if col in ("TYPE", "Model", "Brand"):
            continue
        column: pd.Series = frame.loc[:, col]
        values = cast(pd.Series, pd.to_numeric(column, errors="coerce"))  # a column's numbers
        bad = np.flatnonzero(values.isna().to_numpy())
        if bad.size:
            row = int(bad[0]) + 2  # 1-based, after the header line
            got = frame[col].iloc[bad[0]]
            raise CatalogError(f"{path}: line {row}, column {col}: expected a number, got {got!r}")
        if col in positive:
            _check_positive(path, frame.assign(**{col: values}), col, column)
        frame[col] = values
    return frame


def _check_positive(path: Path, frame: pd.DataFrame, col: str, raw: pd.Series,
                    rows: str = "") -> None:
    """Refuse the first value <= 0 of ``col``, naming its line (the frame keeps the file's
    row index) and the value as written in the file."""
    bad = frame.index[(frame[col] <= 0).to_numpy()]
    if len(bad):
        raise CatalogError(f"{path}: line {int(bad[0]) + 2}, column {col}: expected a number "
                           f"> 0{rows}, got {str(raw.loc[bad[0]]).strip()}")


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9.]+", "-", str(text).strip()).strip("-")


def _unique(ids: list[str]) -> list[str]:
    seen: dict[str, int] = {}
    out = []
    for i in ids:
        seen[i] = seen.get(i, 0) + 1
        out.append(i if seen[i] == 1 else f"{i}#{seen[i]}")
    return out


def propellers_frame(folder: Path) -> pd.DataFrame:
    """APC MR propellers with static Ct/Cp (catalog columns, datasheet units)."""
    data = _read(folder / "Propeller_Data.csv", _PROP_COLS, ("DIAMETER_IN", "BETA"))
    static = data.loc[data["J_adv-ratio"] == 0]
    if static.empty:
        raise CatalogError(f"{folder / 'Propeller_Data.csv'}: no static rows (J_adv-ratio = 0)")
    for col in ("Ct", "Cp"):  # other advance ratios may reach zero thrust, a static row not
        _check_positive(folder / "Propeller_Data.csv", static, col,
                        data.attrs["as_written"][col], " in a static row (J_adv-ratio = 0)")
    means: pd.DataFrame = static.groupby(["DIAMETER_IN", "BETA"], sort=True)[["Ct", "Cp"]].mean()
    grouped = means.reset_index()
    d_in = grouped["DIAMETER_IN"].to_numpy(float)
    pitch_in = grouped["BETA"].to_numpy(float) * d_in
    names = [f"APC {d:g}x{p:.1f}MR" for d, p in zip(d_in, pitch_in, strict=True)]
    return pd.DataFrame(
        {
            "id": _unique([_slug(n) for n in names]),
            "name": names,
            "mass_g": np.round(PROP_MASS_COEF_G * d_in**PROP_MASS_EXPONENT, 2),
            "diameter_m": d_in * 0.0254,
            "ct": grouped["Ct"].to_numpy(float),
            "cp": grouped["Cp"].to_numpy(float),
            "price": np.round(PROP_PRICE_PER_INCH * d_in, 2),
            "pitch_in": np.round(pitch_in, 2),
        }
    )


def motor_inertia_kgm2(mass_g: np.ndarray) -> np.ndarray:
    """Assumed rotor inertia from the motor mass (see module doc)."""
    mass = np.asarray(mass_g, float) / 1000.0
    diameter = (4.0 * mass / (math.pi * MOTOR_EFFECTIVE_DENSITY)) ** (1.0 / 3.0)
    return MOTOR_ROTOR_FRACTION * mass * (diameter / 2.0) ** 2


def motors_frame(folder: Path) -> pd.DataFrame:
    data = _read(folder / "Motors_Data.csv", _MOTOR_COLS, ("Kv_rpm_v", "R_ohm", "Mass_g"))
    mass = data["Mass_g"].to_numpy(float)
    kv_rad = data["Kv_rpm_v"].to_numpy(float) * (2.0 * math.pi / 60.0)
    no_load = data["Io_A"].to_numpy(float)
    # continuous winding current: nominal torque / K_t + I_0, K_t = 1 / K_v (E.5)-(E.7)
    continuous = data["Tnom_Nm"].to_numpy(float) * kv_rad + no_load
    return pd.DataFrame(
        {
            "id": _unique([_slug(m) for m in data["Model"]]),
            "name": data["Model"].astype(str).str.strip(),
            "kv_rpm_per_v": data["Kv_rpm_v"].to_numpy(float),
            "resistance_ohm": data["R_ohm"].to_numpy(float),
            "mass_g": mass,
            "max_current_a": np.round(np.minimum(data["Imax_A"].to_numpy(float), continuous), 3),
            "no_load_current_a": no_load,
            "max_power_w": np.round(
                data["Tnom_Nm"].to_numpy(float)
                * data["Kv_rpm_v"].to_numpy(float)
                * (2.0 * math.pi / 60.0)
                * data["Voltage"].to_numpy(float),
                2,
            ),
            "price": np.round(MOTOR_PRICE_BASE + MOTOR_PRICE_PER_G * mass, 2),
            "inertia_kgm2": motor_inertia_kgm2(mass),
        }
    )


def batteries_frame(folder: Path) -> pd.DataFrame:
    parts = []
    for name, brand in (("Batteries_Data.csv", "TYPE"), ("Batteries_Data_2.csv", "Brand")):
        data = _read(folder / name, (brand, *_BATT_COLS, _BURST),
                     ("Voltage_V", "Capacity_mAh", "Weight_g"))
        parts.append(
            pd.DataFrame(
                {
                    "brand": data[brand].astype(str).str.strip(),
                    "voltage": data["Voltage_V"],
                    "capacity_mah": data["Capacity_mAh"],
                    "c_rating": data["Discharge_Rate_C"],
                    "mass_g": data["Weight_g"],
                    "burst_c_rating": data[_BURST],
                }
            )
        )
    same = ["brand", "voltage", "capacity_mah", "c_rating", "mass_g"]
    all_packs = pd.concat(parts, ignore_index=True).drop_duplicates(subset=same)
    all_packs = all_packs.reset_index(drop=True)
    cells = np.maximum(1, np.round(all_packs["voltage"].to_numpy(float) / CELL_NOMINAL_V))
    energy_wh = all_packs["capacity_mah"].to_numpy(float) / 1000.0 * all_packs["voltage"]
    names = [
        f"{b} {int(c)}S {cap:g} mAh {cr:g}C"
        for b, c, cap, cr in zip(
            all_packs["brand"], cells, all_packs["capacity_mah"], all_packs["c_rating"], strict=True
        )
    ]
    return pd.DataFrame(
        {
            "id": _unique([_slug(n) for n in names]),
            "name": names,
            "mass_g": all_packs["mass_g"].to_numpy(float),
            "capacity_mah": all_packs["capacity_mah"].to_numpy(float),
            "cells": cells.astype(int),
            "price": np.round(BATTERY_PRICE_PER_WH * energy_wh, 2),
            "c_rating": all_packs["c_rating"].to_numpy(float),
            "burst_c_rating": all_packs["burst_c_rating"].to_numpy(float),
            "nominal_voltage_v": all_packs["voltage"].to_numpy(float),
        }
    )


def import_sizinglab(folder: str | Path = DEFAULT_FOLDER) -> Catalog:
    """Read the SizingLab CSVs in ``folder`` into a validated ``Catalog`` (in memory)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise CatalogError(f"{folder}: SizingLab folder not found")
    return Catalog.from_frames(
        propellers_frame(folder),
        motors_frame(folder),
        batteries_frame(folder),
        CONSTANTS,
        source=f"sizinglab:{folder}",
    )


def write_catalog(catalog: Catalog, frames: tuple[pd.DataFrame, ...], out: str | Path) -> Path:
    """Write catalog CSVs + catalog.toml to ``out`` atomically (temp folder, then rename)."""
    import os
    import secrets
    import shutil

    out = Path(out)
    if out.exists():
        raise CatalogError(f"{out}: already exists; choose a new folder")
    out.parent.mkdir(parents=True, exist_ok=True)
    # a plain mkdir (not tempfile.mkdtemp, which makes it 0700): the catalog folder
    # gets the mode the user's umask gives, as a folder made by hand would
    tmp = out.parent / f".{out.name}-{secrets.token_hex(4)}"
    tmp.mkdir()
    try:
        for name, frame in zip(
            ("propellers.csv", "motors.csv", "batteries.csv"), frames, strict=True
        ):
            frame.to_csv(tmp / name, index=False)
        lines = ["# Imported from the SizingLab catalogs; assumptions in docs/optimizer.md"]
        for key, value in CONSTANTS.items():
            if isinstance(value, bool):
                lines.append(f"{key} = {'true' if value else 'false'}")
            elif isinstance(value, str):
                lines.append(f'{key} = "{value}"')
            else:
                lines.append(f"{key} = {value}")
        (tmp / "catalog.toml").write_text("\n".join(lines) + "\n")
        os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out


def import_to_folder(folder: str | Path, out: str | Path) -> Path:
    """Import and write a catalog folder (validated first, so nothing bad is written)."""
    folder = Path(folder)
    frames = (propellers_frame(folder), motors_frame(folder), batteries_frame(folder))
    catalog = Catalog.from_frames(*frames, CONSTANTS, source=f"sizinglab:{folder}")
    return write_catalog(catalog, frames, out)
