"""The history tab: the run index as a table (filter by rig, motor, propeller, status),
open a run, overlay two, the last fit and the export buttons.

Fits, reports and exports are the CLI's own commands (``rotorbench fit/report/export``)
run as child processes (``QProcess``): the window never blocks on them, so its heartbeat
keeps beating and a running motor is never stopped because a fit took a second."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path
from typing import Any

import pyqtgraph as pg
from pyqtgraph.Qt import QtCore, QtWidgets

from bench.console.envelope import envelope
from bench.store.run_index import RunIndex, RunRow

__all__ = ["HistoryTab"]

HEADERS = ("id", "started (UTC)", "rig", "sequence", "motor", "propeller", "status", "reason")
FILTERS = ("rig", "motor", "propeller", "status")
COLORS = ("c", "y")


def _cli() -> list[str]:
    exe = shutil.which("rotorbench")
    return [exe] if exe else [sys.executable, "-m", "bench.cli"]


class HistoryTab(QtWidgets.QWidget):
    def __init__(self, out: Path) -> None:
        super().__init__()
        self.out = Path(out)
        self.rows: list[RunRow] = []
        self.shown: list[RunRow] = []
        self.filters: dict[str, QtWidgets.QComboBox] = {}
        bar = QtWidgets.QHBoxLayout()
        for name in FILTERS:
            box = QtWidgets.QComboBox()
            box.addItem(f"any {name}", None)
            box.currentIndexChanged.connect(self._fill)
            bar.addWidget(box)
            self.filters[name] = box
        self.refresh_button = QtWidgets.QPushButton("Refresh")
        self.refresh_button.clicked.connect(self.refresh)
        bar.addWidget(self.refresh_button)
        bar.addStretch(1)
        self.table = QtWidgets.QTableWidget(0, len(HEADERS))
        self.table.setHorizontalHeaderLabels(HEADERS)
        self.table.horizontalHeader().setStretchLastSection(True)
        self.table.setEditTriggers(QtWidgets.QAbstractItemView.EditTrigger.NoEditTriggers)
        self.table.setSelectionBehavior(QtWidgets.QAbstractItemView.SelectionBehavior.SelectRows)
        self.table.doubleClicked.connect(lambda _i: self.open_selected())
        actions = QtWidgets.QHBoxLayout()
        self.buttons: dict[str, QtWidgets.QPushButton] = {}
        for key, text in (("open", "Open / overlay (select 1-2)"), ("fit", "Fit (last step run)"),
                          ("report", "Report"), ("ardupilot", "ArduPilot"), ("px4", "PX4"),
                          ("gazebo", "Gazebo")):
            b = QtWidgets.QPushButton(text)
            b.setFocusPolicy(QtCore.Qt.FocusPolicy.NoFocus)
            actions.addWidget(b)
            self.buttons[key] = b
        self.buttons["open"].clicked.connect(self.open_selected)
        self.buttons["fit"].clicked.connect(self.fit_last)
        self.buttons["report"].clicked.connect(self.report)
        for target in ("ardupilot", "px4", "gazebo"):
            self.buttons[target].clicked.connect(lambda _=False, t=target: self.export(t))
        self.plot = pg.PlotWidget()
        self.plot.setLabel("left", "thrust", units="N")
        self.plot.setLabel("bottom", "time", units="s")
        self.plot.addLegend()
        self.fit_label = QtWidgets.QLabel("last fit: -")
        self.fit_label.setWordWrap(True)
        self.output = QtWidgets.QPlainTextEdit()
        self.output.setReadOnly(True)
        self.output.setMaximumHeight(90)
        split = QtWidgets.QSplitter(QtCore.Qt.Orientation.Vertical)
        split.addWidget(self.table)
        split.addWidget(self.plot)
        layout = QtWidgets.QVBoxLayout(self)
        layout.addLayout(bar)
        layout.addWidget(split, 1)
        layout.addLayout(actions)
        layout.addWidget(self.fit_label)
        layout.addWidget(self.output)
        self.opened: list[str] = []
        self.process: QtCore.QProcess | None = None

    # -- table --------------------------------------------------------------------------

    @staticmethod
    def _field(row: RunRow, name: str) -> str:
        if name in ("motor", "propeller"):
            return str(row.components.get(name, ""))
        return str(getattr(row, name))

    def refresh(self) -> None:
        self.rows = RunIndex(self.out).list() if (self.out / "runs.sqlite").exists() else []
        for name, box in self.filters.items():
            current = box.currentData()
            values = sorted({self._field(r, name) for r in self.rows} - {""})
            box.blockSignals(True)
            box.clear()
            box.addItem(f"any {name}", None)
            for v in values:
                box.addItem(v, v)
            if current in values:
                box.setCurrentIndex(values.index(current) + 1)
            box.blockSignals(False)
        self._fill()

    def _fill(self, *_: Any) -> None:
        want = {n: b.currentData() for n, b in self.filters.items() if b.currentData()}
        self.shown = [r for r in reversed(self.rows)
                      if all(self._field(r, n) == v for n, v in want.items())]
        self.table.setRowCount(len(self.shown))
        for i, r in enumerate(self.shown):
            for c, value in enumerate((r.id, r.started_utc[:19], r.rig, r.sequence,
                                       self._field(r, "motor"), self._field(r, "propeller"),
                                       r.status, r.reason)):
                self.table.setItem(i, c, QtWidgets.QTableWidgetItem(value))
        self.table.resizeColumnsToContents()

    def selected(self) -> list[RunRow]:
        rows = sorted({i.row() for i in self.table.selectionModel().selectedRows()})
        return [self.shown[i] for i in rows if i < len(self.shown)]

    def select(self, *indices: int) -> None:
        self.table.clearSelection()
        mode = self.table.selectionMode()
        self.table.setSelectionMode(QtWidgets.QAbstractItemView.SelectionMode.MultiSelection)
        for i in indices:
            self.table.selectRow(i)
        self.table.setSelectionMode(mode)

    def path_of(self, row: RunRow) -> Path:
        return self.out / row.path

    # -- open / overlay -------------------------------------------------------------------

    def open_selected(self) -> None:
        """Plot the thrust of the selected run (two selected: overlaid)."""
        from analysis.run_record import read_run

        rows = self.selected()[:2]
        if not rows:
            self.output.setPlainText("select one run (or two to overlay)")
            return
        self.plot.clear()
        self.opened = []
        for color, row in zip(COLORS, rows, strict=False):
            try:
                rec = read_run(self.path_of(row))
                t, y = rec.column("t_s"), rec.column("thrust_n")
            except Exception as exc:  # an unreadable run is reported, not a crash
                self.output.setPlainText(f"{row.id}: {exc}")
                continue
            if t.size == 0:
                self.output.setPlainText(f"{row.id}: no samples")
                continue
            x, yy = envelope(t, y, float(t[0]), float(t[-1]) + 1e-9, 2000)
            self.plot.plot(x, yy, pen=pg.mkPen(color), name=f"{row.id} ({row.status})")
            self.opened.append(row.id)
        if self.opened:
            self.output.setPlainText("opened " + " and ".join(self.opened))

    # -- fit / report / export (the CLI's commands, as child processes) ---------------------

    def _run_cli(self, args: list[str], done: Any = None) -> None:
        if self.process is not None and \
                self.process.state() != QtCore.QProcess.ProcessState.NotRunning:
            self.output.setPlainText("busy: the previous command is still running")
            return
        cmd = [*_cli(), *args]
        self.output.setPlainText("$ " + " ".join(cmd))
        proc = QtCore.QProcess(self)
        proc.setProcessChannelMode(QtCore.QProcess.ProcessChannelMode.MergedChannels)

        def finished(code: int, _status: Any) -> None:
            text = bytes(proc.readAll().data()).decode(errors="replace")
            self.output.appendPlainText(text.strip() or f"(exit {code})")
            if done is not None and code == 0:
                done(text)

        proc.finished.connect(finished)
        proc.start(cmd[0], cmd[1:])
        self.process = proc

    def _selected_or_last(self, sequences: tuple[str, ...]) -> RunRow | None:
        picked = self.selected()
        if picked:
            return picked[0]
        for r in reversed(self.rows):
            if r.sequence in sequences and r.status == "success":
                return r
        return None

    def fit_last(self) -> None:
        row = self._selected_or_last(("step1", "step2"))
        if row is None:
            self.output.setPlainText("fit: no successful step run yet")
            return
        self._run_cli(["fit", str(self.path_of(row)), "--json"],
                      lambda text, rid=row.id: self.show_fit(rid, text))

    def show_fit(self, run_id: str, text: str) -> None:
        try:
            s = json.loads(text[text.index("{"):])
        except ValueError:
            return
        def num(key: str, unit: str = " ms") -> str:
            v = s.get(key)
            return "-" if v is None else f"{v:.4g}{unit}"

        self.fit_label.setText(
            f"last fit ({run_id}, {s.get('signal')}): latency {num('latency_ms')}, "
            f"tau up {num('tau_up_ms')}, tau down {num('tau_down_ms')}, "
            f"gain {num('gain', '')}")

    def report(self) -> None:
        row = self._selected_or_last(("step1", "step2", "sweep"))
        if row is None:
            self.output.setPlainText("report: select a run")
            return
        self._run_cli(["report", str(self.path_of(row)),
                       "--out", str(self.out / f"report-{row.id}")])

    def export(self, target: str) -> None:
        row = self._selected_or_last(("sweep",))
        if row is None:
            self.output.setPlainText(f"{target}: select a sweep run")
            return
        self._run_cli(["export", target, str(self.path_of(row))])
