"""Live plots of the console: eight channels against time, min/max envelope per pixel
column (spikes stay visible), pause, zoom (pyqtgraph's mouse), cursor readout, and a
count of the frames actually painted (the refresh rate the self-test prints)."""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import pyqtgraph as pg
from pyqtgraph.Qt import QtCore, QtWidgets

from bench.console.envelope import RollingEnvelope
from bench.live import RingBuffer
from bench.qt.stacked_axes import stacked_axes

__all__ = ["PLOT_CHANNELS", "LivePlots", "derived"]

# (key, title, unit); power and efficiency are derived from the recorded columns
PLOT_CHANNELS = (
    ("throttle_us", "command", "us"),
    ("thrust_n", "thrust", "N"),
    ("torque_nm", "torque", "N m"),
    ("current_a", "current", "A"),
    ("voltage_v", "voltage", "V"),
    ("rpm", "speed", "rpm"),
    ("power_w", "power", "W"),
    ("efficiency_n_w", "efficiency", "N/W"),
)
MIN_POWER_W = 1.0  # below this the efficiency is noise over noise: not drawn
#: Channels a sensor of the rig records; one without any sample while rows arrive says so
#: in its plot (a rig without a torque sensor left the torque plot blank).
SENSOR_CHANNELS = ("thrust_n", "torque_nm", "current_a", "voltage_v", "rpm")


