"""User-facing errors of the analysis package (bad logs, bad calibration files, weak data)."""

from __future__ import annotations


class LogError(ValueError):
    """A log or calibration file is invalid; the message names the file, row/column or field."""

    exit_code = 2


class CalibrationError(ValueError):
    """The data cannot give a trustworthy calibration (e.g. an axis is not excited)."""

    exit_code = 2


class MissingExtraError(ImportError):
    """An optional extra (e.g. ``imu``: h5py, vqf, ahrs) is needed but not installed."""

    exit_code = 2
