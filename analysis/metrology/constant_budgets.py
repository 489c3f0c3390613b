"""The uncertainty budget of each constant the bench fits (GUM, JCGM 100), term by term.

Why: a constant without its uncertainty cannot be compared with another bench's, nor drawn
from honestly by the optimizer. Each budget lists what this run can know about its own
constant:

* step runs (latency, tau up and down; ``step_budgets``): the noise of the mean response
  through the fit's covariance (Type A), the edge-to-edge scatter beyond that noise
  (Type A, nu = repeats - 1; the standard error of the repeats' mean holds the noise too,
  so only its excess is added: noise is not counted twice), and for the latency the
  declared cell mechanics the fit subtracted (Type B). The load cell's scale does not
  enter: a time constant and a delay do not depend on the units of the response.
* sweeps (k_f, k_q, the thrust polynomial; ``static_budgets``): the least-squares fit of
  the binned speed levels (Type A, nu = N - p; the levels' scatter holds the cell's noise
  and the repeatability across points), the zero every reading shares (the tare's mean
  of a noisy cell: a bias of the whole sweep the points' scatter does not show), the
  cell's calibration from the run's calibration record (Type B; relative, shared by every
  point, so it scales the constant as a whole), and the speed counter's timebase (Type B;
  k ~ 1/w^2, sensitivity -2).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from analysis.metrology.gum import Budget, Term, rectangular
from analysis.static_curves import StaticCurves
from analysis.step_response import DirectionFit, StepResponse

__all__ = ["BUDGETED", "TIMEBASE_PPM", "BudgetedConstant", "calibration_terms", "entry",
           "static_budgets", "step_budgets", "tare_uncertainty"]


@dataclass(frozen=True)
class BudgetedConstant:
    """A constant with a budget: its key (as ``run.json``, the store and ``--json`` name
    it), its name for people, SI unit, the run that fits it (``step`` or ``static``, a
    sweep) and the force channel whose calibration scales it (None: a time)."""

    key: str
    label: str
    unit: str
    run: str
    channel: str | None = None


#: every constant the budgets below give, in the order they are shown
BUDGETED: tuple[BudgetedConstant, ...] = (
    BudgetedConstant("latency_s", "latency", "s", "step"),
    BudgetedConstant("tau_up_s", "tau up", "s", "step"),
    BudgetedConstant("tau_down_s", "tau down", "s", "step"),
    BudgetedConstant("k_f_n_s2", "k_f", "N s^2", "static", "thrust_n"),
    BudgetedConstant("k_q_nm_s2", "k_q", "N m s^2", "static", "torque_nm"),
    BudgetedConstant("thrust_poly_w_0", "thrust poly c0", "N", "static", "thrust_n"),
    BudgetedConstant("thrust_poly_w_1", "thrust poly c1", "N s", "static", "thrust_n"),
    BudgetedConstant("thrust_poly_w_2", "thrust poly c2", "N s^2", "static", "thrust_n"),
)

#: The speed counter's timebase: a quartz crystal within +-50 ppm (a typical
#: microcontroller/FPGA clock specification), rectangular.
TIMEBASE_PPM = 50.0


def _direction_terms(d: DirectionFit, attr: str, scale: float) -> list[Term]:
    """Noise (fit covariance of the mean response) and the repeats' scatter beyond it."""
    u_fit = getattr(d.mean, f"u_{attr}")
    est = getattr(d, attr.removesuffix("_s"))
    terms = []
    if math.isfinite(u_fit):
        terms.append(Term("sensor noise (fit covariance of the mean response)",
                          scale * u_fit, "A",
                          note="least squares of the mean of the repeats, s^2 (J'J)^-1"))
    se = est.stderr
    if est.n > 1 and math.isfinite(se):
        excess = math.sqrt(max(se * se - (u_fit * u_fit if math.isfinite(u_fit) else 0.0), 0.0))
        terms.append(Term("repeatability beyond the noise (edge to edge)", scale * excess,
                          "A", dof=est.n - 1,
                          note=f"{est.n} edges: standard error {se * 1e3:.3g} ms of their "
                               "mean, its noise part above removed"))
    return terms


