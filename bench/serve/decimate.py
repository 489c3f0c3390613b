"""Min/max decimation per pixel column, so a 25 kHz x 200 s run paints at once.

For each of ``columns`` equal time bins the minimum and the maximum of the signal are
kept (two points per bin, the max first where the bin falls), which draws the same
envelope as every sample would: spikes and trips stay visible, unlike plain striding.
``numpy.fmin.reduceat``/``fmax.reduceat`` over the sorted samples; NaNs are skipped.

A signal can be fed in consecutive chunks of rows (``MinMaxEnvelope.add``), so a long
run is reduced while it is read, a few MB at a time, instead of holding whole 40 MB
columns (their fresh pages cost more than the reduction); the points are the same as
those of the whole signal at once (``minmax_decimate``).
"""

from __future__ import annotations

import numpy as np

__all__ = ["Bins", "MinMaxEnvelope", "minmax_decimate"]


class Bins:
    """The ``columns`` equal time bins of the sorted times ``t``: the first and last row
    of each non-empty bin. Short signals (<= 2 * columns samples) are kept whole."""

    def __init__(self, t: np.ndarray, columns: int) -> None:
        if columns < 1:
            raise ValueError("columns must be >= 1")
        self.t = np.asarray(t, dtype=float)
        self.rows = self.t.size
        self.whole = self.rows <= 2 * columns
        if self.whole:
            return
        edges = np.linspace(self.t[0], self.t[-1], columns + 1)
        starts = np.searchsorted(self.t, edges[:-1], side="left")
        self.starts = np.unique(starts[starts < self.rows])
        self.ends = np.append(self.starts[1:], self.rows) - 1


class MinMaxEnvelope:
    """One signal's min/max per bin, fed its rows in order, a chunk at a time."""

    def __init__(self, bins: Bins) -> None:
        self.bins = bins
        self.filled = 0
        n = bins.rows if bins.whole else bins.starts.size
        self._lo = np.full(n, np.nan)  # whole: the samples themselves
        if not bins.whole:
            self._hi = np.full(n, np.nan)
            self._first = np.full(n, np.nan)  # the sample at each bin's start and end
            self._last = np.full(n, np.nan)

    def add(self, y: np.ndarray) -> None:
        """The next ``len(y)`` rows of the signal."""
        y = np.asarray(y, dtype=float)
        lo, n = self.filled, y.size
        hi = lo + n
        if hi > self.bins.rows:
            raise ValueError(f"more rows than the {self.bins.rows} times")
        self.filled = hi
        if n == 0:
            return
        if self.bins.whole:
            self._lo[lo:hi] = y
            return
        starts, ends = self.bins.starts, self.bins.ends
        b0 = int(np.searchsorted(starts, lo, side="right")) - 1  # the bin row `lo` is in
        b1 = int(np.searchsorted(starts, hi, side="left"))  # bins b0..b1-1 meet the chunk
        at = starts[b0:b1] - lo
        at[0] = 0  # the first bin may have begun in an earlier chunk
        with np.errstate(invalid="ignore"):
            self._lo[b0:b1] = np.fmin(self._lo[b0:b1], np.fmin.reduceat(y, at))
            self._hi[b0:b1] = np.fmax(self._hi[b0:b1], np.fmax.reduceat(y, at))
        for rows, into in ((starts, self._first), (ends, self._last)):
            i, j = np.searchsorted(rows, (lo, hi), side="left")
            into[i:j] = y[rows[i:j] - lo]

    def points(self) -> tuple[np.ndarray, np.ndarray]:
        """(t, y): two points per bin, its min and max in the order the signal went."""
        if self.filled != self.bins.rows:
            raise ValueError(f"{self.filled} rows given of {self.bins.rows}")
        t = self.bins.t
        if self.bins.whole:
            return t, self._lo
        tt = np.empty(2 * self._lo.size)
        yy = np.empty(2 * self._lo.size)
        tt[0::2], tt[1::2] = t[self.bins.starts], t[self.bins.ends]
        falling = self._first > self._last  # draw max then min where the bin falls
        yy[0::2] = np.where(falling, self._hi, self._lo)
        yy[1::2] = np.where(falling, self._lo, self._hi)
        return tt, yy


def minmax_decimate(t: np.ndarray, y: np.ndarray, columns: int = 2000
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(t, y) reduced to at most ``2 * columns`` points, the min and max of each bin.

    ``t`` must be sorted. Short signals (<= 2 * columns samples) come back unchanged."""
    envelope = MinMaxEnvelope(Bins(t, columns))
    envelope.add(y)
    return envelope.points()
