"""A stored constant's uncertainty as a GUM budget: the one place that knows how a row of
the constants store carries it, so that a comparison of benches (and anything else that
weighs constants by their uncertainty) reads it one way.

Two forms are read, newest first:

* the budget stored with the constant since budgets are kept:
  ``data[bench.store.constants_fit.UNCERTAINTY][name]``, the object of
  ``analysis.metrology.constant_budgets.entry`` (value, unit, u, U, k, terms; the run and
  the calibration records it came from);
* otherwise the spread the fits have always stored (``bench.store.constants_fit.STD_KEYS``:
  the spread of one speed level of a sweep, of one edge of a step run) over the square root
  of how many there were (``points``; ``repeats``, twice that for the latency, the mean of
  both edges): the standard error of the fitted mean, Type A only, for a row stored before
  budgets were. It leaves out the cell's calibration and the timebase: an underestimate
  where those matter.

A constant with neither has no uncertainty (None): it is listed, never judged.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from analysis.metrology.gum import Budget, Term
from bench.store.constants_fit import STD_KEYS, stored_entry
from bench.store.json_values import finite_number

__all__ = ["stored_budget"]


def stored_budget(name: str, value: float, unit: str, data: Mapping[str, Any]
                  ) -> Budget | None:
    """The uncertainty budget of constant ``name`` (a data key, e.g. ``k_f_n_s2``) of
    value ``value`` in one stored row's ``data``; None when the row carries none."""
    entry = stored_entry(data, name)
    if entry.get("budget"):
        try:
            return Budget.from_dict({**entry, "value": value, "unit": entry.get("unit", unit)})
        except (KeyError, TypeError, ValueError):
            pass  # a damaged entry: fall back to the spread
    return _spread_budget(name, value, unit, data)


def _spread_budget(name: str, value: float, unit: str, data: Mapping[str, Any]
                   ) -> Budget | None:
    if name not in STD_KEYS:
        return None
    std = finite_number(data.get(STD_KEYS[name]))
    count_key = "points" if name in ("k_f_n_s2", "k_q_nm_s2") else "repeats"
    n = finite_number(data.get(count_key))
    if std is None or std < 0 or n is None or n < 2:
        return None
    n = 2 * n if name == "latency_s" else n
    return Budget.of(value, unit, [Term(
        f"spread of the {'speed levels' if count_key == 'points' else 'edges'} "
        "(standard error of the mean)", std / math.sqrt(n), "A", dof=n - 1,
        note=f"{STD_KEYS[name]} {std:.4g} over sqrt({n:g})")])
