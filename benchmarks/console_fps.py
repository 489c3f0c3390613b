"""Console plot refresh: painted frames per second and the CPU one frame costs.

1. The cost of one frame (new rows folded into the min/max envelope, eight plots updated
   and painted) in CPU time, with 25 kHz rows arriving in 20 ms ticks as in a run: the
   frame rate one free core could sustain is 1000 / (ms per frame).
2. ``rotorbench console --selftest`` on the simulated rig, offscreen: the frames painted
   per second while the run records (bench and window in their own processes, competing
   for this machine's cores with whatever else runs). The load average is printed with it.

Usage: python benchmarks/console_fps.py [--runs N]
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")


def frame_cost(frames: int = 150, rate_hz: float = 25_000.0, tick_s: float = 0.02) -> dict:
    import numpy as np
    import pyqtgraph as pg

    from bench.console.link import BenchLink
    from bench.console.window import ConsoleWindow

    link = BenchLink(capacity=int(rate_hz * 6))
    app = pg.mkQApp()
    with tempfile.TemporaryDirectory() as out:
        win = ConsoleWindow(link.gui_link(), Path(out))
        for timer in (win.beat_timer, win.message_timer, win.slow_timer,
                      win.control.plots.timer):
            timer.stop()
        win.show()
        app.processEvents()
        plots, view = win.control.plots, win.control.plots.graphics.viewport()
        rng = np.random.default_rng(0)
        per_tick = int(rate_hz * tick_s)
        n, refresh_s, paint_s = 0, 0.0, 0.0
        for i in range(frames + 10):
            t = np.arange(n, n + per_tick) / rate_hz
            n += per_tick
            link.ring.push({"t_s": t, "throttle_us": 1300.0 + 0 * t,
                            "thrust_n": 2.0 + 0.1 * rng.normal(size=t.size),
                            "current_a": 5.0 + rng.normal(size=t.size),
                            "voltage_v": 11.1 + 0.01 * rng.normal(size=t.size),
                            "rpm": 6000.0 + 50 * rng.normal(size=t.size)})
            c0 = time.process_time()
            plots.refresh()
            c1 = time.process_time()
            view.repaint()
            c2 = time.process_time()
            if i >= 10:  # after the first frames (axis pictures, caches)
                refresh_s += c1 - c0
                paint_s += c2 - c1
        size = (win.width(), win.height())
        win.close()
    ms = 1e3 * (refresh_s + paint_s) / frames
    return {"refresh_ms": 1e3 * refresh_s / frames, "paint_ms": 1e3 * paint_s / frames,
            "frame_ms": ms, "one_core_fps": 1e3 / ms, "size": size}


def selftest_fps() -> tuple[float | None, str]:
    with tempfile.TemporaryDirectory() as out:
        proc = subprocess.run(
            [sys.executable, "-m", "bench.cli", "console", "--selftest", "--out", out,
             "--screenshot", str(Path(out) / "shot.png")],
            capture_output=True, text=True, check=False)
    found = re.search(r"^(\d+) frames/s", proc.stdout, re.M)
    verdict = proc.stdout.strip().splitlines()[-1] if proc.stdout.strip() else proc.stderr
    return (float(found.group(1)) if found else None), verdict


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3, help="self-test runs (default 3)")
    args = ap.parse_args()
    cost = frame_cost()
    print(f"one frame ({cost['size'][0]}x{cost['size'][1]} window, 8 plots, 25 kHz rows): "
          f"{cost['frame_ms']:.1f} ms CPU (envelope + data {cost['refresh_ms']:.1f} ms, "
          f"paint {cost['paint_ms']:.1f} ms) -> {cost['one_core_fps']:.0f} frames/s on one "
          "free core")
    for i in range(args.runs):
        load = os.getloadavg()[0]
        fps, verdict = selftest_fps()
        print(f"selftest {i + 1}: {fps if fps is not None else '?'} frames/s painted while "
              f"the run recorded (load average {load:.1f} on {os.cpu_count()} cores; "
              f"{verdict.strip()})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