def derived(snap: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Electrical power P = V I and static efficiency thrust / P (N/W), vectorised."""
    power = snap["voltage_v"] * snap["current_a"]
    with np.errstate(invalid="ignore", divide="ignore"):
        eff = np.where(power > MIN_POWER_W, snap["thrust_n"] / power, np.nan)
    return {**snap, "power_w": power, "efficiency_n_w": eff}


class _PaintCounter(QtCore.QObject):
    """Counts paint events of a widget: frames that reached the screen (or offscreen
    surface), not merely timer ticks."""

    def __init__(self) -> None:
        super().__init__()
        self.stamps: list[float] = []

    def eventFilter(self, _obj: Any, event: Any) -> bool:
        if event.type() == QtCore.QEvent.Type.Paint:
            self.stamps.append(time.monotonic())
        return False


class _EnvelopeCurve(pg.PlotCurveItem):
    """A curve whose bounds are set with its data: PlotCurveItem recomputes them (with
    pen-width corrections in pixels) several times per paint, which was a third of the
    frame time with eight plots."""

    def __init__(self, pen: Any) -> None:
        super().__init__(pen=pen, skipFiniteCheck=True)
        self._rect = QtCore.QRectF()

    def set_envelope(self, x: np.ndarray, y: np.ndarray) -> None:
        finite = np.isfinite(y)
        if finite.any():
            y0, y1 = float(y[finite].min()), float(y[finite].max())
            self._rect = QtCore.QRectF(float(x[0]), y0, float(x[-1] - x[0]), y1 - y0)
            self.prepareGeometryChange()
            self.setData(x, y, connect="all" if finite.all() else "finite")
        elif self.xData is None or len(self.xData):
            self._rect = QtCore.QRectF()
            self.prepareGeometryChange()
            self.setData(np.empty(0), np.empty(0))

    def boundingRect(self) -> Any:
        return self._rect

    def dataBounds(self, ax: int, frac: float = 1.0, orthoRange: Any = None) -> Any:
        r = self._rect
        return (r.left(), r.right()) if ax == 0 else (r.top(), r.bottom())


class LivePlots(QtWidgets.QWidget):
    """The plot grid, fed from the shared ring on a timer."""

    def __init__(self, ring: RingBuffer, window_s: float = 5.0, frame_ms: int = 10) -> None:
        super().__init__()
        self.ring = ring
        self.window_s = window_s
        self.paused = False
        self.graphics = pg.GraphicsLayoutWidget()
        self.graphics.setBackground("k")
        self.plots: dict[str, Any] = {}
        self.curves: dict[str, Any] = {}
        first = None
        for i, (key, title, unit) in enumerate(PLOT_CHANNELS):
            # a PlotItem hands its ViewBox's methods on at run time, which its stubs omit
            # no context menu: not built at all (its forms were a third of a window's start)
            plot: Any = self.graphics.ci.addPlot(row=i // 2, col=i % 2, enableMenu=False)
            plot.setLabel("left", title, units=unit)
            # x is time relative to the newest row: a fixed range, so the time axes are
            # drawn once; y ranges move in steps (_fit_y). Unchanged axes are blitted from
            # a pixmap: axis text dominated the frame time on the offscreen platform.
            plot.setXRange(-window_s, 0.0, padding=0.0)
            plot.enableAutoRange(x=False, y=False)
            bottom_row = i >= len(PLOT_CHANNELS) - 2  # one time axis per column, at the bottom
            for axis in stacked_axes(plot, ("time - now", "s") if bottom_row else None):
                axis.enableAutoSIPrefix(False)
            if first is None:
                first = plot
            else:
                plot.setXLink(first)
            self.plots[key] = plot
            self.curves[key] = self._curve(plot, pg.mkPen("y" if key == "throttle_us" else "c"))
        self.no_data = {key: self._note(self.plots[key], f"no {title} sensor on this rig")
                        for key, title, _ in PLOT_CHANNELS if key in SENSOR_CHANNELS}
        self.curves["thrust_setpoint_n"] = self._curve(
            self.plots["thrust_n"], pg.mkPen("m", style=QtCore.Qt.PenStyle.DashLine))
        self.readout = QtWidgets.QLabel("cursor: -")
        self.pause_button = QtWidgets.QPushButton("Pause")
        self.pause_button.setCheckable(True)
        self.pause_button.setFocusPolicy(QtCore.Qt.FocusPolicy.NoFocus)
        self.pause_button.toggled.connect(self.set_paused)
        bar = QtWidgets.QHBoxLayout()
        bar.addWidget(self.pause_button)
        bar.addWidget(self.readout, 1)
        layout = QtWidgets.QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addLayout(bar)
        layout.addWidget(self.graphics, 1)
        self.counter = _PaintCounter()
        self.graphics.viewport().installEventFilter(self.counter)
        self.refreshes = 0
        self._env: RollingEnvelope | None = None
        self._total = 0
        self._yrange: dict[str, tuple[float, float]] = {}
        # pyqtgraph's scene is its GraphicsScene; its stubs give Qt's QGraphicsScene
        self.graphics.scene().sigMouseMoved.connect(  # pyright: ignore[reportAttributeAccessIssue]
            self._cursor)
        self.timer = QtCore.QTimer(self)
        self.timer.timeout.connect(self.refresh)
        self.timer.start(frame_ms)

    @staticmethod
    def _curve(plot: Any, pen: Any) -> Any:
        """A bare curve item: the envelope is already one point pair per pixel column,
        so PlotDataItem's downsampling and clipping would only cost time."""
        curve = _EnvelopeCurve(pen)
        plot.addItem(curve)
        return curve

    @staticmethod
    def _note(plot: Any, text: str) -> Any:
        """A hidden line of text centred on the plot's area, fixed in pixels."""
        item = pg.TextItem(text, color=(200, 200, 200), anchor=(0.5, 0.5))
        item.setParentItem(plot.vb)
        item.hide()

        def centre(*_: Any) -> None:
            item.setPos(plot.vb.width() / 2.0, plot.vb.height() / 2.0)

        plot.vb.sigResized.connect(centre)
        centre()
        return item

    def set_paused(self, paused: bool) -> None:
        """Paused: the curves hold still so they can be zoomed and read."""
        self.paused = paused
        self.pause_button.setText("Resume" if paused else "Pause")
        if not paused:
            for plot in self.plots.values():
                plot.setXRange(-self.window_s, 0.0, padding=0.0)
            self._yrange.clear()

    def _columns(self) -> int:
        """One envelope column per pixel of a plot's width."""
        vb = self.plots["thrust_n"].vb
        return max(int(vb.width()), 50)

    def refresh(self) -> None:
        if self.paused or not self.isVisible():
            return
        total, rows = self.ring.tail(max(self.ring.total - self._total, 0))
        self._total = total
        t = rows["t_s"]
        columns = self._columns()
        env = self._env
        restart = env is None or env.columns != columns or (t.size and t[0] < env.t_last)
        if restart:  # a new run (its clock starts at 0) or a resized plot: all rows again
            total, rows = self.ring.tail(self.ring.capacity)
            self._total, t = total, rows["t_s"]
            env = self._env = RollingEnvelope(tuple(self.curves), columns,
                                              self.window_s / columns)
            start = np.flatnonzero(np.diff(t) < 0)  # only the newest run's rows
            if start.size:
                rows = {k: v[start[-1] + 1:] for k, v in rows.items()}
                t = rows["t_s"]
        if t.size == 0:
            return
        assert env is not None  # a restart made one
        env.update(t, derived(rows))
        x, ys = env.lines()
        for key, curve in self.curves.items():
            curve.set_envelope(x, ys[key])
        for key, note in self.no_data.items():
            note.setVisible(not np.isfinite(ys[key]).any())
        for key, plot in self.plots.items():
            y = ys[key]
            if key == "thrust_n":
                y = np.concatenate([y, ys["thrust_setpoint_n"]])
            self._fit_y(key, plot, y)
        self.refreshes += 1

    def _fit_y(self, key: str, plot: Any, y: np.ndarray) -> None:
        """Grow the y range at once to show every sample (strictly inside: a line on the
        edge would be clipped), shrink it only when the data uses less than a third of it;
        ranges snap to a grid so the axis rarely redraws."""
        finite = y[np.isfinite(y)]
        if finite.size == 0:
            return
        lo, hi = float(finite.min()), float(finite.max())
        span = max(hi - lo, 1e-3 * max(abs(hi), abs(lo)), 1e-6)
        cur = self._yrange.get(key)
        if cur is not None and cur[0] < lo and hi < cur[1] and \
                (hi - lo) >= (cur[1] - cur[0]) / 3:
            return
        step = 10.0 ** np.floor(np.log10(span))
        new = (float(np.floor(lo / step - 0.5) * step), float(np.ceil(hi / step + 0.5) * step))
        self._yrange[key] = new
        plot.setYRange(*new, padding=0.0)

    def frames_per_s(self, since: float, until: float | None = None) -> float:
        """Painted frames per second between two ``time.monotonic()`` stamps."""
        until = time.monotonic() if until is None else until
        n = sum(1 for s in self.counter.stamps if since <= s <= until)
        return n / max(until - since, 1e-9)

    def _cursor(self, pos: Any) -> None:
        for key, plot in self.plots.items():
            if plot.sceneBoundingRect().contains(pos):
                _, snap = self.ring.tail(self.ring.capacity)
                if snap["t_s"].size == 0:
                    return
                snap = derived(snap)
                x = plot.vb.mapSceneToView(pos).x() + snap["t_s"][-1]  # x: time - newest
                i = int(np.clip(np.searchsorted(snap["t_s"], x), 0, len(snap["t_s"]) - 1))
                vals = ", ".join(f"{title} {snap[k][i]:.4g} {unit}"
                                 for k, title, unit in PLOT_CHANNELS if k in snap)
                self.readout.setText(f"cursor t = {snap['t_s'][i]:.4f} s: {vals}")
                self.plots[key].setTitle(None)
                return
