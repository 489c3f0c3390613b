"""Screenshots of each console tab for the README: docs/img/console-<tab>.png.

Runs offscreen on the simulated rigs, the bench on a thread of this process: a manual
session at 30 % (control tab), a device check (devices), a Step 1 plan under way (plans),
two runs overlaid (history), and on the simulated IMU bench a quick calibration (IMU).
Usage: python docs/make_console_screenshots.py
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
import threading
import time
from pathlib import Path

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
IMG = Path(__file__).resolve().parent / "img"


def main(img: Path = IMG) -> int:
    """The screenshots into ``img``; the runs they record go to a temporary folder that is
    removed afterwards, also when a step fails (it was left behind: 18 MB in /tmp)."""
    import pyqtgraph as pg

    from bench.qt.qt_messages import filter_qt_messages

    filter_qt_messages()
    _app = pg.mkQApp("rotorbench console")  # kept alive while the windows live
    out = Path(tempfile.mkdtemp(prefix="console-shots-"))
    try:
        return take_screenshots(out, img)
    finally:
        shutil.rmtree(out, ignore_errors=True)


def take_screenshots(out: Path, img: Path) -> int:
    """Drive the console on the simulated rigs (runs recorded under ``out``)."""
    from bench.console.link import BenchLink
    from bench.console.server import ConsoleBench
    from bench.console.window import ConsoleWindow
    from bench.rig.rig import default_rig_path, load_rig

    link = BenchLink(capacity=25_000 * 6)
    bench = ConsoleBench(load_rig(default_rig_path()), out, link)
    win = ConsoleWindow(link.gui_link(), out)
    win.resize(1280, 800)
    win.show()
    threading.Thread(target=bench.serve, daemon=True).start()
    img.mkdir(parents=True, exist_ok=True)

    def wait(predicate, timeout_s: float = 60.0) -> None:
        if not win.wait_for(predicate, timeout_s):
            raise SystemExit(f"screenshots: timed out waiting ({predicate.__doc__ or ''})")

    def shot(name: str) -> None:
        win.wait_for(lambda: False, 0.4)
        path = img / f"console-{name}.png"
        win.grab().save(str(path))
        print(path)

    wait(lambda: bool(win.rig))
    win.wait_for(lambda: False, 1.0)
    # control: a manual session at 30 %
    win.arm_button.click()
    wait(lambda: bool(win.state.get("manual")))
    win.control.set_fraction(0.3)
    wait(lambda: win.state.get("command_us") == 1300.0)
    win.wait_for(lambda: False, 3.0)
    shot("control")
    win.stop_button.click()
    wait(lambda: len(win.finished) == 1)
    # devices: a check, then the tare
    win.tabs.setCurrentWidget(win.devices)
    win.devices.check_button.click()
    wait(lambda: "check:" in win.devices.info.text())
    shot("devices")
    # plans: Step 1 under way
    win.tabs.setCurrentWidget(win.plans)
    win.plans.repeats.setValue(3)
    win.plans.hold.setValue(0.5)
    wait(lambda: "3 repeats" in win.plans.description.text())
    win.plans.start_button.click()
    wait(lambda: win.plans.progress.value() >= 45)
    shot("plans")
    wait(lambda: len(win.finished) == 2)
    # history: the manual session and the plan overlaid
    win.tabs.setCurrentWidget(win.history)
    win.history.refresh()
    win.history.select(0, 1)
    win.history.open_selected()
    shot("history")
    win.close()
    # IMU: the simulated IMU bench, a quick calibration done
    from bench.rig.rig import default_imu_rig_path, load_imu_rig

    imu_link = BenchLink(capacity=1000)
    imu_bench = ConsoleBench(load_imu_rig(default_imu_rig_path()), out / "imu", imu_link)
    win = ConsoleWindow(imu_link.gui_link(), out / "imu")
    win.resize(1280, 800)
    win.show()
    threading.Thread(target=imu_bench.serve, daemon=True).start()
    wait(lambda: bool(win.rig))
    win.imu.quick_button.click()
    wait(lambda: bool(win.finished), 600.0)
    shot("imu")
    win.close()
    time.sleep(0.5)
    return 0


if __name__ == "__main__":
    sys.exit(main())
