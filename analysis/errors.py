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


def excerpt(text: object, limit: int = 40) -> str:
    """``repr`` of a cell or line quoted in an error, cut to ``limit`` characters: a log
    with one 20 MB line must not give a 20 MB message. The length is said when cut."""
    s = str(text)
    if len(s) <= limit:
        return repr(s)
    return f"{s[:limit]!r}... ({len(s)} characters)"
