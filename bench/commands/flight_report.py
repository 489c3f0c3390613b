"""``rotorbench flight-report RUN``: what a flight log says against the design and the bench.

The run is a flight log brought in by ``rotorbench import`` (Betaflight/INAV blackbox, PX4
ULog, ArduPilot DataFlash). The report: the step response per axis (setpoint to gyro;
Flight Review's H1 estimate, PID-Analyzer's deconvolution beside it), each motor's
in-flight response (command to speed: tau up and down, dead time), the hover (throttle,
current, power) and the gyro noise against throttle. ``--design FILE`` (the JSON of
``rotorbench evaluate --json`` or one design of ``optimize --json``) adds the design's
predicted hover beside the flight's; ``--store`` the bench's measured time constants of
that motor beside the in-flight ones. Writes report.json and PNG figures to ``--out``.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

from bench.cli_args.store_args import (
    add_store_args,
    named_store,
    run_folder_arg,
    store_from_args,
)
from bench.errors import RigError
from bench.paths.outputs import check_writable


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "flight-report", help="step response, motor response, hover and noise of a flight log",
        description=__doc__.split("\n\n", 1)[1] if __doc__ else None)
    p.add_argument("run", type=Path, help="a flight run folder (rotorbench import LOG), or "
                                          "a run id of --store")
    p.add_argument("--design", type=Path, default=None, metavar="JSON",
                   help="the design flown: rotorbench evaluate --json output (or one design "
                        "of optimize --json)")
    # dest report_dir: --out names the report's folder, not a run root the store checks
    p.add_argument("--out", dest="report_dir", metavar="OUT", type=Path, default=None,
                   help="folder for report.json and the figures (default: ./flight-report-"
                        "<run id>)")
    p.add_argument("--blades", type=int, default=2, help="propeller blades (default 2)")
    p.add_argument("--json", action="store_true", help="print report.json")
    add_store_args(p)
    p.set_defaults(func=handler)


def _design(path: Path | None) -> dict[str, Any] | None:
    if path is None:
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise RigError(f"--design {path}: not a readable JSON file ({exc})") from None
    if isinstance(data, dict) and isinstance(data.get("designs"), list) and data["designs"]:
        data = data["designs"][0]  # optimize --json: its first design
    if not isinstance(data, dict) or "hover_throttle_pct" not in data:
        raise RigError(f"--design {path}: no hover_throttle_pct: expected the JSON of "
                       "rotorbench evaluate --json")
    return data


def _num(x: Any) -> float | None:
    return float(x) if isinstance(x, int | float) and math.isfinite(float(x)) else None


def design_vs_flight(summary: dict[str, Any], design: dict[str, Any] | None,
                     bench: dict[str, float] | None) -> list[dict[str, Any]]:
    """The table's rows: quantity, design (or bench), flight."""
    hover = summary["hover"]
    rows = []

    def row(name: str, unit: str, predicted: Any, flown: Any, source: str) -> None:
        rows.append({"quantity": name, "unit": unit, "predicted": _num(predicted),
                     "flight": _num(flown), "source": source})

    if design is not None:
        n = _num(design.get("actuators")) or 1.0
        thr = hover.get("throttle")
        row("hover throttle", "%", design.get("hover_throttle_pct"),
            None if thr is None else 100 * thr, "design model")
        row("hover battery current", "A", design.get("hover_battery_current_a"),
            hover.get("current_a"), "design model")
        row("hover electric power", "W", design.get("hover_electric_power_w"),
            hover.get("power_w"), "design model")
        row("hover power per actuator", "W",
            (_num(design.get("hover_electric_power_w")) or math.nan) / n,
            (hover.get("power_w") or math.nan) / n, "design model")
    motors = summary["motors"]
    for key, label in (("tau_up", "tau up"), ("tau_down", "tau down")):
        flown = [m[f"{key}_ms"] for m in motors.values() if _num(m.get(f"{key}_ms"))]
        bench_ms = None if bench is None or bench.get(f"{key}_s") is None \
            else 1e3 * bench[f"{key}_s"]
        if flown or bench_ms is not None:
            row(f"motor {label} (mean of motors)", "ms", bench_ms,
                sum(flown) / len(flown) if flown else None, "bench constants")
    return rows


