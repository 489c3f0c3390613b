"""What a sensor calibration applies: weights in ascending then descending order, held.

ISO 376's loading series scaled to a hobby stand: a zero, the weights upwards, back down
to a zero; each held ``hold_s`` after ``settle_s`` (an HX711 at 10 samples/s settles in
400 ms, a filtered bridge in well under a second). The weights' uncertainty is their OIML
R 111 class (MPE as a rectangular half-width) or a stated standard uncertainty.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from itertools import pairwise
from pathlib import Path
from typing import Any

from analysis.metrology.reference_force import OIML_MPE_MG, mass_uncertainty_kg
from bench.errors import RigError

__all__ = ["CELLS", "SEQUENCE", "CalibrationPlan", "parse_masses_g", "plan_from_file"]

#: the cells a calibration knows: the role of the device and the channel it corrects
CELLS = {"thrust": ("load_cell", "thrust_n"), "torque": ("load_cell", "torque_nm")}
#: the sequence a calibration run is indexed under: how a later run finds it
SEQUENCE = "calibrate-sensors"


@dataclass(frozen=True)
class CalibrationPlan:
    """One calibration series; ``steps()`` is the order the weights go on and off."""

    cell: str = "thrust"
    masses_kg: tuple[float, ...] = (0.0, 0.1, 0.2, 0.5, 1.0)
    weight_class: str | None = "F1"
    mass_u_kg: float | None = None  # a stated standard uncertainty instead of a class
    arm_m: float | None = None  # torque: where the weights hang, from the axis
    arm_u_m: float = 0.0
    settle_s: float = 1.0
    hold_s: float = 3.0
    series: int = 1  # up-and-down series, one after the other

    def __post_init__(self) -> None:
        if self.cell not in CELLS:
            raise RigError(f"cell {self.cell!r}: expected one of {', '.join(CELLS)}")
        m = self.masses_kg
        negative = [x for x in m if x < 0.0]
        if negative:
            raise RigError(f"masses: {negative[0] * 1e3:g} g is negative; a weight's mass "
                           "is 0 or more")
        if len(m) < 3 or m[0] != 0.0 or any(b <= a for a, b in pairwise(m)):
            raise RigError("masses: expected 0 and at least two more, ascending, e.g. "
                           "--masses-g 0,100,200,500,1000")
        if not all(math.isfinite(x) for x in m) or m[-1] > 100.0:
            raise RigError(f"masses: {m[-1] * 1e3:g} g is more than a bench's 100 kg")
        if self.mass_u_kg is None and self.weight_class not in OIML_MPE_MG:
            raise RigError(f"weight class {self.weight_class!r}: expected one of "
                           f"{', '.join(OIML_MPE_MG)} or a stated uncertainty")
        if self.mass_u_kg is not None and not 0 <= self.mass_u_kg < 1:
            raise RigError(f"mass uncertainty {self.mass_u_kg * 1e3:g} g: expected 0 <= u < 1 kg")
        if self.cell == "torque" and not (self.arm_m is not None and 0 < self.arm_m < 5):
            raise RigError("a torque cell is calibrated with weights on an arm: give its "
                           "length (--arm-m, 0 < m < 5)")
        for name in ("settle_s", "hold_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and 0 <= v <= 600) or (name == "hold_s" and v <= 0):
                raise RigError(f"{name.replace('_s', '')}: expected 0 < seconds <= 600, "
                               f"got {v:g}")
        if not 1 <= self.series <= 10:
            raise RigError(f"series: expected 1 to 10, got {self.series}")

    def steps(self) -> list[tuple[float, str]]:
        """(mass, direction) in order: up from the zero, down to the zero, per series."""
        up = [(m, "up") for m in self.masses_kg]
        down = [(m, "down") for m in self.masses_kg[-2::-1]]
        return (up + down) * self.series

    def mass_u(self, mass_kg: float) -> float:
        """Standard uncertainty of the weight on the cell (kg)."""
        if mass_kg == 0:
            return 0.0
        if self.mass_u_kg is not None:
            return self.mass_u_kg
        assert self.weight_class is not None
        return mass_uncertainty_kg(mass_kg, self.weight_class)

    def as_dict(self) -> dict[str, Any]:
        return {"cell": self.cell, "masses_kg": list(self.masses_kg),
                "weight_class": self.weight_class if self.mass_u_kg is None else None,
                "mass_u_kg": self.mass_u_kg, "arm_m": self.arm_m, "arm_u_m": self.arm_u_m,
                "settle_s": self.settle_s, "hold_s": self.hold_s, "series": self.series}


def parse_masses_g(text: str) -> tuple[float, ...]:
    """``0,100,200`` (grams) -> kilograms; one line naming the bad item."""
    out = []
    for item in text.split(","):
        try:
            out.append(float(item) * 1e-3)
        except ValueError:
            raise RigError(f"--masses-g: {item.strip()!r} is not a mass in grams") from None
    return tuple(out)


def plan_from_file(path: Path) -> CalibrationPlan:
    """A plan file (TOML, table ``[calibration]``), e.g.::

        [calibration]
        cell = "thrust"
        masses_g = [0, 100, 200, 500, 1000]
        weight_class = "M1"
        hold_s = 5
    """
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8")).get("calibration")
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise RigError(f"{path}: not a readable TOML plan ({exc})") from None
    if not isinstance(data, dict):
        raise RigError(f"{path}: no [calibration] table")
    known = {"cell", "masses_g", "weight_class", "mass_u_g", "arm_m", "arm_u_m", "settle_s",
             "hold_s", "series"}
    unknown = sorted(set(data) - known)
    if unknown:
        raise RigError(f"{path}: [calibration] {unknown[0]}: unknown key (known: "
                       f"{', '.join(sorted(known))})")
    try:
        kw: dict[str, Any] = {k: data[k] for k in ("cell", "weight_class", "arm_m", "arm_u_m",
                                                  "settle_s", "hold_s", "series") if k in data}
        if "masses_g" in data:
            kw["masses_kg"] = tuple(float(m) * 1e-3 for m in data["masses_g"])
        if "mass_u_g" in data:
            kw["mass_u_kg"] = float(data["mass_u_g"]) * 1e-3
        return CalibrationPlan(**kw)
    except (TypeError, ValueError) as exc:
        raise RigError(f"{path}: [calibration]: {exc}") from None
