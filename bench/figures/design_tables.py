"""Selection results as text: the Table E.8-shaped table ``optimize`` and the demo show.

One column per actuator count, rows = the quantities of Paper E's tables, the best count
marked, infeasible counts with their reason, and cells measured on the bench (``--measured``)
marked ``(m)``. ``evaluate`` prints one design with the same rows and marks. Shared by
several commands, so it lives here rather than in one of them.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from bench.store.measured_constants import is_measured
from optimizer.solve.selection import TIE_ORDER, TIE_RTOL

__all__ = ["MEASURED_MARK", "ROWS", "format_cell", "show_table"]

#: Marks a table cell whose number was measured on the bench (--measured).
MEASURED_MARK = "(m)"

#: Table rows: (label, key, format).
ROWS: tuple[tuple[str, str, str], ...] = (
    ("Propeller chosen", "propeller", "s"),
    ("Motor chosen", "motor", "s"),
    ("Battery chosen", "battery", "s"),
    ("Time constant (ms)", "time_constant_ms", ".0f"),
    ("Flight time (min)", "flight_time_min", ".1f"),
    ("Price", "price", ".2f"),
    ("Total mass (kg)", "total_mass_kg", ".3f"),
    ("Hover speed (rpm)", "hover_rpm", ".0f"),
    ("Propeller power (W)", "propeller_power_w", ".1f"),
    ("Battery current (A)", "current_a", ".2f"),
    ("Roll inertia (kg m^2)", "roll_inertia_kgm2", ".4f"),
    ("Pitch inertia (kg m^2)", "pitch_inertia_kgm2", ".4f"),
)


def format_cell(value: Any, fmt: str) -> str:
    """One cell of ``ROWS``: ``-`` for a missing or non-finite number."""
    if value is None:
        return "-"
    if fmt == "s":
        return str(value)
    if isinstance(value, float) and not math.isfinite(value):
        return "-"
    return format(value, fmt)


def show_table(result: Any, show: Callable[..., None], title: str | None = None) -> None:
    """Rich table like Table E.8: one column per actuator count, best marked, and its
    notes; each goes to ``show``, the command's ``Console.print``."""
    from rich.table import Table

    req = result.requirements
    bits = [f"objective {result.objective.name}", f"payload {req.payload_kg:g} kg"]
    if req.min_flight_time_min is not None:
        bits.append(f"flight time >= {req.min_flight_time_min:g} min")
    if req.max_time_constant_ms is not None:
        bits.append(f"time constant <= {req.max_time_constant_ms:g} ms")
    bits.append(f"method {result.method}")
    table = Table(title=title or ", ".join(bits), title_justify="left")
    table.add_column("Number of actuators", style="bold", no_wrap=True)
    best = result.best
    for d in result.designs:
        mark = " * best" if best is not None and d is best else ""
        table.add_column(f"{d.actuators}{mark}", justify="right", max_width=48)
    any_measured = False
    for label, key, fmt in ROWS:
        cells = []
        for d in result.designs:
            if not d.feasible:
                cells.append("infeasible" if key == "propeller" else "-")
            else:
                value = getattr(d, key) if fmt == "s" else d.metrics.get(key)
                cell = format_cell(value, fmt)
                if is_measured(d.extra.get("sources"), key):
                    cell, any_measured = f"{cell} {MEASURED_MARK}", True
                cells.append(cell)
        table.add_row(label, *cells)
    table.add_row("Solve time (s)", *(f"{d.solve_time_s:.4f}" for d in result.designs))
    table.add_row("Status", *(_status(d) for d in result.designs))
    if any(not d.feasible for d in result.designs):
        table.add_row("Reason", *(d.reason or "" for d in result.designs))
    show(table)
    if best is None:
        show("No feasible design for any actuator count.", style="bold red")
    else:
        show(
            f"Best: {best.actuators} actuators, propeller {best.propeller}, motor "
            f"{best.motor}, battery {best.battery}"
        )
    for line in tie_notes(result):
        show(line, style="dim")
    if any_measured:
        show(f"{MEASURED_MARK} measured on the bench (runs in --json 'sources'); "
                      "other numbers from the datasheet model", style="dim")
    if result.source:
        show(f"Catalog: {result.source}", style="dim")


_PARTS = ("propeller", "motor", "battery")


def tie_notes(result: Any) -> list[str]:
    """What "N tied" in the Status row means, once per distinct set of tied designs."""
    groups: dict[tuple[str, ...], list[int]] = {}
    for d in result.designs:
        names = tuple(d.extra.get("tied_designs") or ()) if d.feasible else ()
        if d.n_tied > 1 and names:
            groups.setdefault(names, []).append(d.actuators)
    notes = []
    objective = getattr(result.objective, "name", str(result.objective))
    for names, counts in groups.items():
        n = next(d.n_tied for d in result.designs if d.actuators == counts[0])
        shown = [f"{names[0]} (chosen)", *names[1:]] + (["..."] if n > len(names) else [])
        differ = [part for p, part in enumerate(_PARTS)
                  if len({name.split("/")[p] for name in names}) > 1]
        why = ""
        if differ == ["motor"] and objective == "flight-time":
            why = (" The flight time does not see the motor here: with the thesis current "
                   "model the battery delivers the propellers' shaft power (--current-model "
                   "drive counts the motor's losses), so motors of equal mass tie.")
        notes.append(
            f"{n} tied ({', '.join(map(str, counts))} actuators): {', '.join(shown)} reach "
            f"the same {objective} (within {TIE_RTOL:g} relative)"
            + (f" and differ only in the {' and '.join(differ)}" if differ else "")
            + f"; the chosen one comes first by {_tie_order(result.objective)}." + why)
    return notes


_TIE_WORDS = {"flight_time_min": "longer flight time", "price": "lower price",
              "time_constant_ms": "faster actuators", "power_w": "lower power",
              "total_mass_kg": "lower mass", "roll_inertia_kgm2": "lower roll inertia",
              "pitch_inertia_kgm2": "lower pitch inertia"}


def _tie_order(objective: Any) -> str:
    """optimizer.solve.selection's tie-break order in words, without the objective's metric."""
    own = set(getattr(objective, "metrics", ())) if getattr(objective, "is_single", False) \
        else set()
    words = [_TIE_WORDS.get(m, m) for m, _ in TIE_ORDER if m not in own]
    return ", then ".join([*words, "catalog order"])


def _status(d: Any) -> str:
    status = d.status
    if d.mip_gap is not None:
        status += f" (gap {d.mip_gap:.0%})"
    if d.n_tied > 1:
        status += f", {d.n_tied} tied"
    return status
