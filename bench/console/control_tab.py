"""The control tab: throttle (with the rig's thrust limit drawn on it), live plots and the
limits beside them (each editable only towards tighter)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pyqtgraph.Qt import QtCore, QtGui, QtWidgets

from bench.console.plots import LivePlots
from bench.engine.safety import LIMIT_FIELDS
from bench.live import RingBuffer

__all__ = ["ControlTab", "LimitsPanel", "ThrottleSlider"]

STEPS = 1000  # slider steps over 0..100 %
LOWER_BOUNDS = {"voltage_min_v"}  # tightening raises these
UNITS = {"thrust_n": "N", "current_a": "A", "rpm": "rpm", "voltage_min_v": "V",
         "voltage_max_v": "V", "temperature_c": "°C"}


class ThrottleSlider(QtWidgets.QSlider):
    """A vertical 0..100 % slider with a red mark where the static map reaches the rig's
    thrust limit."""

    def __init__(self) -> None:
        super().__init__(QtCore.Qt.Orientation.Vertical)
        self.setRange(0, STEPS)
        self.setSingleStep(10)  # arrow keys: 1 %
        self.setPageStep(100)  # page keys: 10 %
        self.setTickPosition(QtWidgets.QSlider.TickPosition.TicksBothSides)
        self.setTickInterval(100)
        self.limit_fraction: float | None = None
        self.setMinimumWidth(60)

    def paintEvent(self, event: Any) -> None:
        super().paintEvent(event)
        if self.limit_fraction is None:
            return
        painter = QtGui.QPainter(self)
        try:
            painter.setPen(QtGui.QPen(QtGui.QColor("red"), 3))
            y = int(self.height() * (1.0 - self.limit_fraction))
            painter.drawLine(0, y, self.width(), y)
        finally:
            painter.end()


class LimitsPanel(QtWidgets.QGroupBox):
    """One row per limit: rig value, value in force, a box that only allows tighter."""

    def __init__(self, request: Callable[[str, Any], None]) -> None:
        super().__init__("Limits (tighten only)")
        self.request = request
        self.rows: dict[str, tuple[QtWidgets.QLabel, QtWidgets.QDoubleSpinBox]] = {}
        grid = QtWidgets.QGridLayout(self)
        for r, name in enumerate(LIMIT_FIELDS):
            label = QtWidgets.QLabel(f"{name}: -")
            box = QtWidgets.QDoubleSpinBox()
            box.setDecimals(2)
            box.setRange(-1e6, 1e6)
            button = QtWidgets.QPushButton("Tighten")
            button.setFocusPolicy(QtCore.Qt.FocusPolicy.NoFocus)
            button.clicked.connect(lambda _=False, n=name: self.tighten(n))
            # the label has the panel's width to itself ("voltage_min_v: 10.35 V (rig 9.9)"
            # was cut to "voltage_min_v: 9 \" beside the box), the box and button below it
            grid.addWidget(label, 2 * r, 0, 1, 2)
            grid.addWidget(box, 2 * r + 1, 0)
            grid.addWidget(button, 2 * r + 1, 1)
            self.rows[name] = (label, box)
        self.values: dict[str, float] = {}

    def show_limits(self, limits: dict[str, float], rig_limits: dict[str, float]) -> None:
        for name, (label, box) in self.rows.items():
            value = limits.get(name)
            if value is None:
                label.setText(f"{name}: none")
                box.setEnabled(False)
                continue
            rig = rig_limits.get(name, value)
            label.setText(f"{name}: {value:g} {UNITS[name]}" +
                          (f" (rig {rig:g})" if rig != value else ""))
            if self.values.get(name) != value:
                box.blockSignals(True)
                if name in LOWER_BOUNDS:
                    box.setRange(value, 1e6)
                else:
                    box.setRange(-1e6 if name == "temperature_c" else 0.0, value)
                box.setValue(value)
                box.blockSignals(False)
            box.setEnabled(True)
        self.values = dict(limits)

    def tighten(self, name: str) -> None:
        self.request("tighten", (name, self.rows[name][1].value()))


class ControlTab(QtWidgets.QWidget):
    """Throttle | plots | limits."""

    def __init__(self, ring: RingBuffer, request: Callable[[str, Any], None],
                 window_s: float = 5.0, frame_ms: int = 10) -> None:
        super().__init__()
        self.request = request
        self.esc = {"idle_us": 1000.0, "min_us": 1000.0, "max_us": 2000.0}
        self.slider = ThrottleSlider()
        self.slider.valueChanged.connect(self._moved)
        self.throttle_label = QtWidgets.QLabel("0.0 %")
        self.command_label = QtWidgets.QLabel("command - us")
        self.limit_label = QtWidgets.QLabel("")
        self.limit_label.setStyleSheet("color: red")
        self.limit_label.setWordWrap(True)
        self.rate_label = QtWidgets.QLabel("")
        self.rate_label.setWordWrap(True)
        left = QtWidgets.QVBoxLayout()
        left.addWidget(QtWidgets.QLabel("Throttle"))
        left.addWidget(self.slider, 1, QtCore.Qt.AlignmentFlag.AlignHCenter)
        for w in (self.throttle_label, self.command_label, self.rate_label, self.limit_label):
            left.addWidget(w)
        left_box = QtWidgets.QWidget()
        left_box.setLayout(left)
        left_box.setFixedWidth(130)
        self.plots = LivePlots(ring, window_s=window_s, frame_ms=frame_ms)
        self.limits = LimitsPanel(request)
        self.limits.setFixedWidth(330)
        layout = QtWidgets.QHBoxLayout(self)
        layout.addWidget(left_box)
        layout.addWidget(self.plots, 1)
        layout.addWidget(self.limits)
        self._sending = True

    @property
    def fraction(self) -> float:
        return self.slider.value() / STEPS

    def set_fraction(self, fraction: float, send: bool = True) -> None:
        self._sending = send
        try:
            self.slider.setValue(round(fraction * STEPS))
        finally:
            self._sending = True

    def _moved(self, value: int) -> None:
        f = value / STEPS
        us = self._us(f)
        self.throttle_label.setText(f"{100 * f:.1f} % -> {us:.0f} us")
        if self._sending:
            self.request("throttle", f)

    def _us(self, f: float) -> float:
        e = self.esc
        return e["idle_us"] if f <= 0 else e["min_us"] + f * (e["max_us"] - e["min_us"])

    def show_rig(self, info: dict[str, Any]) -> None:
        self.esc = info["esc"]
        self.rate_label.setText(f"rate limit {info['rate_us_s']:g} us/s")
        cap = info.get("thrust_cap_us")
        e = self.esc
        if cap is not None and e["max_us"] > e["min_us"]:
            f = min(max((cap - e["min_us"]) / (e["max_us"] - e["min_us"]), 0.0), 1.0)
            self.slider.limit_fraction = f
            self.limit_label.setText(f"red mark: thrust limit {info['rig_limits']['thrust_n']:g}"
                                     f" N at {cap:.0f} us ({100 * f:.0f} %) on the map")
            self.slider.update()

    def show_state(self, state: dict[str, Any]) -> None:
        self.command_label.setText(f"command {state['command_us']:.0f} us")
        self.slider.setEnabled(bool(state.get("manual")))