def _bench_constants(args: argparse.Namespace, design: dict[str, Any] | None
                     ) -> dict[str, float] | None:
    """The bench's step constants of the design's motor and propeller, newest first (only
    from a store that is named: the folder default is no bench's)."""
    if design is None or not named_store(args):
        return None
    store = store_from_args(args)
    for row in reversed(store.constants()):
        if row.kind == "step" and row.motor == design.get("motor") and (
                design.get("propeller") in (None, row.propeller)):
            return {k: float(v) for k, v in row.data.items()
                    if k in ("tau_up_s", "tau_down_s", "latency_s") and _num(v) is not None}
    return None


def handler(args: argparse.Namespace) -> int:
    from analysis.flight_figures import plot_noise, plot_step_responses
    from analysis.flight_report import flight_report
    from analysis.run_record import read_run
    from bench.engine.recorder import atomic_write_json
    from bench.store.json_values import json_safe

    if not 1 <= args.blades <= 8:
        raise RigError(f"--blades: expected 1 to 8, got {args.blades}")
    design = _design(args.design)
    record = read_run(run_folder_arg(args, args.run))
    out = args.report_dir or Path(f"flight-report-{record.id}")
    check_writable(out, "--out", folder=True)
    rep = flight_report(record)
    summary = rep.summary()
    bench = _bench_constants(args, design)
    summary["design_vs_flight"] = design_vs_flight(summary, design, bench)
    summary["design"] = {k: design.get(k) for k in ("actuators", "propeller", "motor",
                                                   "battery")} if design else None
    out.mkdir(parents=True, exist_ok=True)
    figures = [p for p in (plot_step_responses(rep, out / "step_response.png"),
                           plot_noise(rep, out / "noise.png", args.blades)) if p is not None]
    summary["figures"] = [p.name for p in figures]
    report = json_safe(summary)
    atomic_write_json(out / "report.json", report)
    if args.json:
        print(json.dumps(report, indent=2))
        return 0
    _print(summary, out)
    return 0


def _print(s: dict[str, Any], out: Path) -> None:
    print(f"flight {s['run']}: report in {out}")
    for axis, r in s["step_response"].items():
        if r.get("why"):
            print(f"  step response {axis}: n/a ({r['why']})")
            continue
        pa = r["pid_analyzer"]
        print(f"  step response {axis}: delay {r['delay_ms']:.1f} ms, rise {r['rise_ms']:.1f} ms,"
              f" overshoot {r['overshoot_pct']:.1f} % (H1, {r['h1_segments']} segments; "
              f"PID-Analyzer: {pa['delay_ms']:.1f} ms, {pa['rise_ms']:.1f} ms, "
              f"{pa['overshoot_pct']:.1f} %, {pa['windows']} windows)")
    for m, r in s["motors"].items():
        print(f"  {m}: " + (f"n/a ({r['why']})" if r.get("why") else
                            f"tau up {r['tau_up_ms']:.1f} ms, down {r['tau_down_ms']:.1f} ms, "
                            f"dead time {r['dead_time_ms']:.1f} ms"))
    h = s["hover"]
    if "throttle" in h:
        extra = "".join(f", {label} {h[k]:.3g} {unit}" for k, label, unit in
                        (("current_a", "current", "A"), ("voltage_v", "voltage", "V"),
                         ("power_w", "power", "W")) if k in h)
        print(f"  hover ({h['hover_s']:.1f} s): throttle {100 * h['throttle']:.1f} %{extra}")
    for r in s["design_vs_flight"]:
        pred = "-" if r["predicted"] is None else f"{r['predicted']:.4g}"
        flown = "-" if r["flight"] is None else f"{r['flight']:.4g}"
        print(f"  {r['quantity']:<32} {pred:>10} {flown:>10} {r['unit']} ({r['source']})")
    for note in s["notes"]:
        print(f"  note: {note}")
