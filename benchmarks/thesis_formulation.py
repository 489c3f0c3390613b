"""The thesis' own MILP formulation (Paper E section 3) against the exact optimum.

Prints, measured on this machine: the section 2.4.1 robot result; for Paper E's three
test cases and 4, 6, 8 actuators the model size (vs the thesis' 1795, 2444, 3091
variables), build and solve times and the linearisation errors, with 10 regions and
with the thesis' region counts; and, for every objective on the shipped thesis
catalogs, whether the linearised choice is the exact optimum and how much it loses.
"""

from __future__ import annotations

import sys
from pathlib import Path

from rich.console import Console
from rich.table import Table

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from optimizer.cases.robot import load_robot, solve_robot  # noqa: E402
from optimizer.catalogs.catalog import load_catalog  # noqa: E402
from optimizer.solve.thesis_formulation import (  # noqa: E402
    OBJECTIVES,
    THESIS_REGIONS,
    THESIS_VARIABLE_COUNTS,
    solve_thesis,
)

CASES = {"I": ("flight-time", 0.0), "II": ("flight-time", 1.5), "III": ("time-constant", 0.0)}
console = Console()


def robot() -> None:
    problem = load_robot(ROOT / "optimizer/data/catalogs/thesis-robot")
    table = Table(title="Section 2.4.1 robot (Table 2.2), current 1 A/kg")
    for col in (
        "power limit",
        "battery",
        "W kg",
        "C A",
        "R h",
        "E lin W",
        "E exact W",
        "vars",
        "rows",
        "solve s",
    ):
        table.add_column(col)
    for limit in (problem.power_limit_w, None):
        r = solve_robot(problem.with_(power_limit_w=limit))
        table.add_row(
            str(limit),
            r.battery,
            f"{r.weight_kg:g}",
            f"{r.current_a:g}",
            f"{r.runtime_h:.3f}",
            f"{r.power_w:.2f}",
            f"{r.power_exact_w:.2f}",
            str(r.n_vars),
            str(r.n_constraints),
            f"{r.solve_time_s:.4f}",
        )
    r = solve_robot(problem.with_(current_per_kg_a=2.0))
    table.add_row(
        "30 (2 A/kg as printed)",
        str(r.battery),
        "-",
        "-",
        "-",
        "-",
        "-",
        str(r.n_vars),
        str(r.n_constraints),
        f"{r.solve_time_s:.4f} ({r.status})",
    )
    console.print(table)


def paper_e_cases() -> None:
    cat = load_catalog(ROOT / "optimizer/data/catalogs/thesis-e")
    for regions, label in ((10, "10 regions"), (THESIS_REGIONS, "thesis regions (230 / 160)")):
        table = Table(title=f"Paper E test cases, thesis formulation, {label}")
        for col in (
            "case",
            "N",
            "choice",
            "exact optimum?",
            "vars (thesis)",
            "binary",
            "rows",
            "build s",
            "solve s",
            "err power",
            "err flight",
            "err roll",
            "err pitch",
        ):
            table.add_column(col)
        for case, (objective, payload) in CASES.items():
            for n in (4, 6, 8):
                r = solve_thesis(cat, n, objective, payload_kg=payload, regions=regions)
                choice = f"{r.propeller} {r.motor} {r.battery}"
                opt = (
                    "yes"
                    if r.shortfall is not None and r.shortfall <= 1e-9
                    else (f"no, -{100 * r.shortfall:.2f} %")
                )
                e = r.errors
                table.add_row(
                    case,
                    str(n),
                    choice,
                    opt,
                    f"{r.n_vars} ({THESIS_VARIABLE_COUNTS[n]})",
                    str(r.n_binary),
                    str(r.n_constraints),
                    f"{r.build_time_s:.3f}",
                    f"{r.solve_time_s:.3f}",
                    f"{100 * e['propeller_power_w']:+.3f} %",
                    f"{100 * e['flight_time_min']:+.3f} %",
                    f"{100 * e['roll_inertia_kgm2']:+.3f} %",
                    f"{100 * e['pitch_inertia_kgm2']:+.3f} %",
                )
        console.print(table)


def all_objectives() -> None:
    for name in ("thesis-e", "thesis-d"):
        cat = load_catalog(ROOT / "optimizer/data/catalogs" / name)
        table = Table(title=f"{name}: every objective, 10 regions vs thesis regions")
        for col in (
            "objective",
            "N",
            "choice (10)",
            "loss (10)",
            "solve s (10)",
            "choice (thesis)",
            "loss (thesis)",
            "solve s (thesis)",
            "optimal designs",
        ):
            table.add_column(col)
        for objective in OBJECTIVES:
            for n in (4, 6, 8):
                a = solve_thesis(cat, n, objective, regions=10)
                b = solve_thesis(cat, n, objective, regions=THESIS_REGIONS)
                opt = ", ".join(" ".join(d) for d in a.optimal_designs[:3])
                if len(a.optimal_designs) > 3:
                    opt += f" (+{len(a.optimal_designs) - 3})"
                table.add_row(
                    objective,
                    str(n),
                    f"{a.propeller} {a.motor} {a.battery}",
                    f"{100 * a.shortfall:.2f} %",
                    f"{a.solve_time_s:.3f}",
                    f"{b.propeller} {b.motor} {b.battery}",
                    f"{100 * b.shortfall:.2f} %",
                    f"{b.solve_time_s:.3f}",
                    opt,
                )
        console.print(table)


if __name__ == "__main__":
    robot()
    paper_e_cases()
    all_objectives()
