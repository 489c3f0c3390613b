"""Min/max envelope of time series per pixel column, so a one-sample spike in 25 kHz
data stays visible on a plot a thousand pixels wide (plain decimation would drop it)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

__all__ = ["envelope", "envelopes"]


def envelopes(t: np.ndarray, ys: Mapping[str, np.ndarray], t0: float, t1: float,
              columns: int) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Per column of ``[t0, t1)`` split into ``columns``: each series' min and max, as a
    line that goes min -> max in each column (x = column centre, twice). ``t`` ascending;
    NaNs are skipped; a column without samples is left out. The columns are found once
    for all series; each series costs two ``reduceat``."""
    if columns < 1 or not t1 > t0 or t.size == 0:
        return np.empty(0), {k: np.empty(0) for k in ys}
    lo_i, hi_i = np.searchsorted(t, [t0, t1])
    t = t[lo_i:hi_i]
    if t.size <= 2 * columns:  # already fewer points than the envelope would have
        return t.copy(), {k: np.asarray(y[lo_i:hi_i], float).copy() for k, y in ys.items()}
    width = (t1 - t0) / columns
    col = np.minimum(((t - t0) / width).astype(np.intp), columns - 1)
    starts = np.flatnonzero(np.r_[True, col[1:] != col[:-1]])  # first sample of each column
    x = np.repeat(t0 + (col[starts] + 0.5) * width, 2)
    out = {}
    for key, y in ys.items():
        y = np.asarray(y[lo_i:hi_i], float)
        out[key] = np.column_stack([np.fmin.reduceat(y, starts),
                                    np.fmax.reduceat(y, starts)]).ravel()
    return x, out


def envelope(t: np.ndarray, y: np.ndarray, t0: float, t1: float, columns: int
             ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`envelopes` of one series."""
    x, ys = envelopes(t, {"y": y}, t0, t1, columns)
    return x, ys["y"]


class RollingEnvelope:
    """The min/max envelope of the newest ``columns`` time columns of width ``width_s``,
    updated with only the rows that are new since the last frame (so a frame costs
    O(new rows), not O(window)). Columns are fixed in absolute time (column k covers
    ``[k w, (k + 1) w)``), each kept in slot ``k % columns``."""

    def __init__(self, names: tuple[str, ...], columns: int, width_s: float) -> None:
        if columns < 1 or not width_s > 0:
            raise ValueError("need columns >= 1 and a column width > 0 s")
        self.names = tuple(names)
        self.columns = int(columns)
        self.width_s = float(width_s)
        self.k = np.full(self.columns, np.iinfo(np.int64).min, dtype=np.int64)
        self.lo = np.full((len(self.names), self.columns), np.nan)
        self.hi = np.full((len(self.names), self.columns), np.nan)
        self.t_last = -np.inf

    def update(self, t: np.ndarray, ys: Mapping[str, np.ndarray]) -> None:
        """Fold new rows (``t`` ascending, after every row folded before) in."""
        if t.size == 0:
            return
        k = np.floor(t / self.width_s).astype(np.int64)
        keep = k > k[-1] - self.columns  # older rows fall out of the window anyway
        if not keep.all():
            t, k = t[keep], k[keep]
            ys = {n: np.asarray(ys[n])[keep] for n in self.names}
        starts = np.flatnonzero(np.r_[True, k[1:] != k[:-1]])
        kk = k[starts]
        slot = kk % self.columns
        same = self.k[slot] == kk  # a column continued from the last update
        for i, name in enumerate(self.names):
            y = np.asarray(ys[name], float)
            lo = np.fmin.reduceat(y, starts)
            hi = np.fmax.reduceat(y, starts)
            self.lo[i, slot] = np.where(same, np.fmin(self.lo[i, slot], lo), lo)
            self.hi[i, slot] = np.where(same, np.fmax(self.hi[i, slot], hi), hi)
        self.k[slot] = kk
        self.t_last = float(t[-1])

    def lines(self) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """x (column centres, twice, in seconds relative to the newest row) and per name
        the min -> max line, oldest column first."""
        if not np.isfinite(self.t_last):
            return np.empty(0), {n: np.empty(0) for n in self.names}
        newest = int(np.floor(self.t_last / self.width_s))
        valid = self.k > newest - self.columns
        order = np.argsort(self.k[valid], kind="stable")
        slots = np.flatnonzero(valid)[order]
        x = np.repeat((self.k[slots] + 0.5) * self.width_s - self.t_last, 2)
        out = {n: np.column_stack([self.lo[i, slots], self.hi[i, slots]]).ravel()
               for i, n in enumerate(self.names)}
        return x, out
