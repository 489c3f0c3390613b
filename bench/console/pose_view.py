"""A schematic of the hexapod's pose on the IMU tab: the base, the moving plate and six
legs, seen from the front (x-z) and from the side (y-z), drawn from the commanded pose
of the running motion so the operator sees what the platform is doing and how far.

Schematic, not to scale of any controller: a plate of radius 0.10 m over a base of
radius 0.15 m, 0.20 m apart at the home pose; translations are drawn x5 so the few
millimetres of Paper A's motions are visible (the numbers beside it are true).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import pyqtgraph as pg
from pyqtgraph.Qt import QtWidgets

from drivers.hexapod_kinematics import euler_to_matrix

__all__ = ["PoseView", "plate_points"]

BASE_RADIUS_M = 0.15
PLATE_RADIUS_M = 0.10
HOME_HEIGHT_M = 0.20
TRANSLATION_GAIN = 5.0  # drawn translations are magnified this much


def _ring(radius: float, offset_deg: float) -> np.ndarray:
    """Six joints in pairs around a circle, (6, 3) in the plate's own frame."""
    ang = np.radians([a + d for a in (0.0, 120.0, 240.0) for d in (-offset_deg, offset_deg)])
    return np.column_stack([radius * np.cos(ang), radius * np.sin(ang), np.zeros(6)])


BASE_JOINTS = _ring(BASE_RADIUS_M, 50.0)
PLATE_JOINTS = _ring(PLATE_RADIUS_M, 10.0)


def plate_points(pose: Sequence[float] | np.ndarray) -> np.ndarray:
    """The plate's six joints in the base frame for ``pose`` = (x, y, z m, roll, pitch,
    yaw rad), translations magnified by :data:`TRANSLATION_GAIN`; (6, 3)."""
    p = np.asarray(pose, dtype=float)
    rot = euler_to_matrix(p[3:6])[0]
    centre = np.array([0.0, 0.0, HOME_HEIGHT_M]) + TRANSLATION_GAIN * p[:3]
    return PLATE_JOINTS @ rot.T + centre


class PoseView(QtWidgets.QWidget):
    """Front and side views of the platform, and the pose in numbers. Each view is a bare
    ViewBox under a title: a PlotItem (hidden axes) built a context menu and its option
    forms per view, about a fifth of the whole window's construction."""

    def __init__(self) -> None:
        super().__init__()
        layout = QtWidgets.QHBoxLayout(self)
        self.views: dict[str, tuple[int, int]] = {"front (x-z)": (0, 2), "side (y-z)": (1, 2)}
        self.curves: dict[str, tuple[pg.PlotCurveItem, pg.PlotCurveItem, pg.PlotCurveItem]] = {}
        for title in self.views:
            view = pg.GraphicsLayoutWidget()
            vb = self._view_box(view, title)
            base = pg.PlotCurveItem(pen=pg.mkPen("#888", width=3))
            legs = pg.PlotCurveItem(pen=pg.mkPen("#4a90d9", width=2), connect="pairs")
            plate = pg.PlotCurveItem(pen=pg.mkPen("#e0a030", width=4))
            for curve in (base, legs, plate):
                vb.addItem(curve)
            self.curves[title] = (base, legs, plate)
            layout.addWidget(view, 1)
        self.numbers = QtWidgets.QLabel("")
        self.numbers.setMinimumWidth(150)
        layout.addWidget(self.numbers)
        self.pose = np.zeros(6)
        self._drawn: np.ndarray | None = None
        self.show_pose(self.pose)

    @staticmethod
    def _view_box(view: pg.GraphicsLayoutWidget, title: str) -> pg.ViewBox:
        """The title over a fixed, aspect-locked view without mouse or menu."""
        grid: Any = view.ci
        grid.setContentsMargins(1, 1, 1, 1)  # as a PlotItem lays its title and view out
        grid.setSpacing(0)
        label = grid.addLabel(title, row=0, col=0, size="11pt")
        label.setMaximumHeight(30)
        grid.layout.setRowFixedHeight(0, 30)
        vb = grid.addViewBox(row=1, col=0, enableMenu=False)
        vb.setAspectLocked(True)
        vb.setXRange(-0.2, 0.2)
        vb.setYRange(-0.02, 0.3)
        vb.setMouseEnabled(False, False)
        return vb

    def show_pose(self, pose: Sequence[float] | np.ndarray) -> None:
        """Draw ``pose``; the same pose again (a hold sends the home pose ten times a
        second) is already drawn."""
        self.pose = np.asarray(pose, dtype=float)
        if self._drawn is not None and np.array_equal(self._drawn, self.pose):
            return
        self._drawn = self.pose.copy()
        plate = plate_points(self.pose)
        for title, (h, v) in self.views.items():
            base_c, legs_c, plate_c = self.curves[title]
            ring = np.vstack([BASE_JOINTS, BASE_JOINTS[:1]])
            base_c.setData(ring[:, h], ring[:, v])
            legs = np.empty((12, 3))
            legs[0::2], legs[1::2] = BASE_JOINTS, plate
            legs_c.setData(legs[:, h], legs[:, v])
            top = np.vstack([plate, plate[:1]])
            plate_c.setData(top[:, h], top[:, v])
        x, y, z, r, p, yaw = self.pose
        self.numbers.setText(
            f"x {1e3 * x:+.2f} mm\ny {1e3 * y:+.2f} mm\nz {1e3 * z:+.2f} mm\n"
            f"roll {math.degrees(r):+.2f}°\npitch {math.degrees(p):+.2f}°\n"
            f"yaw {math.degrees(yaw):+.2f}°\n(translations drawn x{TRANSLATION_GAIN:g})")
