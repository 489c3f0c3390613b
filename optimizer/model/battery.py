"""Battery under load: Shepherd-type discharge curve, internal resistance, flight time.

The thesis holds the pack voltage constant and uses the whole capacity (E.67-E.74);
section 3.2 names a discharge model as future work. This module is that model, opt-in
and reported beside the thesis' number:

* open-circuit cell voltage against the discharged fraction x = q / Q of the modified
  Shepherd model of Tremblay, Dessaint & Dekkiche (2007), "A generic battery model for
  the dynamic simulation of hybrid electric vehicles" (IEEE VPPC), eq. (2) without the
  filtered-current term (Shepherd 1965, J. Electrochem. Soc. 112(7)):
  ``E(x) = E0 - K / (1 - x) + A exp(-B x)``, with ``A``, ``B``, ``K``, ``E0`` from three
  datasheet points (fully charged, end of the exponential zone, end of the nominal zone);
* terminal pack voltage ``V = S E(x) - R_pack I`` (S cells in series; P parallel strings
  share the current, so ``R_pack = S R_cell / P``);
* a constant-power load P (hover): ``V I = P`` gives ``I = (S E - sqrt((S E)^2 - 4 R P))
  / (2 R)``, so the current rises as the voltage sags;
* flight time ``t = integral_0^x_end Q dx / I(x)``, ending where the terminal voltage
  falls to the cut-off voltage per cell (default 3.3 V) or the pack cannot deliver P.

Everything broadcasts: ``power_w`` and the pack parameters may be arrays of any
compatible shape (the whole design grid at once).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Nodes of the discharge integral on x in [0, X_MAX] (uniform; the error of the trapezoid
#: rule against the closed form is < 1e-4 relative, tests/optimizer/model/test_battery.py).
NODES = 600
X_MAX = 0.999


@dataclass(frozen=True)
class CellCurve:
    """Datasheet points of one LiPo cell's discharge curve at a low rate (per cell).

    Defaults: a typical LiPo cell, 4.20 V full, 3.95 V at the end of the exponential zone
    (10 % discharged), 3.70 V at the end of the nominal zone (80 % discharged); 3.3 V
    cut-off. ``resistance_ohm_ah``: internal resistance of a cell times its capacity
    (R_cell = r / Q_cell[Ah]; 15 mOhm Ah gives 3.75 mOhm for a 4 Ah cell), used when a
    pack has no measured resistance.
    """

    full_v: float = 4.20
    exp_v: float = 3.95
    exp_frac: float = 0.10
    nom_v: float = 3.70
    nom_frac: float = 0.80
    cutoff_v: float = 3.30
    resistance_ohm_ah: float = 0.015

    def __post_init__(self) -> None:
        if not (0 < self.exp_frac < self.nom_frac < 1):
            raise ValueError("cell curve: expected 0 < exp_frac < nom_frac < 1")
        if not (self.full_v >= self.exp_v >= self.nom_v > 0):
            raise ValueError("cell curve: expected full_v >= exp_v >= nom_v > 0")
        if not (0 < self.cutoff_v < self.full_v):
            raise ValueError("cell curve: expected 0 < cutoff_v < full_v")
        if self.resistance_ohm_ah < 0:
            raise ValueError("cell curve: expected resistance_ohm_ah >= 0")

    def parameters(self) -> tuple[float, float, float, float]:
        """(E0, K, A, B) of Tremblay et al. (2007) with x = q / Q as the charge variable.

        A = V_full - V_exp; B = 3 / x_exp; K = (V_full - V_nom + A (exp(-B x_nom) - 1))
        (1 - x_nom) / x_nom; E0 = V_full + K - A (so E(0) = V_full). The R i term of
        their E0 is left out: the points are read at a low rate and R I is applied
        separately.
        """
        a = self.full_v - self.exp_v
        b = 3.0 / self.exp_frac
        k = (self.full_v - self.nom_v + a * (np.exp(-b * self.nom_frac) - 1.0)) * (
            1.0 - self.nom_frac
        ) / self.nom_frac
        return self.full_v + k - a, k, a, b

    def open_circuit_v(self, x: np.ndarray | float) -> np.ndarray:
        """E(x) per cell at discharged fraction x (0 = full)."""
        e0, k, a, b = self.parameters()
        x = np.asarray(x, float)
        return e0 - k / (1.0 - x) + a * np.exp(-b * x)


DEFAULT_CELL = CellCurve()


def pack_resistance_ohm(
    cells: np.ndarray, capacity_ah: np.ndarray, curve: CellCurve = DEFAULT_CELL,
    given_ohm: np.ndarray | None = None,
) -> np.ndarray:
    """R_pack = S R_cell / P = S r / Q_pack (r = ``resistance_ohm_ah``), or the given value."""
    estimate = np.asarray(cells, float) * curve.resistance_ohm_ah / np.asarray(capacity_ah, float)
    if given_ohm is None:
        return estimate
    given = np.asarray(given_ohm, float)
    return np.where(np.isnan(given), estimate, given)


def load_current_a(power_w, open_circuit_v, resistance_ohm) -> np.ndarray | float:
    """Current drawn by a constant-power load from a source E with series resistance R.

    V I = P with V = E - R I: I = (E - sqrt(E^2 - 4 R P)) / (2 R) (the smaller root; the
    other is past the maximum-power point). NaN where E^2 < 4 R P: the pack cannot
    deliver P at all. R = 0 gives I = P / E.
    """
    p = np.asarray(power_w, float)
    e = np.asarray(open_circuit_v, float)
    r = np.asarray(resistance_ohm, float)
    disc = e * e - 4.0 * r * p
    root = np.sqrt(np.where(disc >= 0, disc, np.nan))
    # 2P / (E + sqrt(disc)) is the same root written to stay finite as R -> 0
    with np.errstate(divide="ignore", invalid="ignore"):
        i = 2.0 * p / (e + root)
    return np.where(i > 0, i, np.nan) if np.ndim(i) else (i if i > 0 else np.nan)


@dataclass(frozen=True)
class Discharge:
    """Result of :func:`discharge`: flight time and the pack at start and end."""

    time_min: np.ndarray
    used_fraction: np.ndarray
    start_voltage_v: np.ndarray
    start_current_a: np.ndarray
    end_voltage_v: np.ndarray
    end_current_a: np.ndarray


def discharge(
    power_w,
    cells,
    capacity_ah,
    resistance_ohm,
    curve: CellCurve = DEFAULT_CELL,
    nodes: int = NODES,
) -> Discharge:
    """Constant-power discharge to the cut-off: time, usable fraction, voltages, currents.

    All inputs broadcast; the integral runs on a trailing axis of ``nodes`` points in x.
    The end point between the last valid node and the first invalid one is found by
    linear interpolation of the terminal voltage's margin over the cut-off.
    """
    p = np.asarray(power_w, float)[..., None]
    s = np.asarray(cells, float)[..., None]
    q = np.asarray(capacity_ah, float)[..., None]
    r = np.asarray(resistance_ohm, float)[..., None]
    x = np.linspace(0.0, X_MAX, nodes)
    with np.errstate(divide="ignore", invalid="ignore"):
        return _discharge(p, s, q, r, x, curve, nodes)


def _discharge(p, s, q, r, x, curve: CellCurve, nodes: int) -> Discharge:
    e = s * curve.open_circuit_v(x)
    i = np.asarray(load_current_a(p, e, r))  # arrays in, an array out
    v = e - r * i
    margin = np.where(np.isfinite(v), v - s * curve.cutoff_v, -np.inf)
    ok = np.logical_and.accumulate(margin >= 0, axis=-1)
    inv = np.where(ok, 1.0 / np.where(ok, i, 1.0), 0.0)
    seg_ok = ok[..., 1:]
    dx = x[1] - x[0]
    full = np.sum(np.where(seg_ok, 0.5 * (inv[..., 1:] + inv[..., :-1]) * dx, 0.0), axis=-1)
    n_ok = ok.sum(axis=-1)  # valid nodes from the start
    last = np.clip(n_ok - 1, 0, nodes - 1)
    nxt = np.clip(n_ok, 0, nodes - 1)
    take = lambda a, idx: np.take_along_axis(a, idx[..., None], axis=-1)[..., 0]  # noqa: E731
    m0, m1 = take(margin, last), take(margin, nxt)
    # fraction of the next segment still above the cut-off (linear in the margin)
    frac = np.where((n_ok < nodes) & np.isfinite(m1) & (m0 > m1), m0 / (m0 - m1), 0.0)
    frac = np.clip(frac, 0.0, 1.0)
    i0 = take(i, last)
    i1 = np.where(np.isfinite(take(i, nxt)), take(i, nxt), i0)
    i_end = i0 + frac * (i1 - i0)
    partial = frac * dx * 0.5 * (1.0 / np.where(n_ok > 0, i0, np.inf) + 1.0 / i_end)
    partial = np.where(n_ok > 0, np.nan_to_num(partial), 0.0)
    x_end = np.where(n_ok > 0, x[last] + frac * dx, 0.0)
    hours = q[..., 0] * (full + partial)
    v_end = np.where(frac > 0, s[..., 0] * curve.cutoff_v, take(v, last))
    return Discharge(
        time_min=np.where(n_ok > 0, 60.0 * hours, 0.0),
        used_fraction=x_end,
        start_voltage_v=v[..., 0],
        start_current_a=i[..., 0],
        end_voltage_v=np.where(n_ok > 0, v_end, np.nan),
        end_current_a=np.where(n_ok > 0, i_end, np.nan),
    )


def loaded_voltage_v(current_a, cells, resistance_ohm, curve: CellCurve = DEFAULT_CELL, x=0.0):
    """Terminal voltage at discharged fraction ``x`` delivering ``current_a``."""
    return np.asarray(cells, float) * curve.open_circuit_v(x) - np.asarray(
        resistance_ohm, float
    ) * np.asarray(current_a, float)
