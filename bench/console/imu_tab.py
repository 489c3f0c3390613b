"""The IMU tab: the IMU-bench calibration runs recorded under the output folder (stage,
status, hexapod pose range of the run) and the calibration result of the newest one.

Runs on an IMU rig are started with ``rotorbench calibrate``; the console shows them."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from pyqtgraph.Qt import QtWidgets

from bench.run_index import RunIndex

__all__ = ["ImuTab"]

HEADERS = ("id", "started (UTC)", "rig", "stage", "status", "reason")


def _is_imu_run(row: Any, out: Path) -> bool:
    try:
        meta = json.loads((out / row.path / "run.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    rig = meta.get("rig")
    return "hexapod" in json.dumps(rig) or str(meta.get("kind", "")).startswith("calib")


class ImuTab(QtWidgets.QWidget):
    def __init__(self, out: Path) -> None:
        super().__init__()
        self.out = Path(out)
        self.info = QtWidgets.QLabel("")
        self.info.setWordWrap(True)
        self.table = QtWidgets.QTableWidget(0, len(HEADERS))
        self.table.setHorizontalHeaderLabels(HEADERS)
        self.table.horizontalHeader().setStretchLastSection(True)
        self.result = QtWidgets.QPlainTextEdit()
        self.result.setReadOnly(True)
        layout = QtWidgets.QVBoxLayout(self)
        layout.addWidget(self.info)
        layout.addWidget(QtWidgets.QLabel("IMU-bench runs (hexapod stages)"))
        layout.addWidget(self.table, 1)
        layout.addWidget(QtWidgets.QLabel("newest calibration result"))
        layout.addWidget(self.result, 1)
        self.rows: list[Any] = []

    def show_rig(self, info: dict[str, Any]) -> None:
        self.info.setText(
            f"This console drives the propulsion rig {info['name']}. IMU-bench rigs "
            "([rig] kind = \"imu\": hexapod and IMUs) are calibrated with `rotorbench "
            f"calibrate`; their runs under {info['out']} are listed here.")
        self.refresh()

    def refresh(self) -> None:
        if not (self.out / "runs.sqlite").exists():
            return
        self.rows = [r for r in RunIndex(self.out).list() if _is_imu_run(r, self.out)]
        self.table.setRowCount(len(self.rows))
        for i, r in enumerate(reversed(self.rows)):
            for c, value in enumerate((r.id, r.started_utc[:19], r.rig, r.sequence, r.status,
                                       r.reason)):
                self.table.setItem(i, c, QtWidgets.QTableWidgetItem(value))
        for r in reversed(self.rows):
            for name in ("calibration.json", "result.json"):
                path = self.out / r.path / name
                if path.is_file():
                    self.result.setPlainText(f"{path}\n{path.read_text(encoding='utf-8')}")
                    return
