"""The devices tab: each device of the rig with its state (check result, answering,
last value), check, load-cell tare and the load cell's calibration with known weights
(prompted step by step, or by the simulated stand's fixture)."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from pyqtgraph.Qt import QtCore, QtWidgets

__all__ = ["DevicesTab"]

# the recorded columns that show a device's last value
ROLE_COLUMNS = {"esc": ("throttle_us",), "load_cell": ("thrust_n",),
                "power": ("current_a", "voltage_v"), "rpm": ("rpm",),
                "torque": ("torque_nm",)}
HEADERS = ("role", "url", "state", "last value", "detail")


class DevicesTab(QtWidgets.QWidget):
    def __init__(self, request: Callable[[str, Any], None]) -> None:
        super().__init__()
        self.request = request
        self.table = QtWidgets.QTableWidget(0, len(HEADERS))
        self.table.setHorizontalHeaderLabels(HEADERS)
        self.table.horizontalHeader().setStretchLastSection(True)
        self.table.setEditTriggers(QtWidgets.QAbstractItemView.EditTrigger.NoEditTriggers)
        self.check_button = QtWidgets.QPushButton("Check devices")
        self.tare_button = QtWidgets.QPushButton("Tare load cell")
        for b in (self.check_button, self.tare_button):
            b.setFocusPolicy(QtCore.Qt.FocusPolicy.NoFocus)
        self.check_button.clicked.connect(lambda: self._ask("check", "checking..."))
        self.tare_button.clicked.connect(lambda: self._ask("tare", "taring (motor stopped)..."))
        self.info = QtWidgets.QLabel("Check opens every device and asks for a sign of life "
                                     "without moving anything.")
        self.info.setWordWrap(True)
        buttons = QtWidgets.QHBoxLayout()
        buttons.addWidget(self.check_button)
        buttons.addWidget(self.tare_button)
        buttons.addStretch(1)
        # the load cell's calibration with known weights (docs/calibration.md)
        self.masses = QtWidgets.QLineEdit("0,100,200,500,1000")
        self.masses.setToolTip("the weights in grams, ascending from 0")
        self.automatic = QtWidgets.QCheckBox("automatic fixture")
        self.calibrate_button = QtWidgets.QPushButton("Calibrate load cell")
        self.placed_button = QtWidgets.QPushButton("Weight placed")
        self.placed_button.setEnabled(False)
        for b in (self.calibrate_button, self.placed_button):
            b.setFocusPolicy(QtCore.Qt.FocusPolicy.NoFocus)
        self.calibrate_button.clicked.connect(self._calibrate)
        self.placed_button.clicked.connect(self._placed)
        self.prompt = QtWidgets.QLabel("")
        self.prompt.setWordWrap(True)
        cal = QtWidgets.QHBoxLayout()
        cal.addWidget(QtWidgets.QLabel("weights (g):"))
        cal.addWidget(self.masses, 1)
        cal.addWidget(self.automatic)
        cal.addWidget(self.calibrate_button)
        cal.addWidget(self.placed_button)
        layout = QtWidgets.QVBoxLayout(self)
        layout.addLayout(buttons)
        layout.addLayout(cal)
        layout.addWidget(self.prompt)
        layout.addWidget(self.info)
        layout.addWidget(self.table, 1)
        self.roles: list[str] = []

    def _ask(self, kind: str, text: str) -> None:
        self.info.setText(text)
        self.request(kind, None)

    def _calibrate(self) -> None:
        self.info.setText("calibrating the load cell (motor stopped)...")
        self.request("calibrate_cell", {"masses_g": self.masses.text(),
                                        "automatic": self.automatic.isChecked()})

    def _placed(self) -> None:
        self.placed_button.setEnabled(False)
        self.request("cell_placed", None)

    def show_prompt(self, prompt: dict[str, Any]) -> None:
        """The bench asks for the next weight."""
        self.prompt.setText(str(prompt.get("text", "")))
        self.placed_button.setEnabled(True)

    def show_calibration(self, result: dict[str, Any]) -> None:
        self.prompt.setText("")
        self.placed_button.setEnabled(False)
        if result.get("status") != "success":
            self.info.setText(f"calibration failed: {result.get('reason')}")
            return
        verdict = "accepted" if result.get("passed") else "NOT accepted: " + "; ".join(
            result.get("failed", []))
        self.info.setText(f"calibration: gain {result['gain']:.6g} +- "
                          f"{2 * result['u_gain']:.2g} (k = 2), {verdict}; recorded in "
                          f"{result['run_dir']}; later runs apply it")

    def _set(self, row: int, col: int, text: str) -> None:
        self.table.setItem(row, col, QtWidgets.QTableWidgetItem(text))

    def show_rig(self, info: dict[str, Any]) -> None:
        self.roles = list(info.get("devices", {}))
        self.table.setRowCount(len(self.roles))
        for r, role in enumerate(self.roles):
            self._set(r, 0, role)
            self._set(r, 1, info["devices"][role])
            self._set(r, 2, "not checked")
        self.table.resizeColumnsToContents()

    def show_reports(self, reports: list[dict[str, Any]]) -> None:
        for rep in reports:
            if rep["role"] not in self.roles:
                self.roles.append(rep["role"])
                self.table.setRowCount(len(self.roles))
                self._set(len(self.roles) - 1, 0, rep["role"])
            r = self.roles.index(rep["role"])
            self._set(r, 2, "answering" if rep["ok"] else "FAULT")
            self._set(r, 4, rep["detail"])
        ok = sum(1 for rep in reports if rep["ok"])
        self.info.setText(f"check: {ok}/{len(reports)} devices answer")
        self.table.resizeColumnsToContents()

    def show_tare(self, result: dict[str, Any]) -> None:
        if result.get("status") == "success":
            self.info.setText(f"tare: offset {result.get('tare_offset_n', math.nan):.4f} N "
                              f"(recorded in {result['run_dir']}); each run tares again at "
                              "its start")
        else:
            self.info.setText(f"tare failed: {result.get('reason')}")

    def show_last(self, last: dict[str, float], busy: bool) -> None:
        """Last values while a run streams (devices are open only during a run)."""
        for r, role in enumerate(self.roles):
            cols = [c for c in ROLE_COLUMNS.get(role, ()) if c in last]
            vals = [f"{c}={last[c]:.4g}" for c in cols if math.isfinite(last[c])]
            self._set(r, 3, ", ".join(vals) if busy and vals else "-")
