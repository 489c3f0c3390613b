"""Measured propeller coefficients against speed: APC static data, matched to a catalog.

The thesis takes C_t and C_p as constants (Table D.2). ``APC_STATIC-data-all-props.csv``
(SizingLab, Apache-2.0) holds APC's static thrust and torque from 1000 rpm up for 274
propellers. Its own ``Ct``/``Cp`` columns are rounded to two decimals (0.04 for Cp), so
the coefficients are recomputed here from thrust and torque, with APC's convention
(E.1)-(E.2): ``C_t = T / (rho n^2 D^4)``, ``C_p = 2 pi Q / (rho n^2 D^5)`` (P = 2 pi n Q),
rho = 1.225 kg/m^3. Thrust is given to 0.01 lbf and torque to 0.01 in lbf: rows below
``MIN_THRUST_LBF`` / ``MIN_TORQUE_IN_LBF`` (quantisation above 2 %) are dropped; below the
first row kept the coefficients are held at its value (np.interp clamps).

A catalog propeller matches a data propeller of the same diameter (within 0.01 in) and
pitch (within ``PITCH_TOL_IN``); among several, the APC family named in the catalog name
(``MR``, ``SF``, ``E`` ...) wins, then the closest pitch. Unmatched propellers keep their
constants; ``match_report`` lists both.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import pairwise
from pathlib import Path
from typing import Any

import numpy as np

from optimizer.catalogs.catalog import Catalog
from optimizer.catalogs.sizinglab import _read as read_sizinglab_table
from optimizer.model import physics

FILE = "APC_STATIC-data-all-props.csv"
RHO_APC = 1.225
LBF_TO_N = 4.4482216152605
IN_LBF_TO_NM = 0.1129848290276167
MIN_THRUST_LBF = 0.25
MIN_TORQUE_IN_LBF = 0.25
PITCH_TOL_IN = 0.06
#: common speed axis of the tables, rpm
RPM_STEP = 100.0

_COLS = ("COMP", "TYPE", "RPM", "DIAMETER(IN)", "PITCH(IN)", "BLADE(nb)", "THRUST(LBF)",
         "TORQUE(IN.LBF)")
#: the columns that name one data propeller
_KEYS = ("COMP", "TYPE", "DIAMETER(IN)", "PITCH(IN)", "BLADE(nb)")


@dataclass(frozen=True)
class PropCurve:
    """One data propeller: C_t, C_p against rpm (rows kept after the resolution filter)."""

    comp: int
    family: str
    diameter_in: float
    pitch_in: float
    blades: int
    rpm: np.ndarray
    ct: np.ndarray
    cp: np.ndarray

    @property
    def name(self) -> str:
        return f"APC {self.diameter_in:g}x{self.pitch_in:g}{self.family} ({self.blades} blades)"


def load_curves(folder: str | Path) -> list[PropCurve]:
    """All propellers of the APC static file in ``folder`` with their coefficient curves."""
    # the SizingLab reader: semicolons, needed columns, numbers checked (line and column)
    data = read_sizinglab_table(Path(folder) / FILE, _COLS)
    data = data.loc[data["THRUST(LBF)"] >= MIN_THRUST_LBF]
    data = data.loc[data["TORQUE(IN.LBF)"] >= MIN_TORQUE_IN_LBF]
    # one sort, then slices: a pandas group per propeller costs more than its numbers
    # (rows missing a key column name no propeller, as a groupby drops them)
    data = data.dropna(subset=list(_KEYS)).sort_values([*_KEYS, "RPM"], kind="stable")
    keys = [data[k].to_numpy(object) for k in _KEYS]
    rpm = data["RPM"].to_numpy(float)
    thrust_lbf = data["THRUST(LBF)"].to_numpy(float)
    torque_in_lbf = data["TORQUE(IN.LBF)"].to_numpy(float)
    out = []
    for start, stop in _runs(keys):
        comp, family, d_in, p_in, blades = (k[start] for k in keys)
        n = rpm[start:stop] / 60.0
        d = float(d_in) * 0.0254
        thrust = thrust_lbf[start:stop] * LBF_TO_N
        torque = torque_in_lbf[start:stop] * IN_LBF_TO_NM
        ct = physics.thrust_coefficient(thrust, RHO_APC, n, d)  # (E.1)
        cp = physics.power_coefficient(torque, RHO_APC, n, d)  # (E.2) with P = 2 pi n Q
        fam = "" if str(family) in ("NULL", "nan") else str(family)
        out.append(PropCurve(int(comp), fam, float(d_in), float(p_in), int(blades),
                             rpm[start:stop].copy(), ct, cp))
    return out


def _runs(keys: list[np.ndarray]) -> list[tuple[int, int]]:
    """(start, stop) of each run of equal keys in sorted columns (one run per propeller)."""
    size = keys[0].size
    if size == 0:
        return []
    change = np.zeros(size - 1, bool)
    for k in keys:
        change |= k[1:] != k[:-1]
    edges = [0, *(np.flatnonzero(change) + 1).tolist(), size]
    return list(pairwise(edges))


def _family(name: str) -> str | None:
    """APC family suffix in a catalog name such as 'APC 10x4.5MR' (None if absent)."""
    import re

    m = re.search(r"\d+(?:\.\d+)?x\d+(?:\.\d+)?([A-Z]+)", str(name))
    return m.group(1) if m else None


def match(catalog: Catalog, curves: list[PropCurve]) -> list[PropCurve | None]:
    """The data propeller of each catalog propeller (None: no match)."""
    out: list[PropCurve | None] = []
    props = catalog.propellers
    for _, row in props.iterrows():
        diameter: Any = row["diameter_m"]  # the row's cells, as the catalog holds them
        d_in = float(diameter) / 0.0254
        pitch: Any = row.get("pitch_m", np.nan)  # a number, NaN or None
        if pitch is None or not np.isfinite(pitch):
            out.append(None)
            continue
        p_in = float(pitch) / 0.0254
        cands = [c for c in curves if abs(c.diameter_in - d_in) <= 0.01
                 and abs(c.pitch_in - p_in) <= PITCH_TOL_IN and c.blades == 2]
        fam = _family(str(row["name"]))
        cands.sort(key=lambda c: (c.family != fam, abs(c.pitch_in - p_in), c.comp))
        out.append(cands[0] if cands else None)
    return out


@dataclass(frozen=True)
class CatalogCurves:
    """C_t, C_p tables on a common rpm axis for a catalog's propellers (grid axis 0)."""

    rpm: np.ndarray
    ct: np.ndarray  # (P, K)
    cp: np.ndarray  # (P, K)
    matched: tuple[PropCurve | None, ...]

    def coefficients(self, rpm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(C_t, C_p) at ``rpm``, an array whose axis 0 is the propeller (P, ...) or 1."""
        rpm = np.asarray(rpm, float)
        p = self.ct.shape[0]
        shape = np.broadcast_shapes(rpm.shape, (p,) + (1,) * max(rpm.ndim - 1, 0))
        r = np.broadcast_to(rpm, shape)
        prop = np.broadcast_to(np.arange(p).reshape((p,) + (1,) * (len(shape) - 1)), shape)
        pos = np.clip(r / RPM_STEP, 0, self.rpm.size - 1)
        lo = np.floor(pos).astype(int)
        hi = np.minimum(lo + 1, self.rpm.size - 1)
        w = pos - lo
        ct = self.ct[prop, lo] * (1 - w) + self.ct[prop, hi] * w
        cp = self.cp[prop, lo] * (1 - w) + self.cp[prop, hi] * w
        return ct, cp


def catalog_curves(catalog: Catalog, curves: list[PropCurve]) -> CatalogCurves:
    """Tables for every catalog propeller: the matched data, else its constants."""
    matched = match(catalog, curves)
    top = max([c.rpm.max() for c in matched if c is not None], default=RPM_STEP)
    axis = np.arange(0.0, top + RPM_STEP, RPM_STEP)
    ct_const = catalog.propellers["ct"].to_numpy(float)
    cp_const = catalog.propellers["cp"].to_numpy(float)
    ct = np.repeat(ct_const[:, None], axis.size, axis=1)
    cp = np.repeat(cp_const[:, None], axis.size, axis=1)
    for i, c in enumerate(matched):
        if c is not None:
            ct[i] = np.interp(axis, c.rpm, c.ct)
            cp[i] = np.interp(axis, c.rpm, c.cp)
    return CatalogCurves(axis, ct, cp, tuple(matched))


def match_report(catalog: Catalog, table: CatalogCurves) -> dict[str, Any]:
    """Which catalog propellers matched which data propeller, and which did not."""
    matches, misses = [], []
    for pid, name, c in zip(catalog.propeller_ids, catalog.propellers["name"], table.matched,
                            strict=True):
        if c is None:
            misses.append(pid)
        else:
            matches.append({"propeller": pid, "name": str(name), "data": c.name,
                            "rpm_range": [float(c.rpm.min()), float(c.rpm.max())]})
    return {"matched": matches, "missed": misses}


def compare_for_design(single: Catalog, record: dict[str, Any], curve: Any) -> dict[str, Any]:
    """evaluate --prop-data: hover and full throttle with measured vs constant C_t, C_p."""
    from optimizer.model.sheet import design_sheet

    table = catalog_curves(single, load_curves(data_folder()))
    report = match_report(single, table)
    if not report["matched"]:
        return {**report, "summary": f"no APC static data for propeller "
                f"{single.propeller_ids[0]} (diameter and pitch); constants used"}
    data = design_sheet(single, record, curve, coefficients=table.coefficients)
    const = {k: record[k] for k in ("max_thrust_n", "hover_throttle_pct", "efficiency_g_per_w",
                                   "hover_electric_power_w")}
    n = int(record["actuators"])
    from optimizer.model import operating_points as ops
    from optimizer.model.sheet import drive_of, pack_of

    weight = float(record["total_mass_kg"]) * single.constants.gravity_m_s2
    hover = ops.at_thrust(drive_of(single, table.coefficients), weight / n,
                           pack_of(single)["voltage_v"])
    rows = {
        "hover_rpm": (float(record["hover_rpm"]), float(np.ravel(hover.rpm)[0])),
        "propeller_power_w": (float(record["propeller_power_w"]),
                              float(np.ravel(hover.shaft_power_w)[0])),
        **{k: (float(const[k]), float(data[k])) for k in const},
        "battery_model_flight_time_min": (float(record["battery_model"]["flight_time_min"]),
                                          float(data["battery_model"]["flight_time_min"])),
    }
    diff = {k: {"constant": a, "data": b, "difference_pct": 100.0 * (b - a) / a if a else None}
            for k, (a, b) in rows.items()}
    m = report["matched"][0]
    p = diff["propeller_power_w"]["difference_pct"]
    return {**report, "comparison": diff,
            "summary": f"{m['data']}: hover {diff['hover_rpm']['data']:.0f} rpm "
            f"(constants {diff['hover_rpm']['constant']:.0f}), hover shaft power "
            f"{p:+.1f} % against the constant C_p"}


def data_folder() -> Path:
    """The SizingLab folder the package ships (``optimizer.catalogs.sizinglab.DEFAULT_FOLDER``)."""
    from optimizer.catalogs.sizinglab import DEFAULT_FOLDER

    return DEFAULT_FOLDER
