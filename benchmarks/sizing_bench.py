"""Sizing benchmark: series/parallel MILP, Pareto fronts, rules, battery model.

Prints what it measures on this machine (nothing hard-coded):
1. Series/parallel on the SizingLab catalogs (batteries read as cells, S 2-6, P 1-4):
   per actuator count the MILP and enumeration choices, whether they agree, the MILP
   solve time (all S) and the wall time including the model grids.
2. Pareto front flight time vs time constant (SizingLab, N = 4; thesis-e N = 4):
   points, MILP solves and time against enumeration, agreement.
3. The flyable-design rules on SizingLab: designs each removes, the best design before
   and after, and the best design's eCalc-like sheet (battery-model flight time).
4. Battery model: constant-power discharges per second over a whole design grid.

Run: ``.venv/bin/python benchmarks/sizing_bench.py [--quick]`` (quick: N = 4 only).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from optimizer.catalogs.catalog import load_catalog  # noqa: E402
from optimizer.catalogs.sizinglab import DEFAULT_FOLDER, import_sizinglab  # noqa: E402
from optimizer.model import battery as bat  # noqa: E402
from optimizer.model.design_model import evaluate_design, evaluate_grid, single_design_catalog  # noqa: E402
from optimizer.model.flyable import FlyableBuilder, Rules  # noqa: E402
from optimizer.model.sheet import design_sheet  # noqa: E402
from optimizer.solve.objectives import single  # noqa: E402
from optimizer.solve.packs import optimize_packs  # noqa: E402
from optimizer.solve.pareto import enumerate_front, milp_front  # noqa: E402
from optimizer.solve.selection import optimize  # noqa: E402


def series_parallel(lab, counts) -> None:
    print("\n1. Series/parallel, SizingLab cells, S 2-6, P 1-4, max flight time")
    for n in counts:
        rows = {}
        for method in ("milp", "exact"):
            t0, c0 = time.perf_counter(), time.process_time()
            d = optimize_packs(lab, single("flight-time"), (n,), method=method).designs[0]
            rows[method] = (d, time.perf_counter() - t0, time.process_time() - c0)
        (dm, wm, cm), (de, we, ce) = rows["milp"], rows["exact"]
        same = (dm.propeller, dm.motor, dm.battery) == (de.propeller, de.motor, de.battery)
        print(f"  N={n}: {dm.propeller} / {dm.motor} / {dm.battery} "
              f"({dm.metrics['flight_time_min']:.1f} min, {dm.metrics['total_mass_kg']:.2f} kg)"
              f"; MILP solve {dm.solve_time_s:.2f} s, grids {dm.grid_time_s:.2f} s, wall "
              f"{wm:.2f} s (CPU {cm:.2f} s); enumeration solve {de.solve_time_s:.2f} s, wall "
              f"{we:.2f} s (CPU {ce:.2f} s); agree: {same}")
        t0 = time.perf_counter()
        d = optimize_packs(lab, single("flight-time"), (n,), method="milp",
                           build_grid=FlyableBuilder(Rules())).designs[0]
        print(f"       with the rules: {d.propeller} / {d.motor} / {d.battery} "
              f"({d.metrics['flight_time_min']:.1f} min, {d.metrics['total_mass_kg']:.2f} kg, "
              f"{d.metrics['time_constant_ms']:.0f} ms), wall {time.perf_counter() - t0:.2f} s")


def fronts(lab, thesis_e) -> None:
    print("\n2. Pareto fronts, flight time vs time constant, N = 4")
    for name, cat in (("thesis-e", thesis_e), ("SizingLab", lab)):
        g = evaluate_grid(cat, 4)
        ok = g.feasible()
        cx, cy = single("flight-time").cost(g), single("time-constant").cost(g)
        e = enumerate_front(cx, cy, ok)
        m = milp_front(cx, cy, ok)
        print(f"  {name}: {ok.sum()} feasible designs, {len(m.indices)} front points; "
              f"MILP {m.solves} solves {m.time_s:.2f} s, enumeration {e.time_s:.3f} s; "
              f"agree: {e.indices.tolist() == m.indices.tolist()}")


def rules(lab) -> None:
    print("\n3. Flyable-design rules, SizingLab, max flight time, N = 4")
    plain = optimize(lab, single("flight-time"), (4,)).designs[0]
    builder = FlyableBuilder(Rules())
    ruled = optimize(lab, single("flight-time"), (4,), build_grid=builder).designs[0]
    rep = builder.reports[0]
    print(f"  {rep.physically_feasible} of {rep.designs} designs within the catalog limits, "
          f"{rep.flyable} flyable")
    for name in rep.removed_alone:
        print(f"    {name:15s} removes {rep.removed_alone[name]:7d} alone, "
              f"{rep.removed_in_turn[name]:7d} in turn")
    for label, d in (("before", plain), ("after", ruled)):
        one = single_design_catalog(lab, d.propeller, d.motor, d.battery)
        rec = evaluate_design(lab, 4, d.propeller, d.motor, d.battery)
        sheet = design_sheet(one, rec)
        print(f"  best {label}: {d.propeller} / {d.motor} / {d.battery}: "
              f"{rec['total_mass_kg']:.2f} kg, constant-voltage flight time "
              f"({lab.constants.current_model} current) {rec['flight_time_min']:.0f} "
              f"min, battery model {sheet['battery_model']['flight_time_min']:.0f} min, "
              f"{rec['time_constant_ms']:.0f} ms, hover throttle "
              f"{sheet['hover_throttle_pct']:.0f} %, T/W {sheet['thrust_to_weight']:.2f}, "
              f"full-throttle motor current {sheet['max_motor_current_a']:.1f} A (limit "
              f"{one.motors['max_current_a'].iloc[0]:g} A), tip speed "
              f"{sheet['tip_speed_max_m_s']:.0f} m/s, {sheet['efficiency_g_per_w']:.1f} g/W")


def battery_speed(lab) -> None:
    print("\n4. Battery model over a grid")
    g = evaluate_grid(lab, 4)
    power = g.metrics["power_w"][:, :40, :]
    b = lab.batteries
    cells = b["cells"].to_numpy(float)[None, None, :]
    cap = b["capacity_ah"].to_numpy(float)[None, None, :]
    r = bat.pack_resistance_ohm(cells, cap)
    t0 = time.perf_counter()
    d = bat.discharge(power, cells, cap, r)
    dt = time.perf_counter() - t0
    ratio = d.time_min / g.metrics["flight_time_min"][:, :40, :]
    ok = np.isfinite(ratio) & (d.time_min > 0)
    print(f"  {power.size} discharges ({bat.NODES} nodes each) in {dt:.2f} s "
          f"({power.size / dt:.0f} per s); battery-model / thesis flight time over them: "
          f"median {np.median(ratio[ok]):.2f}, 5-95 % {np.percentile(ratio[ok], 5):.2f}-"
          f"{np.percentile(ratio[ok], 95):.2f} (shaft power load, no motor losses)")


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args(argv)
    if not DEFAULT_FOLDER.is_dir():
        print(f"SizingLab data not found at {DEFAULT_FOLDER}")
        return 1
    lab = import_sizinglab(DEFAULT_FOLDER)
    thesis_e = load_catalog(REPO / "optimizer" / "data" / "catalogs" / "thesis-e")
    series_parallel(lab, (4,) if args.quick else (4, 6, 8))
    fronts(lab, thesis_e)
    rules(lab)
    battery_speed(lab)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
