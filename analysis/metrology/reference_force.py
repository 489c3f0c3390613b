"""The force a dead weight puts on a cell: conventional mass, air buoyancy and local gravity.

A "gram" calibration converted with g_n is off by up to 0.3 % where local g differs
(9.780 m/s^2 at the equator, 9.832 at the poles), and ignoring buoyancy by 1.5e-4; both are
systematic, so they go into the scale's budget, not into the fit's scatter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from analysis.metrology.gum import rectangular

__all__ = ["G_STANDARD", "OIML_MPE_MG", "Gravity", "conventional_weight_force",
           "local_gravity", "mass_uncertainty_kg"]

G_STANDARD = 9.80665  # m/s^2, defined (not a local value)
RHO_AIR_CONVENTIONAL = 1.2  # kg/m^3 (OIML D 28)
RHO_MASS_CONVENTIONAL = 8000.0  # kg/m^3

#: OIML R 111 maximum permissible errors, mg, by class and nominal mass in grams.
OIML_MPE_MG: dict[str, dict[float, float]] = {
    "E2": {10: 0.06, 20: 0.08, 50: 0.10, 100: 0.16, 200: 0.3, 500: 0.8, 1000: 1.6, 2000: 3.0},
    "F1": {10: 0.20, 20: 0.25, 50: 0.3, 100: 0.5, 200: 1.0, 500: 2.5, 1000: 5.0, 2000: 10},
    "F2": {10: 0.6, 20: 0.8, 50: 1.0, 100: 1.6, 200: 3.0, 500: 8.0, 1000: 16, 2000: 30},
    "M1": {10: 2.0, 20: 2.5, 50: 3.0, 100: 5.0, 200: 10, 500: 25, 1000: 50, 2000: 100},
    "M2": {10: 6.0, 20: 8.0, 50: 10, 100: 16, 200: 30, 500: 80, 1000: 160, 2000: 300},
}


@dataclass(frozen=True)
class Gravity:
    """Local g with its standard uncertainty and where it came from."""

    g: float
    u: float
    source: str


def local_gravity(latitude_deg: float | None = None, height_m: float = 0.0,
                  g_m_s2: float | None = None) -> Gravity:
    """Local g: measured (``g_m_s2``, u 1e-5 relative, rectangular), from latitude and height
    by the WELMEC formula (normal gravity: +-1e-4 relative), or g_n where nothing is known
    (+-0.27 %: the spread of g over the Earth's surface)."""
    if g_m_s2 is not None:
        return Gravity(g_m_s2, rectangular(1e-5 * g_m_s2), "given")
    if latitude_deg is not None:
        phi = math.radians(latitude_deg)
        g = (9.780318 * (1 + 0.0053024 * math.sin(phi) ** 2
                         - 0.0000058 * math.sin(2 * phi) ** 2) - 0.000003085 * height_m)
        return Gravity(g, rectangular(1e-4 * g),
                       f"WELMEC formula, latitude {latitude_deg:g} deg, height {height_m:g} m")
    return Gravity(G_STANDARD, rectangular(0.0027 * G_STANDARD),
                   "standard gravity (no latitude given: +-0.27 %)")


def mass_uncertainty_kg(nominal_kg: float, weight_class: str) -> float:
    """Standard uncertainty of a weight of an OIML R 111 class: its MPE as a rectangular
    half-width. A nominal between the table's values takes the next larger one's MPE (a
    stack of weights is never better than its largest piece)."""
    table = OIML_MPE_MG[weight_class]
    grams = nominal_kg * 1e3
    if grams <= 0:
        return 0.0
    larger = [n for n in sorted(table) if n >= grams - 1e-9]
    if not larger:
        mpe_mg = table[max(table)] * grams / max(table)  # proportional beyond the table
    else:
        mpe_mg = table[larger[0]]
    return rectangular(mpe_mg * 1e-6)


def conventional_weight_force(mass_kg: float, g: float, rho_air: float = RHO_AIR_CONVENTIONAL,
                              rho_mass: float = RHO_MASS_CONVENTIONAL) -> float:
    """F = m_c g (1 - rho_0/rho_c)(1 - rho_a/rho) / (1 - rho_0/rho): the force of a weight of
    conventional mass m_c in air of density rho_a (OIML D 28); m_c g (1 - 1.5e-4) at rho_a =
    1.2 kg/m^3 whatever the material."""
    r0, rc = RHO_AIR_CONVENTIONAL, RHO_MASS_CONVENTIONAL
    return mass_kg * g * (1 - r0 / rc) * (1 - rho_air / rho_mass) / (1 - r0 / rho_mass)
