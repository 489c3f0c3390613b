"""The console's main window: header (state, ARM, a large STOP, the trip banner) over the
tabs. Stop works from the button, Space and Esc anywhere in the window (an application
event filter sees the keys before any widget). The window beats the heartbeat from its GUI
thread: if that thread freezes, the bench stops the run."""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

from pyqtgraph.Qt import QtCore, QtGui, QtWidgets

from bench.console.control_tab import ControlTab
from bench.console.devices_tab import DevicesTab
from bench.console.history_tab import HistoryTab
from bench.console.imu_tab import ImuTab
from bench.console.link import HEARTBEAT_PERIOD_S, GuiLink
from bench.console.plans_tab import PlansTab

__all__ = ["ConsoleWindow"]

STOP_KEYS = (QtCore.Qt.Key.Key_Space, QtCore.Qt.Key.Key_Escape)
TAB_NAMES = ("control", "devices", "plans", "history", "imu")


class _StopKeys(QtCore.QObject):
    """Space and Esc mean stop wherever the focus is. The filter sees every event of the
    application (paints, timers), so anything but a key event is let through on a type
    check: reading each event's type made an enum object per event (about 5 % of the
    window's process while it painted a run)."""

    def __init__(self, stop: Any, parent: Any) -> None:
        super().__init__(parent)  # destroyed with its window, and with it the filter
        self.stop = stop

    def eventFilter(self, _obj: Any, event: Any) -> bool:
        if not isinstance(event, QtGui.QKeyEvent) or event.key() not in STOP_KEYS:
            return False
        kind = event.type()
        if kind not in (QtCore.QEvent.Type.KeyPress, QtCore.QEvent.Type.ShortcutOverride):
            return False
        if kind == QtCore.QEvent.Type.KeyPress and not event.isAutoRepeat():
            self.stop()
        return True


