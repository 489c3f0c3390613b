"""Make the figures of docs/sizing.md in docs/img (run from the repository root).

    .venv/bin/python docs/make_sizing_figures.py

Every figure comes from the commands or modules the docs describe: ``evaluate --plot``,
``pareto --plot`` and ``optimizer.model.battery``.
"""

from __future__ import annotations

import contextlib
import io
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bench.cli import main  # noqa: E402

IMG = REPO / "docs" / "img"
SIZINGLAB = REPO / "optimizer" / "data" / "sizinglab"


def quiet(argv: list[str]) -> None:
    with contextlib.redirect_stdout(io.StringIO()):
        code = main(argv)
    if code != 0:
        raise SystemExit(f"{' '.join(argv)}: exit {code}")


def discharge_figure(path: Path) -> None:
    """Case I's best design: pack voltage and current against time, model vs thesis."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from optimizer.catalogs.catalog import load_catalog
    from optimizer.model import battery as bat
    from optimizer.model.design_model import evaluate_design, single_design_catalog
    from optimizer.model.sheet import design_sheet, pack_of

    base = load_catalog(REPO / "optimizer" / "data" / "catalogs" / "thesis-e")
    ids = ("P4", "M1", "B3")
    curve = bat.DEFAULT_CELL
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.6))
    for n, model in enumerate(("thesis", "drive")):
        cat = replace(base, constants=base.constants.with_updates(current_model=model))
        one = single_design_catalog(cat, *ids)
        rec = evaluate_design(cat, 4, *ids)
        sheet = design_sheet(one, rec)
        pack = {k: float(np.ravel(v)[0]) for k, v in pack_of(one).items()}
        p = sheet["hover_electric_power_w"]
        x = np.linspace(0, sheet["battery_model"]["usable_capacity_pct"] / 100, 400)
        e = pack["cells"] * curve.open_circuit_v(x)
        i = bat.load_current_a(p, e, pack["resistance_ohm"])
        v = e - pack["resistance_ohm"] * i
        dt = np.diff(x) * pack["capacity_ah"] * 60 * 0.5 * (1 / i[1:] + 1 / i[:-1])
        t = np.concatenate([[0], np.cumsum(dt)])
        color = f"C{2 * n}"
        a1.plot(t, v, color=color, label=f"battery model, current model {model}")
        a2.plot(t, i, color=color, label=f"{model}: battery model, {p:.0f} W (to "
                f"{sheet['battery_model']['flight_time_min']:.1f} min)")
        a2.axhline(rec["current_a"], color=color, ls="--",
                   label=f"{model}: constant B_V, x18 (to {rec['flight_time_min']:.1f} min)")
    a1.axhline(pack["voltage_v"], color="C1", ls="--", label="thesis: constant B_V (E.67)")
    a1.axhline(pack["cells"] * curve.cutoff_v, color="grey", ls=":", label="cut-off 3.3 V/cell")
    a1.set_xlabel("time (min)")
    a1.set_ylabel(f"pack voltage (V), R = {1e3 * pack['resistance_ohm']:.1f} mOhm")
    a1.legend(fontsize=8)
    a2.set_xlabel("time (min)")
    a2.set_ylabel("battery current (A)")
    a2.legend(fontsize=8)
    for a in (a1, a2):
        a.grid(alpha=0.3)
    fig.suptitle("thesis-e, 4 x P4 / M1 / B3 (Case I best): hover discharge, both current "
                 "models", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run(img: Path = IMG, lab: Path = SIZINGLAB) -> list[Path]:
    """Write the figures into ``img``; print each one written and each one skipped (with
    why); return those written."""
    img.mkdir(parents=True, exist_ok=True)
    written = [img / "sizing_partial_load.png", img / "sizing_pareto_thesis_e.png"]
    quiet(["evaluate", "--actuators", "4", "--propeller", "P4", "--motor", "M1", "--battery",
           "B3", "--plot", str(written[0])])
    quiet(["pareto", "--actuators", "4", "--x", "flight-time", "--y", "time-constant",
           "--plot", str(written[1])])
    skipped: list[str] = []
    target = img / "sizing_pareto_sizinglab.png"
    if lab.is_dir():
        import tempfile

        from optimizer.catalogs.sizinglab import import_to_folder

        with tempfile.TemporaryDirectory() as tmp:
            folder = import_to_folder(lab, Path(tmp) / "sizinglab")
            quiet(["pareto", "--catalog", str(folder), "--actuators", "4", "--x",
                   "flight-time", "--y", "time-constant", "--flyable", "--plot", str(target)])
        written.append(target)
    else:
        skipped.append(f"skipped {target}: no SizingLab data at {lab}")
    discharge_figure(img / "sizing_discharge.png")
    written.append(img / "sizing_discharge.png")
    for path in written:
        print(f"wrote {path}")
    for line in skipped:
        print(line)
    return written


if __name__ == "__main__":
    run()
