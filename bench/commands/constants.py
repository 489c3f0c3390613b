"""``rotorbench constants``: store fitted constants of runs and list the stored ones.

``--add RUN ...`` fits each run (step runs: latency and time constants; sweeps: static
curves and the supply current at a list of thrusts; ``bench.store.constants_fit``) and stores the
result in ``<out>/constants.sqlite`` under the run's motor, propeller, ESC, ESC mode and
battery. ``bench.store.measured_constants.load_measured`` turns the store into the optimizer's
``MeasuredActuator`` overrides.
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

from rich.console import Console
from rich.table import Table

from bench.cli_args.store_args import (
    DEFAULT_RUNS_ROOT,
    add_store_args,
    run_folder_arg,
    store_from_args,
)
from bench.paths.outputs import check_folder_to_read, check_writable
from bench.store.constants_fit import STD_KEYS, fit_for_store
from bench.store.lab_catalog import StoredConstants


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
    add_store_args(p)
    p.set_defaults(func=handler)


def handler(args: argparse.Namespace) -> int:
    store = store_from_args(args)
    if hasattr(store, "root"):  # a folder store: the folder must be readable/writable
        check_folder_to_read(store.root)
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
    for c in fitted:
        print(f"stored {c.kind} constants of {c.run_id} for {c.motor} / {c.propeller} / "
              f"{c.esc} ({c.esc_mode}) / {c.battery}")
        for note in c.data.get("notes", []):
            print(f"note: {note}")
    rows = store.constants()
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
            vals = (f"latency {_value(d, 'latency_s', 1e3, '.1f')} ms, tau up "
                    f"{_value(d, 'tau_up_s', 1e3, '.1f')} / down "
                    f"{_value(d, 'tau_down_s', 1e3, '.1f')} ms")
        else:
            vals = (f"k_f {_value(d, 'k_f_n_s2', 1.0, '.3g')}, {len(d['hover_thrust_n'])} "
                    f"current points up to {max(d['hover_thrust_n'], default=0):.2f} N")
        table.add_row(r.motor, r.propeller, f"{r.esc} ({r.esc_mode})", r.battery, r.kind, vals,
                      r.run_id)
    Console(width=shutil.get_terminal_size((160, 24)).columns).print(table)
    return 0


def _value(data: dict, key: str, scale: float, fmt: str) -> str:
    """A stored constant with the spread of one measurement where the store has one
    (``STD_KEYS``): "40.1 ± 1.2"; "?" for a constant the fit could not give."""
    x, std = data.get(key), data.get(STD_KEYS[key])
    text = format(x * scale, fmt) if isinstance(x, int | float) else "?"
    return text + (f" ± {format(std * scale, fmt)}" if isinstance(std, int | float) else "")