class ConsoleWindow(QtWidgets.QMainWindow):
    def __init__(self, link: GuiLink, out: Path, window_s: float = 5.0,
                 frame_ms: int = 10) -> None:
        super().__init__()
        self.link = link
        self.setWindowTitle("rotorbench console")
        self.resize(1100, 680)
        self.state: dict[str, Any] = {}
        self.rig: dict[str, Any] = {}
        self.finished: list[dict[str, Any]] = []
        self.errors: list[str] = []
        self.bench_gone = False
        # header
        self.status = QtWidgets.QLabel("waiting for the bench...")
        self.status.setStyleSheet("font-size: 14pt")
        self.arm_button = QtWidgets.QPushButton("ARM (manual)")
        self.arm_button.setMinimumHeight(50)
        self.arm_button.clicked.connect(self.arm)
        self.stop_button = QtWidgets.QPushButton("STOP  (Space / Esc)")
        self.stop_button.setMinimumSize(300, 60)
        self.stop_button.setStyleSheet(
            "QPushButton { background: #c00000; color: white; font-size: 18pt; "
            "font-weight: bold; border-radius: 6px; }")
        self.stop_button.clicked.connect(self.stop)
        for b in (self.arm_button, self.stop_button):
            b.setFocusPolicy(QtCore.Qt.FocusPolicy.NoFocus)
        self.banner = QtWidgets.QLabel("")
        self.banner.setWordWrap(True)
        self.banner.setStyleSheet("background: #ffd0d0; color: #800000; padding: 6px; "
                                  "font-weight: bold")
        self.banner.hide()
        header = QtWidgets.QHBoxLayout()
        header.addWidget(self.status, 1)
        header.addWidget(self.arm_button)
        header.addWidget(self.stop_button)
        # tabs
        self.control = ControlTab(link.ring, self.request, window_s=window_s, frame_ms=frame_ms)
        self.devices = DevicesTab(self.request)
        self.plans = PlansTab(self.request)
        self.history = HistoryTab(out)
        self.imu = ImuTab(out, self.request)
        self.tabs = QtWidgets.QTabWidget()
        for name, tab in zip(TAB_NAMES, (self.control, self.devices, self.plans, self.history,
                                         self.imu), strict=True):
            self.tabs.addTab(tab, name.upper() if name == "imu" else name.capitalize())
        body = QtWidgets.QWidget()
        layout = QtWidgets.QVBoxLayout(body)
        layout.addLayout(header)
        layout.addWidget(self.banner)
        layout.addWidget(self.tabs, 1)
        self.setCentralWidget(body)
        self._keys = _StopKeys(self.stop, self)
        app = QtWidgets.QApplication.instance()
        assert app is not None  # a window lives in the application
        app.installEventFilter(self._keys)
        # timers: heartbeat, messages, device values
        self.beat_timer = QtCore.QTimer(self)
        self.beat_timer.timeout.connect(link.beat)
        self.beat_timer.start(int(HEARTBEAT_PERIOD_S * 1000))
        link.beat()
        self.message_timer = QtCore.QTimer(self)
        self.message_timer.timeout.connect(self.poll)
        self.message_timer.start(30)
        self.slow_timer = QtCore.QTimer(self)
        self.slow_timer.timeout.connect(self._slow)
        self.slow_timer.start(500)
        self.history.refresh()
        self.request("hello")

    # -- requests -----------------------------------------------------------------------

    def request(self, kind: str, payload: Any = None) -> None:
        self.link.send(kind, payload)

    def arm(self) -> None:
        self.banner.hide()
        self.control.set_fraction(0.0, send=False)
        self.request("arm")
        self.tabs.setCurrentWidget(self.control)
        self.control.slider.setFocus()

    def stop(self) -> None:
        """Stop: ESC idle and disarmed (the bench decides; this only asks, at once)."""
        self.request("stop")
        self.control.set_fraction(0.0, send=False)

    def closeEvent(self, event: Any) -> None:
        self.request("closed")  # the bench stops any run (it also sees the process end)
        event.accept()
        self._release_keys()

    def _release_keys(self) -> None:
        """A closed window no longer filters every event of the application: a filter
        left installed until garbage collection taxed each event of the windows opened
        after it (about half of their construction time)."""
        app = QtWidgets.QApplication.instance()
        if app is not None:
            app.removeEventFilter(self._keys)

    # -- messages -----------------------------------------------------------------------

    def poll(self) -> None:
        for kind, payload in self.link.receive():
            if kind == "state":
                self.show_state(payload)
            elif kind == "rig":
                self.rig = payload
                self.control.show_rig(payload)
                self.devices.show_rig(payload)
                self.imu.show_rig(payload)
                if payload.get("kind") == "imu":
                    self.arm_button.setEnabled(False)
                    self.tabs.setCurrentWidget(self.imu)
                self.show_state(self.state or {"limits": payload["rig_limits"], "busy": False,
                                               "command_us": payload["esc"]["idle_us"]})
                self.plans.preview()
            elif kind == "finished":
                self.show_finished(payload)
            elif kind == "devices":
                self.devices.show_reports(payload)
            elif kind == "cell_prompt":
                self.devices.show_prompt(payload)
            elif kind == "preview":
                self.plans.show_preview(payload)
            elif kind == "error":
                self.errors.append(payload)
                self.status.setText(f"refused: {payload}")
            elif kind == "bench_gone":
                self.bench_gone = True
                self.status.setText("the bench process is gone")

    def show_state(self, state: dict[str, Any]) -> None:
        self.state = state
        if self.rig:
            self.control.limits.show_limits(state["limits"], self.rig["rig_limits"])
        self.control.show_state(state)
        self.plans.show_state(state)
        self.imu.show_state(state)
        if state.get("busy"):
            arm = "ARMED" if state.get("armed") else "disarmed"
            self.status.setText(f"{state['kind']} run: {arm}, command "
                                f"{state['command_us']:.0f} us")
        elif not self.status.text().startswith("refused"):
            self.status.setText(f"idle (ESC idle, disarmed) - rig {self.rig.get('name', '?')}")
        self.arm_button.setEnabled(not state.get("busy") and self.rig.get("kind") != "imu")
        self.plans.start_button.setEnabled(not state.get("busy"))

    def show_finished(self, info: dict[str, Any]) -> None:
        self.finished.append(info)
        self.control.set_fraction(0.0, send=False)
        self.status.setText(f"{info['kind']} run {info['status']}: {info['reason']}")
        trip = info.get("trip")
        if trip:
            sample = ", ".join(f"{k}={v:.4g}" for k, v in trip["sample"].items()
                               if isinstance(v, float) and math.isfinite(v))
            self.banner.setText(f"LIMIT TRIP - {trip['message']}. ESC idle and disarmed. "
                                f"Tripping sample: {sample}")
            self.banner.show()
        elif info["status"] != "success":
            self.banner.setText(f"RUN {info['status'].upper()} - {info['reason']}")
            self.banner.show()
        if info["kind"] == "tare":
            self.devices.show_tare(info)
        if info["kind"] == "cell calibration":
            self.devices.show_calibration(info)
        if info["kind"] == "calibration":
            self.imu.show_finished(info)
        self.plans.show_finished(info)
        self.history.refresh()
        self.imu.refresh()

    def _slow(self) -> None:
        _, newest = self.link.ring.tail(1)
        last = {k: float(v[-1]) for k, v in newest.items() if v.size}
        self.devices.show_last(last, bool(self.state.get("busy")))

    def frames_per_s(self, since: float, until: float | None = None) -> float:
        return self.control.plots.frames_per_s(since, until)

    def wait_for(self, predicate: Any, timeout_s: float) -> bool:
        """Process events until ``predicate()`` (self-test and docs script)."""
        app = QtWidgets.QApplication.instance()
        assert app is not None  # a window lives in the application
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            app.processEvents(QtCore.QEventLoop.ProcessEventsFlag.AllEvents, 20)
            if predicate():
                return True
            time.sleep(0.002)
        return bool(predicate())
