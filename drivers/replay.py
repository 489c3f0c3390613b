"""Replayed sensor: hands out recorded blocks as the rig clock passes their timestamps.

Used to run bench code and analysis on a recording as if it were live, and as a second
implementation for the sensor contract tests. ``replay:///abs/path/file.npz`` opens an
``.npz`` holding ``t_s`` and one array per column (``thrust_n``, ``current_a``, ...).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from urllib.parse import urlsplit

import numpy as np

from drivers.contracts import Block, ChannelInfo, Clock, DeviceInfo
from drivers.errors import DeviceError

UNITS = {"thrust_n": "N", "current_a": "A", "voltage_v": "V", "rpm": "rpm", "throttle_us": "us"}


class ReplaySensor:
    """A sensor whose samples come from a recording, released by the rig clock."""

    def __init__(self, url: str, t_s: np.ndarray, values: dict[str, np.ndarray],
                 clock: Clock, kind: str = "replay") -> None:
        t_s = np.asarray(t_s, dtype=float)
        if t_s.ndim != 1 or np.any(np.diff(t_s) < 0):
            raise DeviceError(f"{url}: replay timestamps must be one increasing column")
        for name, v in values.items():
            if np.shape(v) != t_s.shape:
                raise DeviceError(f"{url}: column {name!r} has {np.shape(v)} values, "
                                  f"t_s has {t_s.shape}")
        self.url = url
        self.kind = kind
        self.t_s = t_s
        self.values = {k: np.asarray(v, dtype=float) for k, v in values.items()}
        self.clock = clock
        self.pos = 0
        self.closed = False
        dt = np.diff(t_s)
        self.rate_hz = float(1.0 / np.median(dt)) if dt.size else 0.0

    @classmethod
    def from_blocks(cls, url: str, blocks: Sequence[Block], clock: Clock) -> ReplaySensor:
        names = tuple(blocks[0].values) if blocks else ()
        t = np.concatenate([b.t_s for b in blocks]) if blocks else np.empty(0)
        vals = {n: np.concatenate([b.values[n] for b in blocks]) for n in names}
        return cls(url, t, vals, clock)

    @classmethod
    def from_url(cls, url: str, clock: Clock) -> ReplaySensor:
        path = Path(urlsplit(url).path)
        try:
            with np.load(path) as data:
                if not hasattr(data, "files"):  # a bare .npy array, not named columns
                    raise ValueError("a single array, not named columns")
                arrays = {k: data[k] for k in data.files}
        except FileNotFoundError:
            raise DeviceError(f"{url}: replay file {path} not found") from None
        except (OSError, ValueError) as exc:
            # np.load's message for bytes it does not know is about pickles: not useful here
            reason = "not a NumPy .npz file" if "pickle" in str(exc) else str(exc)
            raise DeviceError(f"{url}: cannot read replay file {path}: {reason} (expected an "
                              ".npz recording with t_s and value columns)") from None
        if "t_s" not in arrays:
            raise DeviceError(f"{url}: replay file {path} has no t_s column")
        t = arrays.pop("t_s")
        return cls(url, t, arrays, clock)

    def describe(self) -> DeviceInfo:
        chans = tuple(ChannelInfo(n, UNITS.get(n, ""), self.rate_hz) for n in self.values)
        return DeviceInfo(kind=self.kind, model="replay", url=self.url, channels=chans)

    def read_block(self) -> Block:
        if self.closed:
            raise DeviceError(f"{self.url}: sensor is closed")
        end = int(np.searchsorted(self.t_s, self.clock.now(), side="right"))
        sl = slice(self.pos, end)
        self.pos = max(end, self.pos)
        return Block(self.t_s[sl].copy(), {k: v[sl].copy() for k, v in self.values.items()})

    def close(self) -> None:
        self.closed = True
