"""Puts the blocks of several sensors on one time base for the samples table.

The base sensor (the load cell, 25 kHz) sets the rows; every other channel is the last
sample of its own sensor at or before each row's time (zero-order hold, causal, like a
DAQ that latches the newest reading). Samples that arrive ahead of the base are kept
until the base catches up, so no value is ever used before its timestamp.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from bench.errors import RigError
from drivers.contracts import Block

__all__ = ["BlockAligner"]

_MAX_PENDING = 2_000_000  # samples per sensor kept while the base sensor delivers nothing


class _Held:
    """Pending samples of one secondary sensor plus its last value before them."""

    def __init__(self, names: tuple[str, ...]) -> None:
        self.names = names
        self.t = np.empty(0)
        self.v = {n: np.empty(0) for n in names}
        self.last = {n: np.nan for n in names}

    def add(self, block: Block) -> None:
        if len(block):
            self.t = np.concatenate([self.t, block.t_s])
            for n in self.names:
                self.v[n] = np.concatenate([self.v[n], np.asarray(block.values[n], float)])
            if self.t.size > _MAX_PENDING:
                self._consume(self.t.size - _MAX_PENDING)

    def _consume(self, count: int) -> None:
        if count <= 0:
            return
        for n in self.names:
            self.last[n] = float(self.v[n][count - 1])
            self.v[n] = self.v[n][count:]
        self.t = self.t[count:]

    def at(self, t: np.ndarray) -> dict[str, np.ndarray]:
        idx = np.searchsorted(self.t, t, side="right") - 1
        have = idx >= 0
        safe = np.where(have, idx, 0)
        out = {}
        for n in self.names:
            if self.t.size:
                out[n] = np.where(have, self.v[n][safe], self.last[n])
            else:
                out[n] = np.full(t.shape, self.last[n])
        if t.size:
            self._consume(int(np.searchsorted(self.t, t[-1], side="right")))
        return out


class BlockAligner:
    """Merges per-sensor blocks into columns on the base sensor's timestamps."""

    def __init__(self, channels: Mapping[str, tuple[str, ...]], base: str) -> None:
        if base not in channels:
            raise RigError(f"rig: no sensor with role {base!r} to time the samples table")
        seen: dict[str, str] = {}
        for role, names in channels.items():
            for n in names:
                if n in seen:
                    raise RigError(f"rig: channel {n!r} comes from both {seen[n]!r} and {role!r}")
                seen[n] = role
        self.base = base
        self.base_names = tuple(channels[base])
        self.columns = ("t_s", *[n for names in channels.values() for n in names])
        self._held = {r: _Held(tuple(n)) for r, n in channels.items() if r != base}

    def push(self, blocks: Mapping[str, Block]) -> dict[str, np.ndarray]:
        """Add one read of every sensor; return the rows the base sensor produced."""
        base = blocks.get(self.base)
        t = np.asarray(base.t_s, float) if base is not None else np.empty(0)
        out: dict[str, np.ndarray] = {"t_s": t}
        for n in self.base_names:
            out[n] = np.asarray(base.values[n], float) if base is not None else np.empty(0)
        for role, held in self._held.items():
            block = blocks.get(role)
            if (block is not None and held.t.size == 0 and t.size and len(block) == t.size
                    and bool((block.t_s == t).all())):
                # Same sample clock as the base (one DAQ): the columns line up as they are.
                for n in held.names:
                    v = np.asarray(block.values[n], float)
                    out[n] = v
                    held.last[n] = float(v[-1])
                continue
            if block is not None:
                held.add(block)
            out.update(held.at(t))
        return out
