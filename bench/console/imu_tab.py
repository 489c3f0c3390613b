"""The IMU tab: on an IMU-bench rig, start or abort a Paper A calibration and follow its
stages (stage, phase, the hexapod motion and its peaks, progress, and the hexapod's pose
drawn front and side); the IMU-bench runs recorded under the output folder and the newest
calibration result."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pyqtgraph.Qt import QtCore, QtWidgets

from bench.console.pose_view import PoseView
from bench.store.run_index import RunIndex

__all__ = ["ImuTab"]

HEADERS = ("id", "started (UTC)", "rig", "stage", "status", "reason")


def _is_imu_run(row: Any, out: Path) -> bool:
    try:
        meta = json.loads((out / row.path / "run.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return bool(meta.get("calibration_session")) or "hexapod" in json.dumps(meta.get("rig"))


class ImuTab(QtWidgets.QWidget):
    def __init__(self, out: Path, request: Callable[[str, Any], None]) -> None:
        super().__init__()
        self.out = Path(out)
        self.request = request
        self.info = QtWidgets.QLabel("")
        self.info.setWordWrap(True)
        self.quick_button = QtWidgets.QPushButton("Calibrate (quick)")
        self.full_button = QtWidgets.QPushButton("Calibrate (Paper A)")
        self.abort_button = QtWidgets.QPushButton("Abort (hexapod stop)")
        self.quick_button.clicked.connect(lambda: self.request("calibrate", {"quick": True}))
        self.full_button.clicked.connect(lambda: self.request("calibrate", {"quick": False}))
        self.abort_button.clicked.connect(lambda: self.request("abort", None))
        for b in (self.quick_button, self.full_button, self.abort_button):
            b.setFocusPolicy(QtCore.Qt.FocusPolicy.NoFocus)
            b.setEnabled(False)
        self.progress = QtWidgets.QProgressBar()
        self.stage_label = QtWidgets.QLabel("no calibration running")
        self.stage_label.setWordWrap(True)
        self.pose_view = PoseView()
        buttons = QtWidgets.QHBoxLayout()
        for b in (self.quick_button, self.full_button, self.abort_button):
            buttons.addWidget(b)
        buttons.addWidget(self.progress, 1)
        self.table = QtWidgets.QTableWidget(0, len(HEADERS))
        self.table.setHorizontalHeaderLabels(HEADERS)
        self.table.horizontalHeader().setStretchLastSection(True)
        self.result = QtWidgets.QPlainTextEdit()
        self.result.setReadOnly(True)
        layout = QtWidgets.QVBoxLayout(self)
        layout.addWidget(self.info)
        layout.addLayout(buttons)
        layout.addWidget(self.stage_label)
        layout.addWidget(self.pose_view, 1)
        layout.addWidget(QtWidgets.QLabel("IMU-bench runs (hexapod stages)"))
        layout.addWidget(self.table, 1)
        layout.addWidget(QtWidgets.QLabel("newest calibration result"))
        layout.addWidget(self.result, 1)
        self.rows: list[Any] = []

    def show_rig(self, info: dict[str, Any]) -> None:
        imu = info.get("kind") == "imu"
        for b in (self.quick_button, self.full_button, self.abort_button):
            b.setEnabled(imu)
        if imu:
            self.info.setText(f"IMU-bench rig {info['name']}: " + ", ".join(
                f"{r} {u}" for r, u in info["devices"].items()) + ". Each stage is a "
                "recorded run; abort or a lost window stops the hexapod.")
        else:
            self.info.setText(
                f"{info['name']} is a propulsion rig. Open the console on an IMU-bench rig "
                "([rig] kind = \"imu\": hexapod and IMUs) to calibrate from here; the "
                f"IMU-bench runs under {info['out']} are listed below.")
        self.refresh()

    def show_state(self, state: dict[str, Any]) -> None:
        p = state.get("imu")
        if not p:
            return
        if p.get("pose") is not None:
            self.pose_view.show_pose(p["pose"])
        total = p["total"] or 1.0
        self.progress.setValue(int(100 * p["t"] / total))
        peaks = ", ".join(f"{k} {v:g}" for k, v in (p.get("peaks") or {}).items())
        self.stage_label.setText(
            f"stage {p['stage']}/{p['stages']} {p['name']}: phase {p['phase']}, "
            f"{p['label']}, {p['t']:.1f}/{p['total']:.1f} s" + (f" (peaks {peaks})"
                                                                  if peaks else ""))

    def show_finished(self, info: dict[str, Any]) -> None:
        self.stage_label.setText(f"calibration {info['status']}: {info['reason']}")
        path = info.get("calibration")
        if path:
            self.result.setPlainText(f"{path}\n{Path(path).read_text(encoding='utf-8')}")

    def refresh(self) -> None:
        if not (self.out / "runs.sqlite").exists():
            return
        self.rows = [r for r in RunIndex(self.out).list() if _is_imu_run(r, self.out)]
        self.table.setRowCount(len(self.rows))
        for i, r in enumerate(reversed(self.rows)):
            for c, value in enumerate((r.id, r.started_utc[:19], r.rig, r.sequence, r.status,
                                       r.reason)):
                self.table.setItem(i, c, QtWidgets.QTableWidgetItem(value))
        results = sorted(self.out.glob("*calibration*.json"))
        if results and not self.result.toPlainText():
            self.result.setPlainText(f"{results[-1]}\n"
                                     f"{results[-1].read_text(encoding='utf-8')}")
