"""The wire-level simulated rigs against the plain simulated rig: fits and disconnect timing.

1. ``rotorbench step`` (Step 1, ``--repeats`` up/down steps) on sim.toml, sim-serial.toml and
   sim-can.toml, then ``rotorbench fit --json``: latency, tau up/down and gain per rig.
2. A hold at 1500 us through ``bench.plan_runner.session.run_sequence`` with a device failing after
   1.2 s (board unplugged, board silent, VESC gone, flight controller silent): the time
   from the backend's first DeviceError, or the runner's safe stop when its silence
   limit found it first (detection), to the plant's ESC at idle, and
   whether the rows up to the fault reached the run folder.

Real time: about 10 s per wire step run plus ~2 s per fault case.
Usage: .venv/bin/python benchmarks/wire_rigs.py [--repeats 5] [--trials 3]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import statistics
import tempfile
import time
from pathlib import Path

from rich.console import Console
from rich.table import Table

from analysis.run_record import read_run
from bench.cli import main
from bench.plan_runner.runner import RunOptions
from bench.plan_runner.session import run_sequence
from bench.plans.sequences import Arm, Disarm, Sequence, Tare, ThrottleStep
from bench.rig.rig import default_rig_path, load_rig
from drivers.errors import DeviceError
from drivers.factory import open_rig

RIGS = default_rig_path().parent
KILL_AT_S = 1.2


def step_fit(rig: str, repeats: int, out: Path) -> dict:
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        code = main(["step", "--rig", str(RIGS / f"{rig}.toml"), "--repeats", str(repeats),
                     "--out", str(out)])
    if code:
        raise SystemExit(f"step on {rig} failed ({code})")
    (run_dir,) = [p for p in out.iterdir() if p.is_dir()]
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        main(["fit", str(run_dir), "--json"])
    return json.loads(buf.getvalue())


class Watched:
    def __init__(self, dev, log):
        self._dev, self._log = dev, log

    def __getattr__(self, name):
        attr = getattr(self._dev, name)
        if name not in ("read_block", "set_pulse_us"):
            return attr

        def call(*a, **k):
            try:
                return attr(*a, **k)
            except DeviceError:
                self._log.setdefault("detected", time.monotonic())
                raise
        return call


def _vesc(r):
    return next(p for k, p in r.wire.peers.items() if k.endswith(":vesc:1"))


def _board(r):
    return r.wire.peers["serial:loadcell"]


FAULTS = {
    "board unplugged (sim-serial)": ("sim-serial", lambda r: _board(r).stop()),
    "board silent (sim-can)": ("sim-can", lambda r: _board(r).port.disconnect()),
    "VESC gone (sim-can)": ("sim-can", lambda r: _vesc(r).disconnect()),
    "FC replies stop (sim-serial)": ("sim-serial",
                                     lambda r: r.wire.peers["serial:msp"].port.disconnect()),
}


def fault_case(rig_name: str, fault, out: Path) -> dict:
    rig = load_rig(RIGS / f"{rig_name}.toml")
    seq = Sequence("hold", (Arm(0.2), Tare(0.3), ThrottleStep(1500.0, 3.0), Disarm()))
    log: dict = {}
    opened = []

    def opener(cfg, seed=None):
        r = open_rig(cfg, seed=seed)
        opened.append(r)
        r.sensors = {k: Watched(s, log) for k, s in r.sensors.items()}
        r.esc = Watched(r.esc, log)
        close = r.close

        def close_when_idle():
            end = time.monotonic() + 2.0
            while r.wire.plant.idle_since() is None and time.monotonic() < end:
                time.sleep(0.005)
            log["idle"] = r.wire.plant.idle_since()
            close()
        r.close = close_when_idle
        return r

    def on_progress(t, _total, _seg):
        if t >= KILL_AT_S and "fault" not in log:
            log["fault"], log["fault_t"] = time.monotonic(), t
            fault(opened[0])

    with contextlib.suppress(DeviceError):
        run_sequence(rig, seq, out, opener, options=RunOptions(tick_s=0.02),
                     on_progress=on_progress)
    (run_dir,) = [p for p in out.iterdir() if p.is_dir()]
    rec = read_run(run_dir)
    t = rec.column("t_s")
    if "detected" not in log:  # the runner's silence limit found it, not a backend: the
        # safe stop's run time, on the monotonic clock through the fault's
        stop_t = float(rec.events.loc[rec.events["kind"] == "safe_stop", "t_s"].iloc[0])
        log["detected"] = log["fault"] + stop_t - log["fault_t"]
    return {"detect_ms": (log["detected"] - log["fault"]) * 1e3,
            "idle_ms": (log["idle"] - log["detected"]) * 1e3 if log.get("idle") else None,
            "last_row_s": float(t[-1]), "reason": rec.meta["reason"]}


def main_() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--trials", type=int, default=3)
    args = ap.parse_args()
    console = Console(width=150)
    table = Table(title=f"Step 1 fits ({args.repeats} repeats, 0.5 s holds)")
    for col in ("rig", "latency ms", "tau up ms", "tau down ms", "gain", "wall s"):
        table.add_column(col)
    with tempfile.TemporaryDirectory() as tmp:
        for rig in ("sim", "sim-serial", "sim-can"):
            t0 = time.monotonic()
            f = step_fit(rig, args.repeats, Path(tmp) / rig)
            table.add_row(rig, f"{f['latency_ms']:.2f}", f"{f['tau_up_ms']:.2f}",
                          f"{f['tau_down_ms']:.2f}", f"{f['gain']:.4f}",
                          f"{time.monotonic() - t0:.1f}")
        console.print(table)
        table = Table(title=f"device fault at {KILL_AT_S} s of a 1500 us hold "
                            f"({args.trials} trials)")
        for col in ("fault", "fault->detect ms", "detect->ESC idle ms (max)", "last row s",
                    "recorded reason"):
            table.add_column(col)
        for k, (label, (rig, fault)) in enumerate(FAULTS.items()):
            res = [fault_case(rig, fault, Path(tmp) / f"fault{k}-{i}")
                   for i in range(args.trials)]
            idle = [r["idle_ms"] for r in res if r["idle_ms"] is not None]
            table.add_row(label, f"{statistics.median(r['detect_ms'] for r in res):.0f}",
                          f"{max(idle):.1f}" if len(idle) == len(res) else
                          f"not idle in {len(res) - len(idle)}/{len(res)}",
                          f"{min(r['last_row_s'] for r in res):.2f}",
                          res[0]["reason"][:70])
        console.print(table)


if __name__ == "__main__":
    main_()
