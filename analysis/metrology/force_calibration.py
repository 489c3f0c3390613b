"""The fit of a load- or torque-cell calibration series: known forces in, readings out.

A guided calibration applies known forces in ascending then descending order (ISO 376's
loading series, scaled down to a hobby stand) and holds each. From the holds this module
gives what a calibration record states:

* the reading model ``reading = offset + F / scale`` by weighted least squares (each point
  weighted by its reading's and its reference force's standard uncertainty), so the bench
  converts ``F = scale (reading - offset)``, with the covariance of (offset, 1/scale);
* the instrument's characteristics, relative to the full-scale output (FSO = the span of
  readings from zero to the largest force): non-linearity (the largest deviation of the
  mean of up and down at one force from the line), hysteresis (the largest |down - up|),
  creep (the change of the reading over the hold at the largest force), repeatability (the
  largest difference between repeats of one force in one direction) and zero return (the
  zero after the series minus the zero before);
* the scale's uncertainty budget (GUM): the reference forces' systematic part (g, buoyancy),
  the fit (Type A; with a common dispersion added to every point when the residuals exceed
  the points' own uncertainties, since then they hold non-linearity and hysteresis the
  weights did not; see ``_dispersion``), and the non-linearity and hysteresis a reading in
  use can carry (rectangular, GUM 4.3.7).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from analysis.errors import CalibrationError
from analysis.metrology.gum import Budget, Term, rectangular

__all__ = ["CalibrationPoint", "ForceCalibration", "fit_force_calibration", "hold_mean"]

#: Blocks a hold is cut into for the standard uncertainty of its mean: the samples of a
#: filtered ADC stream are correlated, block means much less so (GUM 4.2, caution on n).
HOLD_BLOCKS = 10


@dataclass(frozen=True)
class CalibrationPoint:
    """One hold: the reference force applied (N or N m), its independent standard
    uncertainty (the weight's mass, the arm's length), the direction of loading (``"up"``,
    ``"down"``; the zeros before and after are ``"up"`` and ``"down"`` at force 0) and the
    readings with their times over the hold."""

    force: float
    u_force: float
    direction: str
    t_s: np.ndarray
    readings: np.ndarray


def hold_mean(readings: np.ndarray) -> tuple[float, float]:
    """The mean of a hold and its standard uncertainty from the scatter of block means."""
    y = np.asarray(readings, dtype=float)
    y = y[np.isfinite(y)]
    if y.size < 2 * HOLD_BLOCKS:
        if y.size < 2:
            raise CalibrationError(f"a hold has {y.size} readings: at least 2 are needed")
        return float(y.mean()), float(y.std(ddof=1) / math.sqrt(y.size))
    blocks = np.array_split(y, HOLD_BLOCKS)
    means = np.array([b.mean() for b in blocks])
    return float(y.mean()), float(means.std(ddof=1) / math.sqrt(HOLD_BLOCKS))


@dataclass(frozen=True)
class ForceCalibration:
    """What a calibration series gives; ``scale`` and ``offset`` turn a reading into force."""

    scale: float  # N (or N m) per reading unit
    offset: float  # reading at zero force
    covariance: np.ndarray  # of (offset, 1/scale), reading units
    scale_budget: Budget  # relative (unit "1"): u(scale)/scale term by term
    full_scale_force: float
    nonlinearity: float  # fractions of the full-scale output
    hysteresis: float
    creep: float
    repeatability: float
    zero_return: float
    residual_rms: float  # N, the points against the line
    birge_ratio: float
    points: list[dict[str, Any]] = field(default_factory=list)

    def force(self, reading: np.ndarray | float) -> np.ndarray | float:
        """Force from a reading (the applied calibration)."""
        return self.scale * (np.asarray(reading) - self.offset)

    def u_scale(self) -> float:
        """Standard uncertainty of the scale, N per reading unit."""
        return self.scale * self.scale_budget.u

    def characteristics(self) -> dict[str, float]:
        return {"nonlinearity": self.nonlinearity, "hysteresis": self.hysteresis,
                "creep": self.creep, "repeatability": self.repeatability,
                "zero_return": self.zero_return}

    def failed(self, limits: dict[str, float]) -> list[str]:
        """The characteristics above their acceptance limits (fractions of FSO)."""
        have = self.characteristics()
        return [f"{name} {abs(have[name]) * 100:.3g} % of full scale > limit "
                f"{limit * 100:.3g} %" for name, limit in sorted(limits.items())
                if name in have and abs(have[name]) > limit]

    def as_dict(self) -> dict[str, Any]:
        return {"scale": self.scale, "offset": self.offset,
                "u_scale": self.u_scale(), "u_offset": math.sqrt(self.covariance[0, 0]),
                "covariance_offset_inverse_scale": self.covariance.tolist(),
                "scale_budget": self.scale_budget.as_dict(),
                "full_scale_force": self.full_scale_force,
                "characteristics_fraction_of_full_scale": self.characteristics(),
                "residual_rms": self.residual_rms, "birge_ratio": self.birge_ratio,
                "points": self.points}


def fit_force_calibration(points: Sequence[CalibrationPoint], *, u_rel_systematic: float,
                          systematic_note: str = "", resolution: float = 0.0
                          ) -> ForceCalibration:
    """Fit a calibration series (see the module's docstring). ``u_rel_systematic`` is the
    relative standard uncertainty shared by every reference force (local g, buoyancy):
    it scales them all alike, so it enters the scale's budget once, not the fit."""
    if len(points) < 3:
        raise CalibrationError(f"{len(points)} calibration points: at least 3 are needed "
                               "(a zero and two forces)")
    forces = np.array([p.force for p in points], dtype=float)
    if np.ptp(forces) <= 0:
        raise CalibrationError("every calibration point has the same force: nothing to fit")
    stats = [hold_mean(p.readings) for p in points]
    y = np.array([m for m, _ in stats])
    u_y = np.array([u for _, u in stats])
    u_f = np.array([p.u_force for p in points], dtype=float)
    floor = max(resolution / math.sqrt(12.0), 1e-12 * max(1.0, float(np.abs(y).max())))
    design = np.column_stack([np.ones_like(forces), forces])
    slope = float(np.polyfit(forces, y, 1)[0])
    if slope == 0:
        raise CalibrationError("the readings do not change with the force: is the cell "
                               "connected?")
    sigma = np.sqrt(u_y ** 2 + floor ** 2)
    for _ in range(2):  # the force's uncertainty enters through the slope: refine once
        sigma = np.sqrt(u_y ** 2 + (slope * u_f) ** 2 + floor ** 2)
        beta, _cov, _chi2 = _weighted_line(design, y, sigma)
        slope = float(beta[1])
    dof = len(points) - 2
    extra = _dispersion(design, y, sigma, dof)
    beta, cov, _chi2 = _weighted_line(design, y, np.sqrt(sigma ** 2 + extra))
    resid = y - design @ beta
    birge = math.sqrt(_weighted_line(design, y, sigma)[2] / dof) if dof > 0 else 1.0
    offset, inv_scale = float(beta[0]), float(beta[1])
    scale = 1.0 / inv_scale
    f_max = float(forces.max())
    fso = abs(inv_scale * f_max)
    chars = _characteristics(points, forces, y, beta, fso)
    u_fit_rel = math.sqrt(cov[1, 1]) / abs(inv_scale)
    terms = [
        Term("reference forces: g, buoyancy", u_rel_systematic, "B", note=systematic_note),
        Term("calibration fit (masses, reading noise)", u_fit_rel, "A", dof=max(dof, 1),
             note=f"{len(points)} points, Birge ratio {birge:.3g}"
                  + (f", dispersion {math.sqrt(extra) * abs(scale):.3g} added" if extra else "")),
        Term("non-linearity (in use)", rectangular(chars["nonlinearity"]), "B",
             note="largest deviation from the line, rectangular"),
        Term("hysteresis (in use)", rectangular(chars["hysteresis"] / 2.0), "B",
             note="half the largest up/down difference, rectangular"),
    ]
    table = [{"force": float(p.force), "u_force": float(p.u_force),
              "direction": p.direction, "reading": float(m), "u_reading": float(u),
              "residual_force": float(r * scale), "samples": int(np.size(p.readings))}
             for p, (m, u), r in zip(points, stats, resid, strict=True)]
    return ForceCalibration(
        scale=scale, offset=offset, covariance=cov,
        scale_budget=Budget.of(1.0, "1", terms), full_scale_force=f_max,
        nonlinearity=chars["nonlinearity"], hysteresis=chars["hysteresis"],
        creep=chars["creep"], repeatability=chars["repeatability"],
        zero_return=chars["zero_return"],
        residual_rms=float(np.sqrt(np.mean((resid * scale) ** 2))), birge_ratio=birge,
        points=table)


def _weighted_line(design: np.ndarray, y: np.ndarray, sigma: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, float]:
    """Weighted least squares: beta = (X'WX)^-1 X'Wy, V = (X'WX)^-1, and chi^2."""
    w = 1.0 / sigma ** 2
    cov = np.linalg.inv(design.T @ (design * w[:, None]))
    beta = cov @ (design.T @ (w * y))
    resid = y - design @ beta
    return beta, cov, float(np.sum(w * resid ** 2))


def _dispersion(design: np.ndarray, y: np.ndarray, sigma: np.ndarray, dof: int) -> float:
    """The variance to add to every point so that chi^2 / dof = 1 (0 if already <= 1).

    When the residuals exceed the points' own uncertainties they hold non-linearity and
    hysteresis, which are the same size at every point; the weights then become more even
    (a point whose hold happened to be quiet does not pin the line), and the covariance
    holds the scatter the data show (the additive-dispersion estimate of Paule-Mandel)."""
    if dof <= 0 or _weighted_line(design, y, sigma)[2] <= dof:
        return 0.0
    lo, hi = 0.0, float(np.var(y - design @ np.linalg.lstsq(design, y)[0])) * 10 + 1e-300
    for _ in range(60):  # chi^2 falls as the added variance grows: bisect (log scale)
        mid = math.sqrt(lo * hi) if lo > 0 else hi / 1e6
        if _weighted_line(design, y, np.sqrt(sigma ** 2 + mid))[2] > dof:
            lo = mid
        else:
            hi = mid
    return hi


def _characteristics(points: Sequence[CalibrationPoint], forces: np.ndarray, y: np.ndarray,
                     beta: np.ndarray, fso: float) -> dict[str, float]:
    """ISO 376-style error terms, each as a fraction of the full-scale output."""
    line = beta[0] + beta[1] * forces
    key = np.round(forces / max(float(np.abs(forces).max()), 1e-300), 9)
    up = np.array([p.direction == "up" for p in points])
    nonlin = hyst = repeat = 0.0
    for k in np.unique(key):
        at = key == k
        u_vals, d_vals = y[at & up], y[at & ~up]
        means = [v.mean() for v in (u_vals, d_vals) if v.size]
        nonlin = max(nonlin, abs(float(np.mean(means)) - float(line[at][0])))
        if u_vals.size and d_vals.size:
            hyst = max(hyst, abs(float(d_vals.mean() - u_vals.mean())))
        for vals in (u_vals, d_vals):
            if vals.size > 1:
                repeat = max(repeat, float(np.ptp(vals)))
    zeros = [i for i, p in enumerate(points) if p.force == 0]
    zero_return = float(y[zeros[-1]] - y[zeros[0]]) if len(zeros) > 1 else 0.0
    top = int(np.argmax(forces))
    t = np.asarray(points[top].t_s, dtype=float)
    r = np.asarray(points[top].readings, dtype=float)
    ok = np.isfinite(t) & np.isfinite(r)
    creep = 0.0
    if ok.sum() >= 3 and np.ptp(t[ok]) > 0:
        slope = float(np.polyfit(t[ok], r[ok], 1)[0])
        creep = slope * float(np.ptp(t[ok]))  # the change over the hold
    scale = 1.0 / fso
    return {"nonlinearity": nonlin * scale, "hysteresis": hyst * scale,
            "creep": creep * scale * math.copysign(1.0, beta[1]),
            "repeatability": repeat * scale,
            "zero_return": zero_return * scale * math.copysign(1.0, beta[1])}
