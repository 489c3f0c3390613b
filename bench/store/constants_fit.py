"""A bench run folder as the constants the store keeps: the first half of the constants stage.

Step runs (kind ``step1``/``step``) give the latency and the rising and falling time
constants, each with the spread of one edge (``*_std_s``); sweeps give the static curves
(k_f, k_q with the spread of one speed level, ``k_f_std_n_s2``, ``k_q_std_nm_s2``) and the
supply current at ``HOVER_POINTS`` thrusts inside the measured range (the optimizer
never extrapolates a measurement, so nothing outside it is stored). Keyed by the run's
motor, propeller, ESC, ESC mode and battery (``bench.store.constants_store.ActuatorKey``).
A library function rather than CLI code because ``rotorbench constants``, ``rotorbench fly
--step-run`` and the demo all fit runs the same way. The second half, store -> optimizer
overrides, is ``bench.store.measured_constants``.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from analysis.metrology.constant_budgets import BUDGETED
from bench.errors import RigError
from bench.store.constants_store import ActuatorKey

__all__ = ["HOVER_POINTS", "STD_KEYS", "UNCERTAINTY", "fit_for_store", "stored_entry",
           "uncertainties"]

HOVER_POINTS = 24  # thrusts at which the supply current is stored
#: the stored constants that carry a spread, and the key of that spread (a store written
#: before the latency's and k_f's spreads were kept lacks those keys: no uncertainty)
STD_KEYS = {"tau_up_s": "tau_up_std_s", "tau_down_s": "tau_down_std_s",
            "latency_s": "latency_std_s", "k_f_n_s2": "k_f_std_n_s2",
            "k_q_nm_s2": "k_q_std_nm_s2"}


#: the key of a stored row's uncertainties: constant -> its budget, run and calibrations
#: (``analysis.metrology.constant_budgets.entry``); older rows lack it
UNCERTAINTY = "uncertainty"
#: the channel whose calibration a constant of a sweep reads through
CHANNEL_OF = {c.key: c.channel for c in BUDGETED if c.channel is not None}


def stored_entry(data: Mapping[str, Any], name: str) -> Mapping[str, Any]:
    """The stored uncertainty of constant ``name`` in a row's ``data`` (``UNCERTAINTY``:
    value, u, U, k, budget, run, calibrations); empty for a row stored without one."""
    budgets = data.get(UNCERTAINTY)
    entry = budgets.get(name) if isinstance(budgets, Mapping) else None
    return entry if isinstance(entry, Mapping) else {}


def uncertainties(budgets: dict[str, Any], run_id: str, applied: dict[str, Any]
                  ) -> dict[str, Any]:
    """Each budget as stored: value, u, U, terms, the run and the calibration records."""
    from analysis.metrology.constant_budgets import entry

    out = {}
    for name, budget in budgets.items():
        cal = applied.get(CHANNEL_OF.get(name, ""), {})
        ids = [str(cal["id"])] if cal.get("id") and "gain" in cal else []
        out[name] = entry(budget, run_id, ids)
    return out


def fit_for_store(run: Path) -> tuple[ActuatorKey, str, str, dict[str, Any]]:
    """Fit one run folder; returns its key, kind (step/static), id and the values."""
    from analysis.run_record import read_run

    rec = read_run(run)
    key = ActuatorKey.from_components(rec.components, str(rec.path / "run.json"))
    kind = str(rec.meta.get("kind", ""))
    if kind == "sweep":
        return key, "static", rec.id, _static_values(rec)
    if kind in ("step1", "step"):
        return key, "step", rec.id, _step_values(rec)
    raise RigError(f"{rec.path}: run kind {kind!r}: only step1 and sweep runs give constants")


def _static_values(rec: Any) -> dict[str, Any]:
    """A sweep's static curves and its supply current at thrusts inside the measured range."""
    from analysis.flight_time import hover_current_a
    from analysis.metrology.constant_budgets import static_budgets, tare_uncertainty
    from analysis.static_curves import fit_static_run

    s = fit_static_run(rec)
    applied = rec.meta.get("calibrations") or {}
    if s.thrust_poly is None or s.current_poly is None:
        raise RigError(f"{rec.path}: the sweep has no thrust or current to store")
    thr = s.thrust[np.isfinite(s.thrust)]
    # the thrust curve over the measured speeds: its top is the measured top thrust,
    # and every stored point lies inside the measured range (no extrapolation)
    lo = max(float(thr.min()), float(s.thrust_at(s.omega[0])))
    hi = min(float(thr.max()), float(s.thrust_at(s.omega[-1]))) * (1.0 - 1e-9)
    grid = np.linspace(lo, hi, HOVER_POINTS)
    inside = [(float(t), hover_current_a(s, float(t))) for t in grid
              if s.omega[0] <= float(s.omega_for_thrust(t)) <= s.omega[-1]]
    return {**s.summary(), "hover_thrust_n": [t for t, _ in inside],
            "hover_current_a": [c for _, c in inside],
            "thrust_max_n": inside[-1][0] if inside else None,
            UNCERTAINTY: uncertainties(
                static_budgets(s, applied, tare_uncertainty(rec.meta)), rec.id, applied)}


def _step_values(rec: Any) -> dict[str, Any]:
    """A step run's latency, time constants and gain (both edges, all repeats)."""
    from analysis.metrology.constant_budgets import step_budgets
    from analysis.step_response import fit_run, pooled_std

    f = fit_run(rec, window_s=2.0)  # the whole hold (slow coasting modes settle late)
    if f.up is None or f.down is None:
        raise RigError(f"{rec.path}: needs rising and falling edges")
    # *_std_s: the spread of one edge (sample std over the repeats), what one step of
    # this actuator may do; the standard error of the mean is std / sqrt(repeats)
    return {"latency_s": 0.5 * (f.up.latency.value + f.down.latency.value),
            "tau_up_s": f.up.tau.value, "tau_down_s": f.down.tau.value,
            "tau_up_std_s": f.up.tau.std, "tau_down_std_s": f.down.tau.std,
            "latency_std_s": pooled_std((f.up.latency, f.down.latency)),
            "rise_time_63_up_s": f.up.t63.value, "rise_time_63_down_s": f.down.t63.value,
            "gain": 0.5 * (f.up.gain.value + f.down.gain.value),
            "rise_fall_rms": f.rise_fall_rms, "repeats": f.up.tau.n,
            "thrust_low_n": f.up.mean.y0, "thrust_high_n": f.up.mean.y1,
            "notes": list(f.notes),  # provenance: e.g. levels held too briefly to settle
            UNCERTAINTY: uncertainties(step_budgets(f), rec.id, {})}
