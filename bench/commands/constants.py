"""``rotorbench constants``: store fitted constants of runs and list the stored ones.

``--add RUN ...`` fits each run (step runs: latency and time constants; sweeps: static
curves and the supply current at a list of thrusts) and stores the result in
``<out>/constants.sqlite`` under the run's motor, propeller, ESC, ESC mode and battery.
``load_measured`` turns the store into the optimizer's ``MeasuredActuator`` overrides.
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Console
from rich.table import Table

from bench.cli_support import check_writable
from bench.constants_store import ActuatorKey, ConstantsStore
from bench.errors import RigError

HOVER_POINTS = 24  # thrusts at which the supply current is stored


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "constants", help="store fitted actuator constants of runs; list the stored ones",
        description="Fits step runs (latency, time constants) and sweeps (static curves, "
                    "current at hover thrusts) and stores them per motor, propeller, ESC, "
                    "ESC mode and battery in <out>/constants.sqlite, beside the run index.")
    p.add_argument("--out", type=Path, default=Path("runs"),
                   help="output root holding runs.sqlite (default: ./runs)")
    p.add_argument("--add", type=Path, nargs="+", default=[], metavar="RUN",
                   help="fit these run folders and store their constants")
    p.set_defaults(func=handler)


def fit_for_store(run: Path) -> tuple[ActuatorKey, str, str, dict[str, Any]]:
    """Fit one run folder; returns its key, kind (step/static), id and the values."""
    from analysis.flight_time import hover_current_a
    from analysis.run_record import read_run
    from analysis.static_curves import fit_static_run
    from analysis.step_response import fit_run

    rec = read_run(run)
    key = ActuatorKey.from_components(rec.components, str(rec.path / "run.json"))
    kind = str(rec.meta.get("kind", ""))
    if kind == "sweep":
        s = fit_static_run(rec)
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
        data = {**s.summary(), "hover_thrust_n": [t for t, _ in inside],
                "hover_current_a": [c for _, c in inside],
                "thrust_max_n": inside[-1][0] if inside else None}
        return key, "static", rec.id, data
    if kind in ("step1", "step"):
        f = fit_run(rec, window_s=2.0)  # the whole hold (slow coasting modes settle late)
        if f.up is None or f.down is None:
            raise RigError(f"{rec.path}: needs rising and falling edges")
        data = {"latency_s": 0.5 * (f.up.latency.value + f.down.latency.value),
                "tau_up_s": f.up.tau.value, "tau_down_s": f.down.tau.value,
                "tau_up_std_s": f.up.tau.std, "tau_down_std_s": f.down.tau.std,
                "rise_time_63_up_s": f.up.t63.value, "rise_time_63_down_s": f.down.t63.value,
                "gain": 0.5 * (f.up.gain.value + f.down.gain.value),
                "rise_fall_rms": f.rise_fall_rms, "repeats": f.up.tau.n,
                "thrust_low_n": f.up.mean.y0, "thrust_high_n": f.up.mean.y1}
        return key, "step", rec.id, data
    raise RigError(f"{rec.path}: run kind {kind!r}: only step1 and sweep runs give constants")


def load_measured(root: Path, catalog: str | None = None) -> list[Any]:
    """The stored constants as ``optimizer.measured.MeasuredActuator`` overrides: the time
    constant is the mean of the rising and falling ones (Table E.13 compares that mean
    with the model), the current from the static curves; one per (propeller, motor, ESC
    mode), the most recent when several batteries/ESCs were measured. A mode without a
    sweep of its own takes the static curves of the same pair in another mode."""
    from optimizer.measured import MeasuredActuator

    by: dict[tuple[str, str, str], dict[str, Any]] = {}
    for row in ConstantsStore(root).rows():
        if catalog is not None and row.key.catalog != catalog:
            continue
        slot = by.setdefault((row.key.propeller, row.key.motor, row.key.esc_mode), {})
        prev = slot.get(row.kind)
        if prev is None or row.fitted_utc >= prev.fitted_utc:
            slot[row.kind] = row
    out = []
    for (prop, motor, mode), rows in sorted(by.items()):
        step, static = rows.get("step"), rows.get("static")
        if static is None:  # steady curves hardly depend on the ESC mode: borrow one
            static = next((r["static"] for (p2, m2, _), r in sorted(by.items())
                           if (p2, m2) == (prop, motor) and "static" in r), None)
        tau = None
        if step is not None:
            tau = 0.5 * (step.data["tau_up_s"] + step.data["tau_down_s"])
        thrust = static.data.get("hover_thrust_n", []) if static is not None else []
        current = static.data.get("hover_current_a", []) if static is not None else []
        sources = ", ".join(f"{r.kind}: {r.run_id}" for r in (step, static) if r is not None)
        out.append(MeasuredActuator(
            propeller_id=prop, motor_id=motor, esc_mode=mode, time_constant_s=tau,
            hover_thrust_n=tuple(thrust), hover_current_a=tuple(current),
            supply_voltage_v=(static.data.get("voltage_v") if static is not None else None),
            max_thrust_n=(static.data.get("thrust_max_n") if static is not None and thrust
                          else None),
            source=sources, time_constant_source=step.run_id if step is not None else "",
            current_source=static.run_id if static is not None else "",
            **_flight_extras(step, static)))
    return out


def _flight_extras(step: Any, static: Any) -> dict[str, float]:
    """The flight model's optional constants (``MeasuredActuator`` tau_up_s ... k_m_nm_s2)
    where the store has them as positive finite numbers."""
    pairs = ()
    if step is not None:
        pairs += (("tau_up_s", step.data.get("tau_up_s")),
                  ("tau_down_s", step.data.get("tau_down_s")),
                  ("latency_s", step.data.get("latency_s")))
    if static is not None:
        pairs += (("k_f_n_s2", static.data.get("k_f_n_s2")),
                  ("k_m_nm_s2", static.data.get("k_q_nm_s2")))
    out = {}
    for name, value in pairs:
        try:
            x = float(value)
        except (TypeError, ValueError):
            continue
        if np.isfinite(x) and (x > 0 or (name == "latency_s" and x >= 0)):
            out[name] = x
    return out


def handler(args: argparse.Namespace) -> int:
    if args.add:
        check_writable(args.out, "--out", folder=True)
    store = ConstantsStore(args.out)
    for run in args.add:
        key, kind, run_id, data = fit_for_store(run)
        store.put(key, kind, run_id, str(run), data)
        print(f"stored {kind} constants of {run_id} for {key.motor} / {key.propeller} / "
              f"{key.esc} ({key.esc_mode}) / {key.battery}")
    rows = store.rows()
    if not rows:
        print(f"no constants stored under {args.out}")
        return 0
    table = Table(title=f"measured constants in {store.path}")
    for col in ("motor", "propeller", "esc (mode)", "battery", "kind", "values", "run"):
        table.add_column(col, overflow="fold")
    for r in rows:
        d = r.data
        if r.kind == "step":
            vals = (f"latency {d['latency_s'] * 1e3:.1f} ms, tau up {d['tau_up_s'] * 1e3:.1f} / "
                    f"down {d['tau_down_s'] * 1e3:.1f} ms")
        else:
            vals = (f"k_f {d.get('k_f_n_s2') or float('nan'):.3g}, {len(d['hover_thrust_n'])} "
                    f"current points up to {max(d['hover_thrust_n'], default=0):.2f} N")
        table.add_row(r.key.motor, r.key.propeller, f"{r.key.esc} ({r.key.esc_mode})",
                      r.key.battery, r.kind, vals, r.run_id)
    Console(width=shutil.get_terminal_size((160, 24)).columns).print(table)
    return 0
