"""A step response as a load cell shows it: the plant's first-order lag seen through the
cell's own mechanics, and thrust as the square of a first-order speed.

Why: a thrust stand's cell and mount are a mass-spring-damper, ``omega_n^2 / (s^2 + 2 zeta
omega_n s + omega_n^2)``. A first-order-plus-delay fitted to what it shows puts the cell's
group delay ``2 zeta / omega_n`` into the latency and shortens tau; when the rig declares
the cell's dynamics, the fit models them instead (``CellDynamics``). And the rotor's speed
is the first-order state (C.2), thrust ``k_f w^2`` of it (E.1): a finite thrust step is not
first order in thrust, it starts slower rising and faster falling, which a first-order fit
in thrust reads as a longer rising and a shorter falling tau. The square law here fits the
speed's tau from a zero-referenced (tared) thrust.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["CellDynamics", "lag_and_derivatives", "lag_through_cell", "thrust_step",
           "thrust_step_jacobian"]


@dataclass(frozen=True)
class CellDynamics:
    """A cell's declared mechanics: natural frequency (Hz), damping ratio and the relative
    standard uncertainty of the group delay they give (0: known exactly, a simulator's)."""

    natural_frequency_hz: float
    damping_ratio: float
    u_rel: float = 0.0
    source: str = ""

    @property
    def omega_n(self) -> float:
        return 2.0 * math.pi * self.natural_frequency_hz

    @property
    def group_delay_s(self) -> float:
        """Low-frequency group delay ``2 zeta / omega_n``: what it adds to a latency."""
        return 2.0 * self.damping_ratio / self.omega_n

    @classmethod
    def from_meta(cls, meta: Mapping[str, Any], channel: str) -> CellDynamics | None:
        """The dynamics a run declares for ``channel`` (``run.json`` ``cell_dynamics``)."""
        d = (meta.get("cell_dynamics") or {}).get(channel)
        if not isinstance(d, Mapping):
            return None
        try:
            fn, zeta = float(d["natural_frequency_hz"]), float(d["damping_ratio"])
            u_rel = float(d.get("u_rel", 0.0) or 0.0)
        except (KeyError, TypeError, ValueError):
            return None
        if not (fn > 0 and zeta > 0 and math.isfinite(fn) and math.isfinite(zeta)):
            return None
        return cls(fn, zeta, u_rel, str(d.get("source", "")))

    def as_dict(self) -> dict[str, Any]:
        return {"natural_frequency_hz": self.natural_frequency_hz,
                "damping_ratio": self.damping_ratio, "u_rel": self.u_rel,
                "source": self.source}


def _poles(tau: float, cell: CellDynamics) -> list[complex]:
    wn, z = cell.omega_n, cell.damping_ratio
    root = np.sqrt(complex(z * z - 1.0))
    poles = [complex(-1.0 / tau), -z * wn + wn * root, -z * wn - wn * root]
    for i in range(1, 3):  # coincident poles have no residue form: part them by 1e-6
        for j in range(i):
            if abs(poles[i] - poles[j]) < 1e-6 * abs(poles[j]):
                poles[i] *= 1.0 + 1e-6 * (i + 1)
    return poles


def lag_through_cell(s: np.ndarray, tau: float, cell: CellDynamics | None) -> np.ndarray:
    """Unit step response of ``1 / (tau s + 1)`` (C.2), through ``cell`` if given, at times
    ``s`` after the (delayed) step; 0 before it.

    Through the cell: ``Y(s) = (omega_n^2 / tau) / (s (s - p0)(s - p1)(s - p2))`` with p0 =
    -1/tau and p1, p2 the cell's poles, so ``y(t) = 1 + sum_k r_k exp(p_k t)``, r_k the
    residues (complex for an underdamped cell; the sum is real)."""
    return _lag(s, tau, cell, derivatives=False)[0]


def lag_and_derivatives(s: np.ndarray, tau: float, cell: CellDynamics | None
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``lag_through_cell`` and its derivatives in ``s`` (the impulse response) and in
    ``tau``, in closed form: a step fit's Jacobian without finite differences (a third of
    the coverage test's time went to them). With the residues above, d/ds is
    ``sum_k r_k p_k exp(p_k s)``; only p0 = -1/tau and the gain omega_n^2 / tau depend on
    tau, so ``d r_k / d tau`` follows from the product form of r_k."""
    return _lag(s, tau, cell, derivatives=True)


def _lag(s: np.ndarray, tau: float, cell: CellDynamics | None, derivatives: bool
         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    s = np.asarray(s, float)
    if cell is None:
        after = s > 0.0
        s = np.where(after, s, 0.0)
        e = np.exp(-s / tau)
        if not derivatives:
            return 1.0 - e, e, e
        return 1.0 - e, np.where(after, e / tau, 0.0), -(s / (tau * tau)) * e
    s = np.clip(s, 0.0, None)
    poles = _poles(tau, cell)
    wn = cell.omega_n
    gain = wn * wn / tau
    dp0 = 1.0 / (tau * tau)  # d p0 / d tau
    x, ds, dtau = np.ones_like(s), np.zeros_like(s), np.zeros_like(s)
    pair = poles[1].imag != 0.0  # conjugate poles: their terms are conjugate, 2 Re(one)
    for k, pk in enumerate(poles[:2] if pair else poles):
        den = pk
        for j, pj in enumerate(poles):
            if j != k:
                den *= pk - pj
        r = gain / den
        if k == 0:  # r0 = gain / (p0 (p0 - p1)(p0 - p2))
            dlog = -1.0 / tau - dp0 * (1.0 / pk + sum(1.0 / (pk - pj) for pj in poles[1:]))
        else:  # r_k = gain / (p_k (p_k - p0)(p_k - p_other)): p0 enters once
            dlog = -1.0 / tau + dp0 / (pk - poles[0])
        twice = 2.0 if pk.imag != 0.0 else 1.0
        term = r * np.exp(pk * s) if pk.imag != 0.0 else r.real * np.exp(pk.real * s)
        x += twice * np.real(term)
        if not derivatives:
            continue
        ds += twice * np.real(term * pk)
        slope = term * dlog + (term * s * dp0 if k == 0 else 0.0)
        dtau += twice * np.real(slope)
    return x, ds, dtau


def thrust_step_jacobian(t: np.ndarray, latency: float, tau: float, y0: float, y1: float,
                         cell: CellDynamics | None = None, square: bool = False
                         ) -> tuple[np.ndarray, np.ndarray]:
    """``thrust_step`` and its derivatives in (latency, tau, y0, y1), columns of an
    (n, 4) array: the analytic Jacobian of a step fit."""
    s = np.asarray(t, float) - latency
    x, hx, tx = lag_and_derivatives(s, tau, cell)
    jac = np.empty((s.size, 4))
    if not square or y0 * y1 <= 0:
        jac[:, 0] = -(y1 - y0) * hx
        jac[:, 1] = (y1 - y0) * tx
        jac[:, 2] = 1.0 - x
        jac[:, 3] = x
        return y0 + (y1 - y0) * x, jac
    sign = math.copysign(1.0, y0)
    a, c = math.sqrt(abs(y0)), math.sqrt(abs(y1))  # F = (a + (c - a) x)^2 in shape
    b = c - a
    x2, hx2, tx2 = lag_and_derivatives(s, tau / 2.0, cell)
    jac[:, 0] = -sign * (2.0 * b * c * hx - b * b * hx2)
    jac[:, 1] = sign * (2.0 * b * c * tx - 0.5 * b * b * tx2)
    # d/da and d/dc of a^2 + 2 (c - a) c x - (c - a)^2 x2; da/dy0 = sign / (2 a), likewise c
    jac[:, 2] = (2.0 * a - 2.0 * c * x + 2.0 * b * x2) / (2.0 * a) if a > 0 else 0.0
    jac[:, 3] = ((4.0 * c - 2.0 * a) * x - 2.0 * b * x2) / (2.0 * c)
    return sign * (a * a + 2.0 * b * c * x - b * b * x2), jac


def thrust_step(t: np.ndarray, latency: float, tau: float, y0: float, y1: float,
                cell: CellDynamics | None = None, square: bool = False) -> np.ndarray:
    """The response ``y0 -> y1`` of a delay and a first-order lag at times ``t`` from the
    command, seen through ``cell``; with ``square``, of a thrust ``F = k_f w^2`` (E.1)
    whose speed w is the first-order state: F = (a + b x)^2, x = 1 - exp(-t/tau), i.e.
    ``a^2 + 2 b (a + b) x(tau) - b^2 x(tau / 2)`` since x^2 = 2 x(tau) - x(tau / 2), each
    x a linear response the cell passes on. Levels of opposite signs (no square law
    through zero) take the first-order form."""
    s = np.asarray(t, float) - latency
    x = lag_through_cell(s, tau, cell)
    if not square or y0 * y1 <= 0:
        return y0 + (y1 - y0) * x
    sign = math.copysign(1.0, y0)
    a, b1 = math.sqrt(abs(y0)), math.sqrt(abs(y1))
    b = b1 - a
    return sign * (a * a + 2.0 * b * (a + b) * x - b * b * lag_through_cell(s, tau / 2.0, cell))
