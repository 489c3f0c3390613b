"""The console window's process: checks the binding, shows the window, and (``--selftest``)
drives it like an operator: arm, throttle to 30 %, hold, stop, screenshot, frame rate."""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import sys
import time
import traceback
from pathlib import Path
from typing import Any

__all__ = ["run_selftest", "window_main"]


def window_main(gui_args: tuple[Any, ...], out: str, selftest: dict[str, Any] | None,
                window_s: float) -> None:
    """Entry point of the spawned window process."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is for the bench process
    from bench.console.link import GuiLink
    from bench.live import _qt_binding_missing, binding_fault

    link = GuiLink(*gui_args)
    problem = _qt_binding_missing() or binding_fault()
    if problem is not None:
        link.send("fatal", problem.replace("--live", "console"))
        return
    import pyqtgraph as pg
    from pyqtgraph.Qt import QtCore

    from bench.console.window import ConsoleWindow
    from bench.qt.qt_messages import filter_qt_messages

    def crash(kind: Any, value: Any, tb: Any) -> None:
        # an exception in a Qt slot would otherwise be printed and forgotten; the window
        # ends instead, so the bench sees it crash and stops any run
        traceback.print_exception(kind, value, tb)
        os._exit(3)

    sys.excepthook = crash
    filter_qt_messages()
    app = pg.mkQApp("rotorbench console")
    win = ConsoleWindow(link, Path(out), window_s=window_s)
    win.show()
    parent = mp.parent_process()

    def watch_parent() -> None:
        if (parent is not None and not parent.is_alive()) or win.bench_gone:
            app.quit()

    watcher = QtCore.QTimer()
    watcher.timeout.connect(watch_parent)
    watcher.start(200)
    if selftest is not None:
        def drive() -> None:
            try:
                result = run_selftest(win, **selftest)
            except Exception as exc:  # reported to the bench, which fails the self-test
                result = {"ok": False, "problem": f"{type(exc).__name__}: {exc}"}
            link.send("selftest", result)
            win.close()

        QtCore.QTimer.singleShot(0, drive)
    app.exec()


def run_selftest(win: Any, screenshot: str, throttle: float = 0.3, hold_s: float = 3.0,
                 timeout_s: float = 60.0) -> dict[str, Any]:
    """Arm, move the throttle to ``throttle``, hold ``hold_s`` once reached, stop, save a
    screenshot; returns what happened and the painted frames per second while it ran."""
    def fail(problem: str) -> dict[str, Any]:
        refused = f" (refused: {'; '.join(win.errors)})" if win.errors else ""
        return {"ok": False, "problem": problem + refused, "state": win.state}

    if not win.wait_for(lambda: bool(win.rig), timeout_s):
        return fail("no rig description from the bench")
    win.wait_for(lambda: False, 1.0)  # the console is open: its first paints are done
    win.arm_button.click()
    if not win.wait_for(lambda: win.state.get("manual") or win.finished, timeout_s):
        return fail("the manual session did not start")
    if win.finished:
        return fail(f"the run ended: {win.finished[-1]['reason']}")
    win.control.set_fraction(throttle)
    t_move = time.monotonic()
    target = win.state.get("target_us", 0.0)
    reached = win.wait_for(lambda: win.finished or (abs(
        win.state.get("command_us", 0.0) - win.state.get("target_us", -1.0)) < 0.5
        and win.state.get("target_us", 0.0) > target), timeout_s)
    if not reached or win.finished:
        return fail("the throttle did not reach its target")
    win.wait_for(lambda: bool(win.finished), hold_s)
    if win.finished:
        return fail(f"the run ended during the hold: {win.finished[-1]['reason']}")
    t_stop = time.monotonic()
    fps = win.frames_per_s(t_move, t_stop)
    command = win.state.get("command_us")
    win.stop_button.click()
    if not win.wait_for(lambda: bool(win.finished), timeout_s):
        return fail("the run did not end after stop")
    win.wait_for(lambda: False, 0.3)  # let the last frame and the banner paint
    image = win.grab()
    Path(screenshot).parent.mkdir(parents=True, exist_ok=True)
    if not image.save(str(screenshot)):
        return fail(f"{screenshot}: could not save the screenshot")
    return {"ok": True, "frames_per_s": fps, "held_s": t_stop - t_move, "command_us": command,
            "screenshot": str(screenshot), "size": [image.width(), image.height()],
            "finished": win.finished[-1]}
