"""The IMU tab draws the hexapod's commanded pose."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("pytestqt")
pytest.importorskip("pyqtgraph")

from bench.console.imu_bench import commanded_pose
from bench.console.imu_tab import ImuTab
from bench.console.pose_view import HOME_HEIGHT_M, TRANSLATION_GAIN, plate_points
from bench.plans.calibration_sequences import HexapodSegment
from drivers.hexapod_motions import Motion


def test_commanded_pose_follows_the_segment_motion():
    # 2 mm in x and 5 deg of roll at 0.5 Hz, no ramp: a quarter period in, both at their peak
    motion = Motion("test", 10.0, ((( 0.002, 0.5, 0.0),), (), (), ((math.radians(5), 0.5, 0.0),),
                                   (), ()), ramp_s=0.0)
    seg = HexapodSegment(3, "move", "test", "gyro", 4.0, 10.0, motion=motion)
    pose = commanded_pose(seg, 4.5)  # 0.5 s into the segment
    assert pose[0] == pytest.approx(0.002)
    assert pose[3] == pytest.approx(math.radians(5))
    assert commanded_pose(HexapodSegment(0, "hold", "rest", "rest", 0.0, 1.0), 0.5) == [0.0] * 6


def test_plate_points_rotate_and_translate():
    home = plate_points([0.0] * 6)
    assert np.allclose(home[:, 2], HOME_HEIGHT_M)
    lifted = plate_points([0.0, 0.0, 0.001, 0.0, 0.0, 0.0])
    assert np.allclose(lifted[:, 2], HOME_HEIGHT_M + TRANSLATION_GAIN * 0.001)
    rolled = plate_points([0.0, 0.0, 0.0, math.radians(10), 0.0, 0.0])
    assert np.ptp(rolled[:, 2]) > 0.01  # a rolled plate is no longer level
    assert np.allclose(np.linalg.norm(rolled - rolled.mean(0), axis=1),
                       np.linalg.norm(home - home.mean(0), axis=1))  # a rigid plate


def test_the_imu_tab_shows_the_pose_it_is_sent(qtbot, tmp_path):
    tab = ImuTab(tmp_path, lambda *_: None)
    qtbot.addWidget(tab)
    pose = [0.001, -0.002, 0.0005, math.radians(3), math.radians(-2), math.radians(15)]
    tab.show_state({"imu": {"stage": 1, "stages": 4, "name": "gyro", "phase": "gyro",
                            "label": "sines", "t": 1.0, "total": 10.0, "peaks": {},
                            "pose": pose}})
    assert np.allclose(tab.pose_view.pose, pose)
    _, _, plate = tab.pose_view.curves["front (x-z)"]
    x, z = plate.getData()
    assert np.allclose(x[:-1], plate_points(pose)[:, 0])
    assert np.allclose(z[:-1], plate_points(pose)[:, 2])
    text = tab.pose_view.numbers.text()
    assert "x +1.00 mm" in text and "yaw +15.00°" in text
