"""One decoded flight log as run columns: the shape every flight-log reader returns.

Flight logs mix streams at different rates (PX4 logs each topic on its own clock,
ArduPilot each message); a run folder is one table. The gyro stream is the fastest the
step-response and vibration fits need, so it is the time base, and every slower stream
is held at its last logged value (``holder``), NaN before its first sample.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["AXES", "MAX_ROWS", "FlightLog", "holder"]

AXES = ("x", "y", "z")  # body roll, pitch, yaw axes
MAX_ROWS = 20_000_000  # rows kept per log unless told otherwise (~2.8 h at 2 kHz)


@dataclass
class FlightLog:
    """Run columns (``t_s`` first, SI units) and what ``run.json`` says about them.

    ``units`` names each column's unit as logged-and-converted (``rad/s``, ``µs``,
    ``normalised 0..1``, ``DShot command``); ``sources`` names the log field it came from.
    """

    columns: dict[str, np.ndarray]
    meta: dict[str, Any]
    units: dict[str, str] = field(default_factory=dict)
    sources: dict[str, str] = field(default_factory=dict)

    def add(self, name: str, values: np.ndarray, unit: str, source: str) -> None:
        self.columns[name] = np.asarray(values, dtype=float)
        self.units[name] = unit
        self.sources[name] = source

    @property
    def rows(self) -> int:
        return len(self.columns["t_s"])

    def keep_first(self, n: int) -> None:
        """Keep the first ``n`` rows (``--max-rows``), saying so in the notes."""
        if self.rows > n:
            self.meta.setdefault("notes", []).append(
                f"kept the first {n} of {self.rows} rows (--max-rows)")
            self.columns = {c: v[:n] for c, v in self.columns.items()}

    def run_meta(self) -> dict[str, Any]:
        """The metadata for ``run.json``'s ``flight`` entry."""
        return {**self.meta, "units": dict(self.units), "sources": dict(self.sources)}


def holder(t_base: np.ndarray, t: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """Hold values logged at times ``t`` (sorted) onto ``t_base``: the last value at or
    before each base time; NaN before the first. The search runs once per stream, however
    many of its fields are held."""
    idx = np.searchsorted(t, t_base, side="right") - 1

    def held(values: np.ndarray) -> np.ndarray:
        values = np.asarray(values, dtype=float)
        if not len(values):
            return np.full(len(t_base), np.nan)
        return np.where(idx >= 0, values[np.clip(idx, 0, len(values) - 1)], np.nan)

    return held
