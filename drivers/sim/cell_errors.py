"""What a real load cell adds to a perfect one: a sensitivity off its datasheet value, a bow
(non-linearity), hysteresis and creep, hidden from the bench so that a calibration has
something to find.

Each is a fraction of the cell's full-scale output (the rated range): the bow is
``4 nl x (1 - |x|)`` of it at the normalised load x (largest, nl, at half range); the
hysteresis a play operator (backlash) of width ``PLAY`` on x, which puts the unloading
branch ``hyst`` above the loading one at half range and at neither end; the creep a
first-order approach, time constant ``creep_tau_s``, to ``creep`` x. The hysteresis and
creep carry state from one read to the next, stepped once per ``DECIMATE`` samples (1 ms at
25 kHz: far faster than either changes) so the per-sample work stays vectorised.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["CellErrorState", "CellErrors", "apply_cell_errors"]

PLAY = 0.02  # half-width of the play operator, in fractions of full scale
DECIMATE = 25  # samples per state step


@dataclass(frozen=True)
class CellErrors:
    """A cell's hidden errors (0: a perfect cell); fractions of full scale but ``scale``,
    the sensitivity's relative error."""

    scale: float = 0.0
    nonlinearity: float = 0.0
    hysteresis: float = 0.0
    creep: float = 0.0
    creep_tau_s: float = 20.0

    @property
    def any(self) -> bool:
        return any((self.scale, self.nonlinearity, self.hysteresis, self.creep))

    @classmethod
    def drawn(cls, seed: int) -> CellErrors:
        """Errors of a hobby-grade cell drawn from a seed: sensitivity within +-3 %,
        non-linearity, hysteresis up to 0.3 % and creep up to 0.2 % of full scale."""
        rng = np.random.default_rng(seed)
        return cls(scale=float(rng.uniform(-0.03, 0.03)),
                   nonlinearity=float(rng.uniform(0.0, 0.003)),
                   hysteresis=float(rng.uniform(0.0, 0.003)),
                   creep=float(rng.uniform(0.0, 0.002)))

    def steady(self, x: float, branch: int, held_s: float = math.inf) -> float:
        """The output (fraction of full scale) at a steady load x reached on the loading
        (+1) or unloading (-1) branch, ``held_s`` after the creep started from 0."""
        # x - p of the play operator is +PLAY while loading, -PLAY while unloading
        hyst = -0.5 * self.hysteresis * branch * 4 * abs(x) * (1 - abs(x))
        creep = self.creep * x * (1 - math.exp(-held_s / self.creep_tau_s))
        return ((1 + self.scale) * x + 4 * self.nonlinearity * x * (1 - abs(x)) + hyst + creep)


@dataclass
class CellErrorState:
    """The play operator's output and the creep's state at the last stepped sample."""

    play: float = 0.0
    creep: float = 0.0
    last_n: int = -1

    def copy(self) -> CellErrorState:
        return CellErrorState(self.play, self.creep, self.last_n)


def apply_cell_errors(errors: CellErrors, state: CellErrorState, x: np.ndarray, n0: int,
                      dt_s: float) -> np.ndarray:
    """The cell's output for normalised loads ``x`` (samples n0, n0+1, ...), fraction of
    full scale; ``state`` is advanced."""
    out = (1 + errors.scale) * x
    if errors.nonlinearity:
        out += 4 * errors.nonlinearity * x * (1 - np.abs(x))
    if not (errors.hysteresis or errors.creep):
        return out
    # the samples whose index is a multiple of DECIMATE step the state
    first = n0 + (-n0) % DECIMATE
    steps = np.arange(first - n0, x.size, DECIMATE)
    p, c = state.play, state.creep
    play = np.empty(steps.size + 1)
    creep = np.empty(steps.size + 1)
    play[0], creep[0] = p, c  # for the samples before this read's first step
    a = math.exp(-DECIMATE * dt_s / errors.creep_tau_s)
    target = errors.creep
    for i, v in enumerate(x[steps].tolist(), start=1):
        p = min(max(p, v - PLAY), v + PLAY)  # the play operator: clamp into [x - w, x + w]
        c = a * c + (1 - a) * target * v  # first order towards creep * x
        play[i], creep[i] = p, c
    state.play, state.creep = p, c
    if steps.size:
        state.last_n = n0 + int(steps[-1])
    # each sample takes the state of the last step at or before it
    which = np.searchsorted(steps, np.arange(x.size), side="right")
    branch = ((x - play[which]) / PLAY).clip(-1.0, 1.0)
    out += -0.5 * errors.hysteresis * branch * 4 * np.abs(x) * (1 - np.abs(x))
    out += creep[which]
    return out
