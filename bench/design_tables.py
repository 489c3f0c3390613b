"""Selection results as text: the Table E.8-shaped table ``optimize`` and the demo print.

One column per actuator count, rows = the quantities of Paper E's tables, the best count
marked, infeasible counts with their reason, and cells measured on the bench (``--measured``)
marked ``(m)``. ``evaluate`` prints one design with the same rows and marks. Shared by
several commands, so it lives here rather than in one of them.
"""

from __future__ import annotations

import math
from typing import Any

from bench.measured_constants import is_measured

__all__ = ["MEASURED_MARK", "ROWS", "format_cell", "print_table"]

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


def print_table(result: Any, title: str | None = None, console: Any = None) -> None:
    """Rich table like Table E.8: one column per actuator count, best marked."""
    from rich.console import Console
    from rich.table import Table

    console = console or Console(soft_wrap=False)
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
    console.print(table)
    if best is None:
        console.print("No feasible design for any actuator count.", style="bold red")
    else:
        console.print(
            f"Best: {best.actuators} actuators, propeller {best.propeller}, motor "
            f"{best.motor}, battery {best.battery}"
        )
    if any_measured:
        console.print(f"{MEASURED_MARK} measured on the bench (runs in --json 'sources'); "
                      "other numbers from the datasheet model", style="dim")
    if result.source:
        console.print(f"Catalog: {result.source}", style="dim")


def _status(d: Any) -> str:
    status = d.status
    if d.mip_gap is not None:
        status += f" (gap {d.mip_gap:.0%})"
    if d.n_tied > 1:
        status += f", {d.n_tied} tied"
    return status
