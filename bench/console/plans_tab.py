"""The plans tab: pick Step 1, Step 2, the sweep or a plan file, see its steps (the dry
run, compiled by the bench) and the progress of a running plan; start and abort."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pyqtgraph.Qt import QtCore, QtWidgets

__all__ = ["PlansTab"]

PLANS = (("Step 1 (Paper C)", "step1"), ("Step 2 (Paper C)", "step2"), ("Sweep", "sweep"),
         ("Plan file...", "file"))
HEADERS = ("#", "t_start_s", "dur_s", "kind", "us_start", "us_end", "setpoint_n", "label")


class PlansTab(QtWidgets.QWidget):
    def __init__(self, request: Callable[[str, Any], None]) -> None:
        super().__init__()
        self.request = request
        self.combo = QtWidgets.QComboBox()
        for text, key in PLANS:
            self.combo.addItem(text, key)
        self.repeats = QtWidgets.QSpinBox()
        self.repeats.setRange(1, 500)
        self.repeats.setValue(20)
        self.hold = QtWidgets.QDoubleSpinBox()
        self.hold.setRange(0.05, 60.0)
        self.hold.setValue(0.5)
        self.hold.setSuffix(" s")
        self.sweep_s = QtWidgets.QDoubleSpinBox()
        self.sweep_s.setRange(1.0, 600.0)
        self.sweep_s.setValue(20.0)
        self.sweep_s.setSuffix(" s")
        self.path = QtWidgets.QLabel("(no file)")
        self.file_button = QtWidgets.QPushButton("Choose file")
        self.file_button.clicked.connect(self._choose)
        self.start_button = QtWidgets.QPushButton("Start plan")
        self.abort_button = QtWidgets.QPushButton("Abort")
        self.start_button.clicked.connect(lambda: self.request("start_plan", self.spec()))
        self.abort_button.clicked.connect(lambda: self.request("abort", None))
        for w in (self.file_button, self.start_button, self.abort_button):
            w.setFocusPolicy(QtCore.Qt.FocusPolicy.NoFocus)
        form = QtWidgets.QHBoxLayout()
        for label, w in (("plan", self.combo), ("repeats", self.repeats), ("hold", self.hold),
                         ("sweep", self.sweep_s)):
            form.addWidget(QtWidgets.QLabel(label))
            form.addWidget(w)
        form.addWidget(self.file_button)
        form.addWidget(self.path, 1)
        self.description = QtWidgets.QLabel("")
        self.description.setWordWrap(True)
        self.progress = QtWidgets.QProgressBar()
        self.progress.setFormat("%p %")
        self.step_label = QtWidgets.QLabel("no plan running")
        self.table = QtWidgets.QTableWidget(0, len(HEADERS))
        self.table.setHorizontalHeaderLabels(HEADERS)
        self.table.horizontalHeader().setStretchLastSection(True)
        self.table.setEditTriggers(QtWidgets.QAbstractItemView.EditTrigger.NoEditTriggers)
        run = QtWidgets.QHBoxLayout()
        run.addWidget(self.start_button)
        run.addWidget(self.abort_button)
        run.addWidget(self.progress, 1)
        layout = QtWidgets.QVBoxLayout(self)
        layout.addLayout(form)
        layout.addWidget(self.description)
        layout.addLayout(run)
        layout.addWidget(self.step_label)
        layout.addWidget(self.table, 1)
        for signal in (self.combo.currentIndexChanged, self.repeats.valueChanged,
                       self.hold.valueChanged, self.sweep_s.valueChanged):
            signal.connect(self.preview)
        self._file = ""
        self._current = -1

    def spec(self) -> dict[str, Any]:
        return {"plan": self.combo.currentData(), "path": self._file,
                "repeats": self.repeats.value(), "hold_s": self.hold.value(),
                "duration_s": self.sweep_s.value()}

    def set_file(self, path: str) -> None:
        self._file = path
        self.path.setText(path or "(no file)")
        self.combo.setCurrentIndex(len(PLANS) - 1)
        self.preview()

    def _choose(self) -> None:
        path, _ = QtWidgets.QFileDialog.getOpenFileName(
            self, "Plan file", "", "Sequence files (*.json *.toml)")
        if path:
            self.set_file(path)

    def preview(self, *_: Any) -> None:
        if self.combo.currentData() == "file" and not self._file:
            return
        self.request("preview", self.spec())

    def show_preview(self, preview: dict[str, Any]) -> None:
        self.description.setText(f"{preview['name']}: {preview['description']} "
                                 f"({len(preview['segments'])} steps, "
                                 f"{preview['duration_s']:.1f} s)")
        rows = preview["segments"]
        self.table.setRowCount(len(rows))
        for r, row in enumerate(rows):
            for c, value in enumerate(row):
                text = "(map)" if value is None and c in (4, 5) else (
                    "" if value is None else str(value))
                self.table.setItem(r, c, QtWidgets.QTableWidgetItem(text))
        self._current = -1

    def show_state(self, state: dict[str, Any]) -> None:
        prog = state.get("progress")
        if not state.get("busy") or prog is None:
            return
        t, total, label, index = prog
        self.progress.setValue(int(100 * t / total) if total > 0 else 0)
        self.step_label.setText(f"{state['kind']}: step {index} ({label}), "
                                f"{t:.1f} / {total:.1f} s")
        if state["kind"] not in ("manual", "tare") and index != self._current and \
                0 <= index < self.table.rowCount():
            self.table.selectRow(index)
            self._current = index

    def show_finished(self, info: dict[str, Any]) -> None:
        self.step_label.setText(f"{info['kind']}: {info['status']}: {info['reason']}")
