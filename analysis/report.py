"""Tables shaped like the thesis' Table C.1 and Tables E.11-E.14, for the terminal and CSV.

A table is a title, column headers and rows of plain values; ``to_rich`` renders it with
``rich`` and ``write_csv`` writes it atomically (temp file, rename). The builders take
fitted results, never raw data, so the same code prints the sim demo and a real stand.
"""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rich.table import Table as RichTable

from analysis.step_response import StepResponse

__all__ = ["OUTPUT_DELAY", "Table", "output_delay_line", "table_c1", "table_e11", "table_e12",
           "table_e13", "table_e14", "write_csv"]

G0 = 9.80665


@dataclass(frozen=True)
class Table:
    title: str
    columns: tuple[str, ...]
    rows: tuple[tuple[Any, ...], ...]
    note: str = ""

    def to_rich(self) -> RichTable:
        t = RichTable(title=self.title, caption=self.note or None)
        for i, c in enumerate(self.columns):
            t.add_column(c, justify="left" if i == 0 else "right")
        for r in self.rows:
            t.add_row(*(_fmt(v) for v in r))
        return t


def _fmt(v: Any) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "N/A"
    if isinstance(v, float):
        if v != 0 and abs(v) < 0.01:
            return f"{v:.3g}"
        if abs(v) >= 100:
            return f"{v:.1f}"
        return f"{v:.2f}" if abs(v) >= 1 or v == 0 else f"{v:.3g}"
    return str(v)


def write_csv(table: Table, path: Path) -> None:
    """Write the table as CSV (header row, then rows) via a temp file and rename."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    with open(tmp, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(table.columns)
        for r in table.rows:
            w.writerow(["" if v is None or (isinstance(v, float) and not math.isfinite(v))
                        else v for v in r])
    os.replace(tmp, path)


def _ms(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else x * 1e3


def table_c1(fits: Sequence[tuple[str, StepResponse]],
             from_parameters_tau_s: float | None = None) -> Table:
    """Table C.1: delay, tau_up, tau_dn and the rise/fall RMS per ESC setting, with the
    spread over repeats; the RMS in grams for thrust fits (as the thesis plots thrust in
    g), in the signal's unit otherwise; the "From Parameters" row from (C.3)."""
    rows = []
    for label, f in fits:
        up, dn = f.up, f.down
        lat = [d.latency.value for d in (up, dn) if d is not None]
        rms = f.rise_fall_rms / G0 * 1e3 if f.signal == "thrust_n" else f.rise_fall_rms
        rows.append((
            label,
            _ms(sum(lat) / len(lat)) if lat else None,
            _ms(up.tau.value) if up else None,
            _ms(up.tau.std) if up else None,
            _ms(dn.tau.value) if dn else None,
            _ms(dn.tau.std) if dn else None,
            _ms(up.t63.value) if up else None,
            _ms(dn.t63.value) if dn else None,
            rms,
        ))
    if from_parameters_tau_s is not None:
        tp = _ms(from_parameters_tau_s)
        rows.append(("From Parameters", None, tp, None, tp, None, None, None, 0.0))
    unit = "g" if fits and fits[0][1].signal == "thrust_n" else (
        fits[0][1].signal if fits else "")
    return Table(
        "Table C.1: first order system with delay",
        ("ESC", "delay [ms]", "tau_up [ms]", "+-", "tau_dn [ms]", "+-", "t63_up [ms]",
         "t63_dn [ms]", f"RMS [{unit}]"),
        tuple(rows),
        note="+-: standard deviation of the single-edge fits; t63 from the command edge; "
             "RMS of |rising| - |falling| change over 500 ms",
    )


def table_e11(rows: Sequence[tuple[str, float, float]]) -> Table:
    """Table E.11: measured 63 % rise times (ms), acceleration T_a and deceleration T_d."""
    return Table("Table E.11: measured rise times (63 %)", ("design", "T_a [ms]", "T_d [ms]"),
                 tuple((lbl, _ms(a), _ms(d)) for lbl, a, d in rows))


def table_e12(rows: Sequence[tuple[str, float, float, float]]) -> Table:
    """Table E.12: simulated 63 % rise time T and its difference to the mean of the
    measured T_a and T_d; rows are (design, T_sim, T_a, T_d) in seconds."""
    return Table("Table E.12: simulated rise times (63 %)",
                 ("design", "T [ms]", "dT [ms]"),
                 tuple((lbl, _ms(sim), _ms(sim - 0.5 * (a + d))) for lbl, sim, a, d in rows))


def table_e13(rows: Sequence[tuple[str, float, float, float]]) -> Table:
    """Table E.13: time constant from experiments (mean of T_a, T_d) against the model's
    (E.8) estimate; rows are (design, T_a, T_d, model tau) in seconds."""
    out = []
    for lbl, a, d, model in rows:
        mean = 0.5 * (a + d)
        out.append((lbl, _ms(mean), _ms(model), _ms(mean - model)))
    return Table("Table E.13: time constants, experiment vs model",
                 ("design", "T [ms]", "model [ms]", "dT [ms]"), tuple(out))


def table_e14(rows: Sequence[tuple[str, float, float]]) -> Table:
    """Table E.14: flight time from measured current T_e vs the optimizer's T_o (min)."""
    return Table("Table E.14: flight times", ("design", "T_e [min]", "T_o [min]"),
                 tuple(rows))


#: run.json's summary of the delay from each command the bench sent to the firmware's
#: first output carrying it (a rig whose ESC is a flight controller's firmware)
OUTPUT_DELAY = "command_to_output_delay_s"


def output_delay_line(meta: Mapping[str, Any]) -> str | None:
    """One line on the run's command-to-output delay, or None when the run has none."""
    d = meta.get(OUTPUT_DELAY)
    if not isinstance(d, Mapping):
        return None
    if d.get("median") is None:
        return f"command to firmware output: no command seen ({d.get('commands', 0)} sent)"

    def ms(key: str) -> str:
        v = d.get(key)
        return f"{float(v) * 1e3:.1f} ms" if isinstance(v, int | float) else "n/a"

    missed = d.get("missed") or 0
    return (f"command to firmware output: median {ms('median')}, p95 {ms('p95')}, max "
            f"{ms('max')} over {d.get('seen')} commands"
            + (f" ({missed} without an output)" if missed else ""))
