"""A one-design catalog from datasheet numbers typed by the user ("my motor, my prop, my pack").

The parts go through ``Catalog.from_frames`` (the same validation as a catalog folder),
so a bad value is reported like a bad catalog cell. Values a datasheet often lacks:
propeller mass from the SizingLab power law (``optimizer.catalogs.sizinglab``), prices 0, and
limits not given are :data:`NO_LIMIT` (reported as "not given", never violated).
"""

from __future__ import annotations

import math
from typing import Any

import pandas as pd

from optimizer.catalogs.catalog import MAX_VALUE, Catalog
from optimizer.catalogs.model_constants import ModelConstants
from optimizer.catalogs.sizinglab import PROP_MASS_COEF_G, PROP_MASS_EXPONENT
from optimizer.errors import CatalogError, RequestError

#: Stand-in for a limit the user did not give (A, W): large, finite, never binding.
NO_LIMIT = 1e9

#: (part, catalog column, command-line flag, required)
FIELDS: tuple[tuple[str, str, str, bool], ...] = (
    ("propeller", "diameter_m", "--prop-diameter-m", True),
    ("propeller", "ct", "--prop-ct", True),
    ("propeller", "cp", "--prop-cp", True),
    ("propeller", "mass_g", "--prop-mass-g", False),
    ("propeller", "pitch_in", "--prop-pitch-in", False),
    ("motor", "kv_rpm_per_v", "--motor-kv", True),
    ("motor", "resistance_ohm", "--motor-resistance", True),
    ("motor", "mass_g", "--motor-mass-g", True),
    ("motor", "no_load_current_a", "--motor-io", False),
    ("motor", "max_current_a", "--motor-max-current", False),
    ("motor", "max_power_w", "--motor-max-power", False),
    ("battery", "cells", "--battery-cells", True),
    ("battery", "capacity_mah", "--battery-mah", True),
    ("battery", "mass_g", "--battery-mass-g", True),
    ("battery", "c_rating", "--battery-c", False),
    ("battery", "burst_c_rating", "--battery-burst-c", False),
    ("battery", "resistance_mohm", "--battery-resistance-mohm", False),
)


def flag_dest(flag: str) -> str:
    """argparse's attribute name for a flag."""
    return flag.lstrip("-").replace("-", "_")


def given(values: dict[str, Any]) -> bool:
    """Whether any free-form flag has a value."""
    return any(values.get(flag_dest(f)) is not None for _, _, f, _ in FIELDS)


def freeform_catalog(values: dict[str, Any], constants: ModelConstants | None = None) -> Catalog:
    """The catalog of one propeller, motor and battery (ids ``prop``, ``motor``, ``battery``)."""
    missing = [f for _, _, f, req in FIELDS if req and values.get(flag_dest(f)) is None]
    if missing:
        raise RequestError(f"free-form design: missing {', '.join(missing)}")
    for _, _, flag, _ in FIELDS:  # NaN is no "not given": the catalog reader would read it
        value = values.get(flag_dest(flag))  # as an empty cell and drop an optional part
        if value is not None and not math.isfinite(float(value)):
            raise RequestError(f"{flag}: expected a finite number, got {float(value):g} "
                               "(leave the option out for no value)")
    rows: dict[str, dict[str, Any]] = {
        "propeller": {"id": "prop", "name": "free-form propeller", "price": 0.0},
        "motor": {"id": "motor", "name": "free-form motor", "price": 0.0,
                  "max_current_a": NO_LIMIT, "max_power_w": NO_LIMIT},
        "battery": {"id": "battery", "name": "free-form battery", "price": 0.0,
                    "max_current_a": NO_LIMIT},
    }
    for part, column, flag, _ in FIELDS:
        value = values.get(flag_dest(flag))
        if value is not None:
            if not math.isfinite(float(value)):  # a catalog reads nan as an empty cell
                raise RequestError(f"{flag}: expected a finite number, got {value}")
            rows[part][column] = value
    prop = rows["propeller"]
    diameter = float(prop["diameter_m"])
    if not 0 < diameter <= MAX_VALUE:  # before the mass law takes its power (nan fails)
        raise RequestError(f"--prop-diameter-m: expected a number > 0 and <= {MAX_VALUE:g}, "
                           f"got {diameter:g}")
    if "mass_g" not in prop:
        d_in = float(prop["diameter_m"]) / 0.0254
        prop["mass_g"] = round(PROP_MASS_COEF_G * d_in**PROP_MASS_EXPONENT, 2)
    if "c_rating" in rows["battery"]:
        del rows["battery"]["max_current_a"]  # from capacity x C rating
    consts = constants or ModelConstants(battery_voltage="nominal")
    try:
        return Catalog.from_frames(
            pd.DataFrame([prop]),
            pd.DataFrame([rows["motor"]]),
            pd.DataFrame([rows["battery"]]),
            consts,
            source="<free-form>",
        )
    except CatalogError as exc:
        raise RequestError(_flag_message(str(exc))) from None


#: catalog columns a flag fills indirectly (the pack's current limit from --battery-c)
_DERIVED = (("battery", "max_current_a", "--battery-c", False),)

_FILES = {"propeller": "propellers.csv", "motor": "motors.csv", "battery": "batteries.csv"}


def _flag_message(message: str) -> str:
    """A catalog cell error ("<free-form>/motors.csv: data row 1, column 'kv_rpm_per_v':
    expected ...") said of the flag the value came from."""
    for part, column, flag, _ in (*FIELDS, *_DERIVED):
        if f"/{_FILES[part]}:" in message and f"column '{column}'" in message:
            return f"{flag}: {message.rsplit(': ', 1)[-1]}"
    return f"free-form design: {message}"
