"""``rotorbench constants``: store fitted constants of runs and list the stored ones.

``--add RUN ...`` fits each run (step runs: latency and time constants; sweeps: static
curves and the supply current at a list of thrusts; ``bench.store.constants_fit``) and stores the
result in ``<out>/constants.sqlite`` under the run's motor, propeller, ESC, ESC mode and
battery. ``bench.store.measured_constants.load_measured`` turns the store into the optimizer's
``MeasuredActuator`` overrides.
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.table import Table

from bench.cli_args.budget_text import budget_lines, with_expanded
from bench.cli_args.store_args import (
    DEFAULT_RUNS_ROOT,
    add_store_args,
    run_folder_arg,
    store_from_args,
)
from bench.paths.outputs import check_folder_to_read, check_writable
from bench.store.constants_fit import STD_KEYS, UNCERTAINTY, fit_for_store, stored_entry
from bench.store.lab_catalog import StoredConstants
from optimizer.errors import RequestError


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "constants", help="store fitted actuator constants of runs; list the stored ones",
        description="Fits step runs (latency, time constants) and sweeps (static curves, "
                    "current at hover thrusts) and stores them per motor, propeller, ESC, "
                    "ESC mode and battery in <out>/constants.sqlite, beside the run index.")
    p.add_argument("--out", type=Path, default=DEFAULT_RUNS_ROOT,
                   help="output root holding runs.sqlite (default: ./runs)")
    p.add_argument("--add", type=Path, nargs="+", default=[], metavar="RUN",
                   help="fit these run folders (or run ids of --store) and store their "
                        "constants")
    p.add_argument("--json", action="store_true",
                   help="list every stored constant with its value, standard uncertainty, "
                        "U (k = 2), the run and the calibration records it came from")
    p.add_argument("--budget", action="store_true",
                   help="print each stored constant's uncertainty budget term by term")
    add_store_args(p)
    p.set_defaults(func=handler)


def handler(args: argparse.Namespace) -> int:
    store = store_from_args(args)
    if hasattr(store, "root"):  # a folder store: the folder must be readable/writable
        check_folder_to_read(store.root)
        if args.json and not args.add and not Path(store.root).is_dir():
            # a script reading [] could not tell a mistyped folder from an empty store
            raise RequestError(f"{store.root}: no such folder; no constants to list")
        if args.add:
            check_writable(store.root, "--out", folder=True)
    fitted = []
    for run in args.add:
        folder = run_folder_arg(args, run)
        key, kind, run_id, data = fit_for_store(folder)
        fitted.append(StoredConstants(key.motor, key.propeller, key.esc, key.esc_mode,
                                      key.battery, kind, key.catalog, run_id, str(folder), "",
                                      data))
    if fitted:  # all or none: the lab catalog adds them in one transaction
        store.add_constants(fitted)
    rows = store.constants()
    if args.json:  # for scripts: nothing but the JSON on stdout
        print(json.dumps(constants_json(rows), indent=2, allow_nan=False))
        return 0
    for c in fitted:
        print(f"stored {c.kind} constants of {c.run_id} for {c.motor} / {c.propeller} / "
              f"{c.esc} ({c.esc_mode}) / {c.battery}")
        for note in c.data.get("notes", []):
            print(f"note: {note}")
    if not rows:
        print(f"no constants stored under {store.describe()}")
        return 0
    where = store.path if hasattr(store, "root") else store.describe()
    table = Table(title=f"measured constants in {where}")
    for col in ("motor", "propeller", "esc (mode)", "battery", "kind", "values", "run"):
        table.add_column(col, overflow="fold")
    for r in rows:
        d = r.data
        if r.kind == "step":
            vals = (f"latency {_value(d, 'latency_s', 1e3, '.2f')} ms, tau up "
                    f"{_value(d, 'tau_up_s', 1e3, '.2f')} / down "
                    f"{_value(d, 'tau_down_s', 1e3, '.2f')} ms")
        else:
            vals = (f"k_f {_value(d, 'k_f_n_s2', 1.0, '.3g')}, {len(d['hover_thrust_n'])} "
                    f"current points up to {max(d['hover_thrust_n'], default=0):.2f} N")
        table.add_row(r.motor, r.propeller, f"{r.esc} ({r.esc_mode})", r.battery, r.kind, vals,
                      r.run_id)
    console = Console(width=shutil.get_terminal_size((160, 24)).columns)
    console.print(table)
    for r in rows:
        unc = r.data.get(UNCERTAINTY) or {}
        if unc:
            console.print(f"{r.kind} of {r.run_id}: "
                          + "; ".join(with_expanded(k, b) for k, b in unc.items()),
                          highlight=False, markup=False)
        if args.budget:
            for k, b in unc.items():
                for line in budget_lines(k, b):
                    console.print(line, highlight=False, markup=False)
    return 0


def constants_json(rows: list[StoredConstants]) -> list[dict[str, Any]]:
    """One entry per stored constant: the actuator, the constant, value, u, U and k, and
    where it came from (run, calibration records); a constant stored before uncertainties
    were kept has u null."""
    out = []
    for r in rows:
        unc = r.data.get(UNCERTAINTY) or {}
        names = [k for k in (*STD_KEYS, *unc) if k in r.data or k in unc]
        for name in dict.fromkeys(names):
            b = unc.get(name, {})
            value = b.get("value", r.data.get(name))
            if not isinstance(value, int | float):
                continue
            out.append({"motor": r.motor, "propeller": r.propeller, "esc": r.esc,
                        "esc_mode": r.esc_mode, "battery": r.battery, "kind": r.kind,
                        "constant": name, "value": value, "unit": b.get("unit"),
                        "u": b.get("u"), "U": b.get("U"), "k": b.get("k"),
                        "dof_eff": b.get("dof_eff"), "run": r.run_id,
                        "calibrations": b.get("calibrations", [])})
    return out


def _value(data: dict, key: str, scale: float, fmt: str) -> str:
    """A stored constant with its expanded uncertainty U (k = 2) where the store has one,
    else the spread of one measurement (``STD_KEYS``, older rows): "40.1 ± 1.2"; "?" for a
    constant the fit could not give."""
    x = data.get(key)
    std = stored_entry(data, key).get("U", data.get(STD_KEYS[key]))
    text = format(x * scale, fmt) if isinstance(x, int | float) else "?"
    return text + (f" ± {format(std * scale, fmt)}" if isinstance(std, int | float) else "")
