"""A constant's uncertainty as text: ``value ± U (k = 2)`` and its budget term by term.

One home for how ``fit`` and ``constants`` print what ``analysis.metrology.gum.Budget``
holds (as its ``as_dict``), so both read alike.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from analysis.metrology.constant_budgets import BUDGETED

__all__ = ["DISPLAY", "budget_lines", "display", "value_and_u", "with_expanded"]

#: how each budgeted constant is shown: name, factor from SI, unit, format (times in ms)
DISPLAY: dict[str, tuple[str, float, str, str]] = {
    c.key: (c.label, 1e3, "ms", ".3f") if c.unit == "s" else (c.label, 1.0, c.unit, ".5g")
    for c in BUDGETED}


def display(name: str) -> tuple[str, float, str, str]:
    """How constant ``name`` is shown (``DISPLAY``): its own name, SI, for one not listed."""
    return DISPLAY.get(name, (name, 1.0, "", ".5g"))


def value_and_u(value: float, big_u: float) -> tuple[str, str]:
    """U to two significant digits and the value to the same decimal place (GUM 7.2.6):
    ``29.71 ± 0.27``, ``4.431e-06 ± 2.1e-08``."""
    if not (math.isfinite(big_u) and big_u > 0):
        return f"{value:.5g}", f"{big_u:.2g}"
    last = math.floor(math.log10(big_u)) - 1  # the decimal place of U's second digit
    if 1e-3 <= abs(value) < 1e6 or value == 0:
        places = max(0, -last)
        return f"{value:.{places}f}", f"{big_u:.{places}f}" if places else f"{big_u:.0f}"
    digits = max(0, math.floor(math.log10(abs(value))) - last)
    return f"{value:.{digits}e}", f"{big_u:.1e}"


def with_expanded(name: str, b: Mapping[str, Any]) -> str:
    """``tau up 29.71 ± 0.27 ms (k = 2)``: U to two significant digits, the value to U's
    last digit."""
    label, f, unit, fmt = display(name)
    value, big_u = b.get("value"), b.get("U")
    if not isinstance(value, int | float) or not math.isfinite(value):
        return f"{label} n/a"
    if isinstance(big_u, int | float) and math.isfinite(big_u) and big_u > 0:
        v, u = value_and_u(value * f, big_u * f)
        return f"{label} {v} ± {u} {unit} (k = {b.get('k', 2):g})"
    return f"{label} {format(value * f, fmt)} {unit}"


def budget_lines(name: str, b: Mapping[str, Any]) -> list[str]:
    """The budget: one line per term (u, type, degrees of freedom, what it is), then u_c,
    the effective degrees of freedom and U."""
    label, f, unit, _ = display(name)
    lines = [f"budget of {label} ({unit}):"]
    for t in b.get("budget", []):
        dof = "inf" if t.get("dof") is None else f"{t['dof']:.0f}"
        lines.append(f"  {t['name']:<52} u {t['u'] * f:10.3g}  {t['type']}  nu {dof:>4}"
                     + (f"  {t['note']}" if t.get("note") else ""))
    dof_eff = b.get("dof_eff")
    lines.append(f"  {'combined standard uncertainty u_c':<52} u {b['u'] * f:10.3g}     nu "
                 f"{'inf' if dof_eff is None else f'{dof_eff:.0f}':>4}")
    lines.append(f"  {'expanded U = k u_c':<52} U {b['U'] * f:10.3g}  k = {b['k']:g}")
    return lines