def step_budgets(res: StepResponse) -> dict[str, Budget]:
    """Budgets of ``latency_s`` (the mean of rising and falling), ``tau_up_s`` and
    ``tau_down_s`` of a step fit; a direction without a fit has none."""
    out: dict[str, Budget] = {}
    for name, d in (("tau_up_s", res.up), ("tau_down_s", res.down)):
        if d is not None:
            out[name] = Budget.of(d.tau.value, "s", _direction_terms(d, "tau_s", 1.0))
    dirs = [d for d in (res.up, res.down) if d is not None]
    if not dirs:
        return out
    w = 1.0 / len(dirs)  # the latency is the mean of the directions: each enters with 1/n
    terms = [Term(f"{d.direction}: {t.name}", t.u, t.kind, t.dof, t.note)
             for d in dirs for t in _direction_terms(d, "latency_s", w)]
    if res.cell is not None:
        c = res.cell
        terms.append(Term("cell mechanics (group delay modelled)", c.group_delay_s * c.u_rel,
                          "B", note=f"{c.natural_frequency_hz:g} Hz, zeta "
                                    f"{c.damping_ratio:g}: 2 zeta / omega_n = "
                                    f"{c.group_delay_s * 1e3:.3g} ms known to "
                                    f"{c.u_rel * 100:g} %" + (f" ({c.source})" if c.source
                                                              else "")))
    value = float(np.mean([d.latency.value for d in dirs]))
    out["latency_s"] = Budget.of(value, "s", terms)
    return out


def calibration_terms(applied: Mapping[str, Any] | None, value: float) -> list[Term]:
    """The cell's calibration as terms of a constant proportional to its force: each line
    of the record's scale budget (relative) times ``value``, or its combined relative
    uncertainty where the run kept only that. None or not applied: no term."""
    if not applied or "u_gain_rel" not in applied:
        return []
    rid = str(applied.get("id", ""))
    lines = (applied.get("budget") or {}).get("budget") or []
    if lines:
        return [Term(f"calibration {rid}: {t['name']}", abs(value) * float(t["u"]),
                     str(t["type"]), math.inf if t.get("dof") is None else float(t["dof"]),
                     str(t.get("note", ""))) for t in lines]
    return [Term(f"calibration {rid}: scale", abs(value) * float(applied["u_gain_rel"]), "B",
                 note="combined relative uncertainty of the record's scale")]


def _timebase_term(value: float, power: int = -2) -> Term:
    """The counter's timebase scales every speed by (1 + e): a constant proportional to
    w^power moves by power * e of itself."""
    return Term("speed counter timebase", abs(power * value) * rectangular(TIMEBASE_PPM * 1e-6),
                "B", note=f"+-{TIMEBASE_PPM:g} ppm crystal, rectangular; ~ w^{power}: "
                          f"sensitivity {power}")


def _noise_term(u_rep: float, replicates: int, spread: float, n: int, what: str
                ) -> list[Term]:
    """The fit's noise: from the interleaved sub-sweeps when the sweep had samples for
    them (``analysis.static_curves.replicate_u``), else the levels' scatter (an upper
    bound: it holds the bins' speed-thrust mismatch too)."""
    if math.isfinite(u_rep) and replicates > 1:
        return [Term(f"sensor noise ({what}, {replicates} interleaved sub-sweeps)", u_rep,
                     "A", dof=replicates - 1,
                     note="standard deviation of the sub-sweeps' mean (GUM 4.2.3)")]
    if n > 1 and math.isfinite(spread):
        return [Term(f"{what} (speed levels' scatter)", spread, "A", dof=n - 1,
                     note=f"{n} binned speed levels")]
    return []


