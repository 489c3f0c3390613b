"""CPU time of one frame of the live view (``rotorbench step --live``) while a run streams.

A 2500 Hz ring over the 10 s window, 50 new rows per frame (a 20 ms tick), redrawn and
painted offscreen. Prints the frame time as shipped (one time axis, axes blitted from a
pixmap while their range stands) and with every plot's time axis shown and no axis cache,
as before, and their ratio. Usage: ``QT_QPA_PLATFORM=offscreen python benchmarks/live_frame.py``.
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from bench.live import LIVE_CHANNELS, LiveView, RingBuffer

RATE_HZ, WINDOW_S, TICK_ROWS = 2500, 10.0, 50


def frame_ms(view: LiveView, ring: RingBuffer, t0: float, frames: int = 60) -> tuple[float, float]:
    """Mean CPU time of a frame (new rows, refresh, paint), and the next time to push."""
    cpu = time.process_time()
    t = t0
    for _ in range(frames):
        ts = t + np.arange(TICK_ROWS) / RATE_HZ
        ring.push({"t_s": ts, "throttle_us": 1500 + 300 * np.sign(np.sin(ts)),
                   "thrust_n": 3 + np.sin(3 * ts), "current_a": 5 + np.sin(2 * ts),
                   "rpm": 8000 + 500 * np.sin(ts)})
        t = ts[-1] + 1.0 / RATE_HZ
        view.refresh()
        view.win.repaint()
        view.app.processEvents()
    return (time.process_time() - cpu) / frames * 1e3, t


def main() -> int:
    names = ("t_s", *(c for c, _, _ in LIVE_CHANNELS))
    ring = RingBuffer(names, int(RATE_HZ * WINDOW_S))
    view = LiveView(ring, window_s=WINDOW_S, interval_ms=50)
    view.timer.stop()  # frames are driven here
    view.show()
    _, t = frame_ms(view, ring, 0.0, frames=int(WINDOW_S * RATE_HZ / TICK_ROWS))  # fill
    shipped, t = frame_ms(view, ring, t)
    from pyqtgraph.Qt import QtWidgets

    for plot in view.plots.values():
        plot.showAxis("bottom")
        for side in ("left", "bottom"):
            plot.getAxis(side).setCacheMode(QtWidgets.QGraphicsItem.CacheMode.NoCache)
    before, _ = frame_ms(view, ring, t)
    view.close()
    print(f"live view frame, {len(LIVE_CHANNELS)} plots, {int(RATE_HZ * WINDOW_S)} rows each")
    print(f"  as shipped:                          {shipped:6.1f} ms")
    print(f"  every time axis shown, no axis cache: {before:6.1f} ms")
    print(f"  ratio:                               {before / shipped:6.1f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
