"""The tare: each force channel's zero at rest, with its standard uncertainty.

Why: a fitted constant inherits the uncertainty of the zero its samples were referred to
(a thrust offset moves the thrust curve's constant term and, through the fit, k_f), so
the tare is a budget term (``analysis.metrology.constant_budgets``) and the run records
it. Thrust and torque are both tared: an untared torque cell's offset would read as
torque a still motor makes. The zero's uncertainty is that of a calibration hold's mean
(``hold_mean``: the scatter of block means, which keeps noise correlated over less than a
block honest).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from analysis.metrology.force_calibration import hold_mean

__all__ = ["TARED_CHANNELS", "ZeroTare"]

TARED_CHANNELS = ("thrust_n", "torque_nm")

Zero = dict[str, float | int]  # offset, u, samples
#: a checkpoint: the samples held so far (None outside a tare) and the zeros found
TareState = tuple[dict[str, list[np.ndarray]] | None, dict[str, Zero]]


class ZeroTare:
    """Collects raw samples during the tare (``begin``, ``add``, ``end``), then subtracts
    each channel's zero from every later sample (``apply``)."""

    def __init__(self) -> None:
        self._zeros: dict[str, Zero] = {}
        self._held: dict[str, list[np.ndarray]] | None = None

    def offset(self, channel: str) -> float:
        return float(self._zeros.get(channel, {}).get("offset", 0.0))

    def begin(self) -> None:
        self._held = {ch: [] for ch in TARED_CHANNELS}

    def add(self, rows: Mapping[str, np.ndarray]) -> None:
        if self._held is None:
            return
        for ch, parts in self._held.items():
            if ch in rows:
                parts.append(np.asarray(rows[ch], dtype=float))

    def end(self) -> dict[str, Zero]:
        """The zeros found (channels with at least two finite samples), which now apply."""
        held, self._held = self._held or {}, None
        for ch, parts in held.items():
            y = np.concatenate(parts) if parts else np.empty(0)
            y = y[np.isfinite(y)]
            if y.size >= 2:
                mean, u = hold_mean(y)
                self._zeros[ch] = {"offset": mean, "u": u, "samples": int(y.size)}
        return dict(self._zeros)

    def apply(self, values: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """``values`` with each tared channel's zero subtracted."""
        out = dict(values)
        for ch, z in self._zeros.items():
            if ch in out:
                out[ch] = out[ch] - float(z["offset"])
        return out

    def state(self) -> TareState:
        """A checkpoint (a speculative batch of ticks may be taken back)."""
        held = None if self._held is None else {ch: list(v) for ch, v in self._held.items()}
        return held, dict(self._zeros)

    def set_state(self, state: TareState) -> None:
        held, zeros = state
        self._held = None if held is None else {ch: list(v) for ch, v in held.items()}
        self._zeros = dict(zeros)

    def record(self) -> dict[str, Any]:
        """What run.json keeps: per channel its offset, standard uncertainty and samples."""
        return {ch: dict(z) for ch, z in self._zeros.items()}
