"""What the web view shows of a run, computed by ``analysis/`` from the run folder.

Nothing here reads a file another way than ``analysis.run_record.read_run``; fits are the
same calls ``rotorbench fit``/``report`` make, so the page and the terminal agree.
Records are kept in a small cache (a run folder does not change once ended; a running one
is re-read when its row count moves).
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from analysis.errors import LogError
from analysis.run_record import RunRecord, read_run
from bench.serve.decimate import Bins, MinMaxEnvelope
from bench.store.json_values import json_safe

__all__ = [
    "FLIGHT_PLOTS",
    "PLOTS",
    "RecordCache",
    "SeriesCache",
    "command_edges",
    "export_of",
    "fits_of",
    "series_of",
    "static_points",
    "step_traces",
]

G0 = 9.80665
#: the time plots of a run page: (key, title, unit)
PLOTS = (("throttle_us", "command", "us"), ("thrust_n", "thrust", "N"),
         ("torque_nm", "torque", "N m"), ("current_a", "current", "A"),
         ("voltage_v", "voltage", "V"), ("rpm", "speed", "rpm"),
         ("efficiency_g_w", "efficiency", "g/W"))
#: the time plots of a flight run (docs/flight-logs.md's columns), several traces each:
#: (key, title, unit, ((column, trace name), ...)); a plot shows the traces the run has
MOTORS = range(1, 9)
FLIGHT_PLOTS = (
    *((f"rate_{a}", f"{name} rate: gyro vs setpoint", "rad/s",
       ((f"gyro_{a}_rad_s", "gyro"), (f"rate_sp_{a}_rad_s", "setpoint")))
      for a, name in (("x", "roll"), ("y", "pitch"), ("z", "yaw"))),
    ("motor_norm", "motor outputs", "0..1", tuple((f"motor{k}_norm", f"motor {k}")
                                                  for k in MOTORS)),
    ("motor_rpm", "motor speed (eRPM)", "rpm", tuple((f"motor{k}_rpm", f"motor {k}")
                                                     for k in MOTORS)),
)


class RecordCache:
    """The last few ``RunRecord``s read, by folder (bounded: a 5 M-row run is ~300 MB)."""

    def __init__(self, size: int = 4) -> None:
        self.size = size
        self._items: OrderedDict[Path, tuple[float, RunRecord]] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, folder: Path) -> RunRecord:
        key = Path(folder).resolve()
        stamp = _stamp(key)
        with self._lock:
            hit = self._items.get(key)
            if hit is not None and hit[0] == stamp:
                self._items.move_to_end(key)
                return hit[1]
        record = read_run(key)
        with self._lock:
            self._items[key] = (stamp, record)
            while len(self._items) > self.size:
                self._items.popitem(last=False)
        return record


def _stamp(folder: Path) -> float:
    """Changes when the run gains a part or its run.json is rewritten."""
    try:
        parts = folder / "samples.parquet"  # not listed when it is a link (maybe out)
        n = sum(1 for _ in parts.iterdir()) if parts.is_dir() and not parts.is_symlink() else 0
        return (folder / "run.json").stat().st_mtime_ns + n
    except OSError:
        return math.nan


def _efficiency_of(thrust: np.ndarray, current: np.ndarray, voltage: np.ndarray
                  ) -> np.ndarray:
    """Thrust per electric power in g/W, where the power is above 1 W."""
    p = voltage * current
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(p > 1.0, thrust / G0 * 1e3 / p, np.nan)


def _efficiency(record: RunRecord) -> np.ndarray | None:
    if not {"thrust_n", "current_a", "voltage_v"} <= set(record.samples.columns):
        return None
    return _efficiency_of(record.column("thrust_n"), record.column("current_a"),
                          record.column("voltage_v"))


class SeriesCache:
    """Decimated time plots by (folder, its stamp, columns): a long run is read once."""

    def __init__(self, size: int = 32) -> None:
        self.size = size
        self._items: OrderedDict[tuple[Path, float, int], dict[str, Any]] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, folder: Path, columns: int) -> dict[str, Any]:
        key = (Path(folder).resolve(), _stamp(Path(folder).resolve()), columns)
        with self._lock:
            if key in self._items:
                self._items.move_to_end(key)
                return self._items[key]
        out = series_of(key[0], columns)
        with self._lock:
            self._items[key] = out
            while len(self._items) > self.size:
                self._items.popitem(last=False)
        return out


def series_of(folder: Path, columns: int = 1500) -> dict[str, Any]:
    """Every time plot of ``PLOTS`` the run has, min/max-decimated to ``columns`` bins;
    reads only those columns, and reduces them a chunk of rows at a time while they are
    read (``analysis.run_record.ColumnChunks``): a 5 M-row run holds one chunk in memory."""
    from analysis.run_record import ColumnChunks

    flight_cols = [c for *_, traces in FLIGHT_PLOTS for c, _ in traces]
    chunks = ColumnChunks(folder, [k for k, _, _ in PLOTS if k != "efficiency_g_w"]
                          + flight_cols)
    keys = list(chunks.names)
    need_eff = ("thrust_n", "current_a", "voltage_v")
    if set(need_eff) <= set(keys):
        keys.append("efficiency_g_w")
    bins = Bins(chunks.t, columns)
    envelopes = {k: MinMaxEnvelope(bins) for k in keys}
    for chunk in chunks:
        if "efficiency_g_w" in envelopes:
            chunk["efficiency_g_w"] = _efficiency_of(*(chunk[k] for k in need_eff))
        for k, envelope in envelopes.items():
            envelope.add(chunk[k])
    points = {k: envelope.points() for k, envelope in envelopes.items()}
    plots = {k: _plot(k, *points[k]) for k, _, _ in PLOTS if k in points}
    out = [plots[k] for k, _, _ in PLOTS if plots.get(k) is not None]
    for key, title, unit, traces in FLIGHT_PLOTS:
        lines = [{"name": name, "t": _json_list(points[c][0]), "y": _json_list(points[c][1])}
                 for c, name in traces if c in points and np.isfinite(points[c][1]).any()]
        if lines:  # the first trace as the plot's own, as a one-trace plot has it
            out.append({"key": key, "title": title, "unit": unit, "t": lines[0]["t"],
                        "y": lines[0]["y"], "traces": lines})
    return {"rows": int(chunks.t.size), "columns": columns, "plots": out}


def _plot(key: str, t: np.ndarray, y: np.ndarray) -> dict[str, Any] | None:
    """One time plot (None for a column without a finite value)."""
    if not np.isfinite(y).any():
        return None
    title, unit = next((ti, u) for k, ti, u in PLOTS if k == key)
    return {"key": key, "title": title, "unit": unit, "t": _json_list(t), "y": _json_list(y)}


def _json_list(a: np.ndarray) -> list[float | None]:
    a = np.round(np.asarray(a, dtype=float), 6)
    return [None if not math.isfinite(v) else v for v in a.tolist()]


def fits_of(record: RunRecord) -> dict[str, Any]:
    """The run's step fit (first-order-plus-delay per edge) and static curves, each with
    the reason when it does not apply (a sweep has no steps, a step run few speeds)."""
    from analysis.static_curves import fit_static_run
    from analysis.step_response import fit_run

    out: dict[str, Any] = {}
    try:
        out["step"] = json_safe(fit_run(record).summary())
    except LogError as exc:
        out["step_why"] = str(exc)
    try:
        out["static"] = json_safe(fit_static_run(record).summary())
    except LogError as exc:
        out["static_why"] = str(exc)
    return out


EdgesOf = Callable[[str], list[Any]]


def command_edges(record: RunRecord) -> EdgesOf:
    """The command jumps of ``record`` by command column, each found once (the compare
    page needs them for its static curves and for its step responses)."""
    from analysis.run_record import event_times
    from analysis.step_response import detect_edges

    found: dict[str, list[Any]] = {}

    def edges(command: str) -> list[Any]:
        if command not in found:
            found[command] = detect_edges(record.column("t_s"), record.column(command), None,
                                          event_times(record))
        return found[command]
    return edges


def _steady(record: RunRecord, edges: list[Any], settle_s: float = 0.3) -> np.ndarray:
    """Samples that are not within ``settle_s`` after a command jump: the plateaus of a
    step run after its transients, and all of a slow sweep (a ramp has no jumps)."""
    t = record.column("t_s")
    keep = np.ones(t.size, bool)
    for e in edges:
        keep[(t >= e.t_s) & (t < e.t_s + settle_s)] = False
    return keep


def static_points(record: RunRecord, bins: int = 40, edges: EdgesOf | None = None
                  ) -> dict[str, Any]:
    """Binned static curves for overlays: thrust vs speed, current and efficiency vs thrust,
    from the steady samples only (a step run's transients are not a static curve)."""
    from analysis.static_curves import binned_medians

    cols = set(record.samples.columns)
    out: dict[str, Any] = {"run_id": record.id}
    command = next((c for c in ("throttle_us", "duty_pct") if c in cols), None)
    t = record.column("t_s")
    edges = edges or command_edges(record)
    keep = _steady(record, edges(command)) if command else np.ones(t.size, bool)
    out["steady_samples"] = int(keep.sum())

    def col(name: str) -> np.ndarray:
        return record.column(name)[keep]

    if {"thrust_n", "rpm"} <= cols:
        x, ys = binned_medians(col("rpm"), {"thrust_n": col("thrust_n")}, bins)
        out["thrust_vs_rpm"] = {"x": _json_list(x), "y": _json_list(ys["thrust_n"])}
    if "thrust_n" in cols:
        ys_in = {k: col(k) for k in ("current_a",) if k in cols}
        eff = _efficiency(record)
        if eff is not None:
            ys_in["efficiency_g_w"] = eff[keep]
        if ys_in:
            x, ys = binned_medians(col("thrust_n"), ys_in, bins)
            for k, v in ys.items():
                out[f"{k}_vs_thrust"] = {"x": _json_list(x), "y": _json_list(v)}
    return out


def step_traces(record: RunRecord, pre_s: float = 0.05, post_s: float = 0.5,
                columns: int = 400, edges: EdgesOf | None = None) -> dict[str, Any]:
    """The mean rising and falling responses of the run, each normalised 0 -> 1."""
    cols = record.samples.columns
    signal = "thrust_n" if "thrust_n" in cols else "rpm" if "rpm" in cols else None
    command = next((c for c in ("throttle_us", "thrust_setpoint_n", "duty_pct") if c in cols),
                   None)
    if signal is None or command is None:
        return {"run_id": record.id, "why": "no command and response columns"}
    t, y = record.column("t_s"), record.column(signal)
    jumps = (edges or command_edges(record))(command)
    grid = np.linspace(-pre_s, post_s, columns)
    out: dict[str, Any] = {"run_id": record.id, "signal": signal, "t": _json_list(grid)}
    for direction in ("up", "down"):
        traces = []
        for e in [e for e in jumps if e.direction == direction][:50]:
            seg = np.interp(e.t_s + grid, t, y)
            lo, hi = np.median(seg[grid < 0]), np.median(seg[-columns // 10:])
            if abs(hi - lo) > 1e-9:
                traces.append((seg - lo) / (hi - lo))
        if traces:
            out[direction] = _json_list(np.mean(traces, axis=0))
            out[f"{direction}_edges"] = len(traces)
    if "up" not in out and "down" not in out:
        return {"run_id": record.id, "why": "no command edges with a response (not a step run)"}
    return out


def export_of(record: RunRecord, target: str) -> dict[str, Any]:
    """What ``rotorbench export TARGET RUN --json`` prints, for one run folder."""
    from analysis.exports import export_params

    return json_safe(export_params(target, record))


def calibration_view(meta: dict[str, Any]) -> dict[str, Any] | None:
    """A calibration run's record for its page (gain +- U, characteristics, acceptance,
    budget), None for other runs or a record not in the shape ``calibrate-sensors``
    writes (a run.json is other people's input: nothing in it is trusted to be numbers)."""
    rec = meta.get("calibration") if meta.get("kind") == "calibration" else None
    if not isinstance(rec, dict):
        return None
    try:
        res, acc = rec["result"], rec["acceptance"]
        gain, u = float(res["scale"]), float(res["u_scale"])
        chars = {str(k).replace("_", " "): f"{float(v) * 100:.3g} %"
                 for k, v in res["characteristics_fraction_of_full_scale"].items()}
        budget = [(str(t["name"]), str(t["type"]), f"{float(t['u']) * 100:.4f} %")
                  for t in res["scale_budget"]["budget"]]
        return {"gain": f"{gain:.6g} +- {2 * u:.2g} (k = 2)",
                "offset": f"{float(res['offset']):.5g}",
                "channel": str(rec["applies"]["channel"]),
                "characteristics": chars, "budget": budget,
                "combined": f"{float(res['scale_budget']['u']) * 100:.4f} %",
                "passed": bool(acc["passed"]), "failed": [str(f) for f in acc["failed"]],
                "valid_until": str(rec["valid_until_utc"]),
                "operator": str(rec.get("operator") or ""),
                "gravity": str(rec["gravity"]["source"])}
    except (KeyError, TypeError, ValueError, AttributeError):
        return None