def _zero_term(sens: float, u_zero: float) -> list[Term]:
    if not (math.isfinite(sens) and math.isfinite(u_zero)):
        return []
    return [Term("zero (tare) of the cell", abs(sens) * u_zero, "A",
                 note=f"u {u_zero:.3g} of the zero, shared by every reading; sensitivity "
                      f"{sens:.3g} per unit of zero")]


def _slope_budget(curves: StaticCurves, k: str, spread: float, n: int, unit: str,
                  applied: Mapping[str, Any] | None, u_zero: float | None) -> Budget:
    value = float(getattr(curves, k))
    terms = _noise_term(getattr(curves, f"{k}_u"), curves.replicates,
                        spread / math.sqrt(n) if n > 0 else math.nan, n,
                        "fit through the origin")
    if u_zero is not None:
        terms += _zero_term(getattr(curves, f"{k}_zero_sensitivity"), u_zero)
    terms += calibration_terms(applied, value)
    terms.append(_timebase_term(value))
    return Budget.of(value, unit, terms)


def tare_uncertainty(meta: Mapping[str, Any]) -> dict[str, float]:
    """The standard uncertainty of each channel's zero, as a run's ``run.json`` keeps its
    tare (``tare``: channel -> offset, u, samples); none for a run without one."""
    tare = meta.get("tare") or {}
    return {ch: float(t["u"]) for ch, t in tare.items()
            if isinstance(t, Mapping) and t.get("u") is not None}


def static_budgets(curves: StaticCurves, calibrations: Mapping[str, Any] | None = None,
                   zero_u: Mapping[str, float] | None = None) -> dict[str, Budget]:
    """Budgets of ``k_f_n_s2``, ``k_q_nm_s2`` and the thrust polynomial's coefficients
    (``thrust_poly_w_0`` .. ``_2``, ascending powers of w) of a sweep; ``calibrations``:
    the run's applied calibrations by channel (``run.json``); ``zero_u``: the standard
    uncertainty of each channel's zero (its tare), by channel."""
    cal = calibrations or {}
    zu = zero_u or {}
    out: dict[str, Budget] = {}
    n_f = int(np.isfinite(curves.thrust).sum())
    n_q = int(np.isfinite(curves.torque).sum())
    if math.isfinite(curves.k_f):
        out["k_f_n_s2"] = _slope_budget(curves, "k_f", curves.k_f_std, n_f, "N s^2",
                                        cal.get("thrust_n"), zu.get("thrust_n"))
    if math.isfinite(curves.k_q):
        out["k_q_nm_s2"] = _slope_budget(curves, "k_q", curves.k_q_std, n_q, "N m s^2",
                                         cal.get("torque_nm"), zu.get("torque_nm"))
    ok = np.isfinite(curves.thrust)
    if curves.thrust_poly is not None and ok.sum() > 4:
        coef, cov = np.polyfit(curves.omega[ok], curves.thrust[ok], 2, cov=True)
        units = ("N", "N s", "N s^2")
        for power, (c, var) in enumerate(zip(coef[::-1], np.diag(cov)[::-1], strict=True)):
            terms = _noise_term(curves.thrust_poly_u[power], curves.replicates,
                                math.sqrt(max(var, 0.0)), int(ok.sum()) - 2,
                                "polynomial fit")
            if power == 0 and "thrust_n" in zu:  # a zero error shifts the constant term
                terms += _zero_term(1.0, zu["thrust_n"])
            terms += calibration_terms(cal.get("thrust_n"), float(c))
            if power:
                terms.append(_timebase_term(float(c), -power))
            out[f"thrust_poly_w_{power}"] = Budget.of(float(c), units[power], terms)
    return out


def entry(budget: Budget, run_id: str, calibrations: Sequence[str] = ()) -> dict[str, Any]:
    """A stored constant's uncertainty: its budget, the run and the calibration records it
    came from (what ``constants --json`` lists and a comparison of benches reads)."""
    return {**budget.as_dict(), "run": run_id, "calibrations": list(calibrations)}
