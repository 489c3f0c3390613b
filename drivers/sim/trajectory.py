"""The plant's state history at its integration points, for the sensors to sample.

Points collect in a Python list (cheap appends from the scalar integrator) or arrive as
whole spans, and move into one growing numpy buffer that is trimmed from behind once the
acquisition no longer needs them.
"""

from __future__ import annotations

from typing import TypeAlias

import numpy as np

#: ``Trajectory.snapshot``: buffer (by reference), live range, points not flushed yet.
TrajectorySnapshot: TypeAlias = tuple[np.ndarray, int, int, list[tuple[float, ...]]]


class Trajectory:
    """Plant state at the integration points, in one growing buffer trimmed from behind.

    New points collect in a Python list (cheap appends from the scalar integrator) and are
    moved into the numpy buffer in one go when someone samples the trajectory.
    """

    names = ("t", "omega", "theta", "i_w", "i_bus", "v_bus", "duty")

    def __init__(self) -> None:
        self._buf = np.empty((len(self.names), 4096))
        self._start = 0
        self._end = 0
        self.pending: list[tuple[float, ...]] = []
        self._index = {n: i for i, n in enumerate(self.names)}

    def append(self, point: tuple[float, ...]) -> None:
        self.pending.append(point)

    def flush(self) -> None:
        if not self.pending:
            return
        new = np.array(self.pending).T
        self.pending = []
        self._write(new)

    def extend(self, columns: np.ndarray) -> None:
        """Append many points at once: one row per name, one column per point."""
        self.flush()
        self._write(columns)

    def _write(self, new: np.ndarray) -> None:
        k = new.shape[1]
        if self._end + k > self._buf.shape[1]:
            live = self._end - self._start
            cap = self._buf.shape[1]
            if live + k > cap // 2:
                cap = max(2 * cap, 2 * (live + k))
            buf = np.empty((len(self.names), cap))
            buf[:, :live] = self._buf[:, self._start : self._end]
            self._buf, self._start, self._end = buf, 0, live
        self._buf[:, self._end : self._end + k] = new
        self._end += k

    def column(self, name: str) -> np.ndarray:
        return self._buf[self._index[name], self._start : self._end]

    @property
    def arrays(self) -> dict[str, np.ndarray]:
        """Views of the flushed columns (call ``flush`` first for the newest points)."""
        return {n: self.column(n) for n in self.names}

    @property
    def size(self) -> int:
        return self._end - self._start + len(self.pending)

    def snapshot(self) -> TrajectorySnapshot:
        """O(1): points before ``_end`` are never written again (appends go after it or
        into a new buffer, trims only move ``_start``), so the buffer is kept by reference."""
        return self._buf, self._start, self._end, list(self.pending)

    def restore(self, snap: TrajectorySnapshot) -> None:
        buf, start, end, pending = snap
        self._buf, self._start, self._end = buf, start, end
        self.pending = list(pending)

    def trim_before(self, t: float) -> None:
        """Drop points not needed to interpolate at times >= t (keeps one point before t)."""
        self.flush()
        k = int(np.searchsorted(self.column("t"), t, side="right")) - 1
        if k > 0:
            self._start += k

    def sample(self, t: np.ndarray, names: tuple[str, ...]) -> dict[str, np.ndarray]:
        self.flush()
        tt = self.column("t")
        return {n: np.interp(t, tt, self.column(n)) for n in names}
